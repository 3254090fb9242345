"""The result of an identification: :class:`Calibration`, what it found and how well it fits."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pinocchio as pin

from pincal.data.dataset import Dataset
from pincal.identify.evaluation import ErrorStats
from pincal.identify.identifiability import Identifiability
from pincal.identify.measurement import Measurement, marker_points, unpack
from pincal.identify.measurements import Problem
from pincal.identify.records import Balance, Choice, Guard, Judgement, PriorChoice
from pincal.kinematics.chain import Chain, forward
from pincal.kinematics.effects import AnyEffect
from pincal.kinematics.models import Model
from pincal.robot.robots import Robot


@dataclass(frozen=True, eq=False)
class Calibration:
    """What an identification found.

    Attributes:
        model: the parameterization.
        extension: the non-geometric effect identified with it, if any.
        measurement: the measurement model (its registration and tool are the initial guesses).
        names: names of all unknowns θ (model, then instrument and tool).
        units: their units (``m`` or ``rad``).
        theta: the identified unknowns.
        std: standard deviations of θ (0 for the parameters held fixed).
        nominal_theta: the nominal model with its registration and tool fitted ("before": the
            error the nominal kinematics is responsible for, FIGAROH's "registration only").
        identifiability: the identifiable set and why the rest was held.
        train_before, train_after: errors on the fitted poses.
        test_before, test_after: errors on held-out poses, or None.
        train_urdf, test_urdf: errors of the URDF exactly as it is: the nominal kinematics with the
            nominal tool (the tip frame's origin, or the tool given), only the instrument
            registered (as the papers report "before calibration").
        n_poses: number of fitted poses.
        n_evaluations: Jacobian evaluations of the solver.
        message: the solver's termination message.
        converged: the solver met a tolerance; False when it stopped at its evaluation limit
            (the fit is then not a minimum: the report warns).
        excluded: outlier poses left out of the fit, as (row number, residual [mm]) pairs.
        choice: how the parameters and the extension were chosen (``params="auto"`` or
            ``extension="auto"``), else None.
        balance: with an extension, how geometry and effect were weighted so that the URDF
            alone stays the best URDF (:mod:`pincal.auto.balance`), else None.
        prior: the pull toward the URDF: its weight and how it was chosen (:mod:`pincal.identify.prior`).
        guard: the fit judged against the nominal model on the fitted poses (:mod:`pincal.identify.guard`).
        train_markers, test_markers: several markers: the errors after of each marker on the
            fitted and held-out poses, by label (else empty).
        plausibility: whether the result can describe a real arm (:func:`pincal.calibrate` judges
            it, :mod:`pincal.plausibility.judge`); the writers refuse an implausible one.
        urdf_fit: when the full model (this calibration: geometry and effects fitted together)
            is not what a URDF alone should hold, the fit written to the URDF: the geometry,
            registration and tool fitted without the effects (the best URDF alone); the sidecar's
            ``complete`` then carries what the full model changes beyond it. None: the URDF holds
            this calibration's own geometry.
        default_pull_theta: the fit at the default pull (:data:`pincal.identify.solver.PRIOR_WEIGHT`)
            from which the fit at the chosen weight was solved, or None: where a fit of nearly
            the same poses at that pull begins (:mod:`pincal.identify.warm`).
    """

    model: Model
    extension: AnyEffect | None
    measurement: Measurement
    names: tuple[str, ...]
    units: tuple[str, ...]
    theta: np.ndarray
    std: np.ndarray
    nominal_theta: np.ndarray
    identifiability: Identifiability
    train_before: ErrorStats
    train_after: ErrorStats
    test_before: ErrorStats | None
    test_after: ErrorStats | None
    train_urdf: ErrorStats
    test_urdf: ErrorStats | None
    urdf_measurement: Measurement
    urdf_theta: np.ndarray
    n_poses: int
    n_evaluations: int
    message: str
    excluded: tuple[tuple[int, float], ...] = ()
    choice: Choice | None = None
    balance: Balance | None = None
    prior: PriorChoice | None = None
    guard: Guard | None = None
    plausibility: Judgement | None = None
    urdf_fit: Calibration | None = None
    converged: bool = True
    default_pull_theta: np.ndarray | None = field(default=None, repr=False)

    @property
    def written(self) -> Calibration:
        """The fit the corrected URDF holds (:attr:`urdf_fit`, or this calibration)."""
        return self.urdf_fit if self.urdf_fit is not None else self

    train_markers: dict[str, ErrorStats] = field(default_factory=dict)
    test_markers: dict[str, ErrorStats] = field(default_factory=dict)

    @property
    def robot(self) -> Robot:
        """The calibrated robot (nominal description)."""
        return self.model.robot

    @property
    def x(self) -> np.ndarray:
        """The model parameters (first part of θ)."""
        return self.theta[: self.model.n_params]

    @property
    def effect_params(self) -> np.ndarray:
        """The extension's parameters (empty without one)."""
        n = self.extension.n_params if self.extension else 0
        return self.theta[self.model.n_params : self.model.n_params + n]

    def chain(self) -> Chain:
        """The calibrated chain from base to tip."""
        return self.model.chain(self.x)

    def problem(self, data: Dataset) -> Problem:
        """The residual function of this calibration on other data (all pairs for distances)."""
        return Problem(self.model, replace(self.measurement, pairs=None), data, self.extension)

    def split(self) -> tuple[np.ndarray, pin.SE3, pin.SE3]:
        """Model parameters, ``instrument_T_base`` and ``tip_T_target`` as identified."""
        n = self.model.n_params + (self.extension.n_params if self.extension else 0)
        x, reg, tool = unpack(n, self.measurement, self.theta)
        return x[: self.model.n_params], reg, tool

    def markers(self) -> dict[str, np.ndarray]:
        """Several markers: each marker's point on its frame [m] by label, as identified (else empty)."""
        m = self.measurement
        if not m.markers:
            return {}
        n = self.model.n_params + (self.extension.n_params if self.extension else 0)
        return dict(zip(m.markers, marker_points(n, m, self.theta)))

    def base_T_tip(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Calibrated tip rotations (N, 3, 3) and positions (N, 3) [m] for commanded joint values
        (N, n), the extension's joint error included."""
        q = np.atleast_2d(q)
        if self.extension is not None:
            q = q + self.extension.joint_error(q, self.effect_params)
        frames = forward(self.chain(), q)
        return frames.tip_rotation, frames.tip_translation
