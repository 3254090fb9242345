"""What :func:`pincal.calibrate` is asked to do: one typed, frozen set of options.

:class:`CalibrateOptions` holds every choice of a calibration beyond the robot, the data, the
model and the measure; the pipeline hands it down whole, and reads the keywords each step takes
from it (:meth:`CalibrateOptions.setup`, :meth:`CalibrateOptions.fitting`). Lengths in metres,
angles in radians.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np
import pinocchio as pin

from pincal.errors import DataError
from pincal.identify.fixed_points import PointDistance
from pincal.identify.guard import DEFAULT_PULL, Pull
from pincal.identify.identifiability import RCOND
from pincal.identify.solver import SETUP_KEYS
from pincal.identify.warm import WarmStart
from pincal.kinematics.effects import AnyEffect, Extension, combined
from pincal.kinematics.gravity import Payload
from pincal.options import LOSSES, ROTATION_WEIGHT
from pincal.robot.robots import Robot

#: How geometry and an effect share the fit (see :attr:`CalibrateOptions.deliver`).
DELIVERIES = ("complete", "balanced", "joint", "none")
#: The options of each fit (:func:`pincal.auto.fitting.fit`'s keywords).
FITTING = ("partial", "loss", "f_scale", "rcond", "pull")


@dataclass(frozen=True)
class CalibrateOptions:
    """Every choice of :func:`pincal.calibrate` but the robot, the data, the model and the measure.

    Attributes:
        instrument_T_base: the known registration (default: unknown, estimated).
        tool: the measured point on the tip (3,) [m] or the target frame ``tip_T_target``
            (default: unknown, estimated).
        rotation_weight: weight of orientation residuals [m/rad] for pose data.
        pairs: pose pairs for distance data: ``all``, ``gao`` (Gao et al. eq. 21) or (m, 2).
        point_distances: known distances between fixed points, ((A, B, D [m]), ...).
        loss: ``linear`` or a robust loss of ``scipy.optimize.least_squares``.
        f_scale: where the robust loss down-weights [m].
        rcond: the rank's relative threshold.
        extension: an effect (:class:`~pincal.kinematics.effects.Extension` or
            ``EFFECT:JOINT``), several (:class:`~pincal.kinematics.effects.Effects` or
            ``EFFECT:JOINT+EFFECT:JOINT``), ``"auto"`` (the causes the diagnosis names) or None.
        params: None or ``"all"`` (every identifiable parameter), ``"auto"`` (chosen by
            cross-validation on the fitted poses) or parameter names.
        outliers: leave out poses this many robust σ above the others (None: keep all).
        partial: fit what the data identify when varied poses would identify more.
        payload: a load on the tip, for the gravity torques.
        folds: K of the cross-validations (the diagnosis', the nested one).
        seed: seed of their folds.
        nested: judge the whole call by K-fold cross-validation: True, False or None (when cheap).
        deliver: with effects, ``complete`` (two deliverables: the URDF holds the geometry fitted
            without the effects, the best URDF alone; the sidecar's full model, geometry and
            effects fitted together, the best model with the sidecar: :mod:`pincal.auto.delivery`),
            ``balanced`` (one geometry, weighted so that the URDF alone stays the best URDF:
            :mod:`pincal.auto.balance`), ``joint`` (one geometry, fitted with the effects) or
            ``none`` (joint, gravity on the nominal URDF: the diagnosis' inner fits).
        pull: the pull toward the URDF, and when the fit is exported.
        start: a fit to begin the solves from (:class:`~pincal.identify.warm.WarmStart`: a fold's
            from the fit on all poses); the answer is the same minimum, found in fewer steps.
            None: from the nominal model.
    """

    instrument_T_base: pin.SE3 | None = None
    tool: pin.SE3 | np.ndarray | None = None
    rotation_weight: float = ROTATION_WEIGHT
    pairs: str | np.ndarray = "all"
    point_distances: tuple[PointDistance, ...] = ()
    loss: str = "linear"
    f_scale: float = 1e-4
    rcond: float = RCOND
    extension: AnyEffect | str | None = None
    params: Sequence[str] | str | None = None
    outliers: float | None = None
    partial: bool = False
    payload: Payload | None = None
    folds: int = 5
    seed: int = 0
    nested: bool | None = False
    deliver: str = "complete"
    pull: Pull = DEFAULT_PULL
    start: WarmStart | None = None

    def __post_init__(self) -> None:
        """Refuse a loss or a delivery that is not one of its choices."""
        for name, choices in (("loss", LOSSES), ("deliver", DELIVERIES)):
            if getattr(self, name) not in choices:
                raise DataError(f"unknown {name} {getattr(self, name)!r}: choose one of {', '.join(choices)}")
        object.__setattr__(self, "point_distances", tuple(self.point_distances))

    @classmethod
    def of(cls, options: CalibrateOptions | None, changes: dict[str, Any]) -> CalibrateOptions:
        """``options`` (default: the defaults) with the keyword ``changes``.

        Raises:
            DataError: a keyword that is no option.
        """
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise DataError(
                f"calibrate() has no option {', '.join(map(repr, unknown))}: "
                f"its options are {', '.join(sorted(known))}"
            )
        return replace(options or cls(), **changes)

    def keywords(self) -> dict[str, Any]:
        """Every option by name, as :func:`pincal.calibrate` takes them."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def setup(self) -> dict[str, Any]:
        """The measurement set-up's options (:data:`pincal.identify.solver.SETUP_KEYS`)."""
        return {name: getattr(self, name) for name in SETUP_KEYS}

    def fitting(self) -> dict[str, Any]:
        """Each fit's options (:data:`FITTING`)."""
        return {name: getattr(self, name) for name in FITTING}

    def wanted(self) -> tuple[str, ...] | str | None:
        """The parameters asked for: None (every identifiable one), ``"auto"`` or the names.

        Raises:
            DataError: a string other than ``auto`` or ``all``.
        """
        params = self.params
        if params is None or (isinstance(params, str) and params == "all"):
            return None
        if isinstance(params, str):
            if params != "auto":
                raise DataError(f"params={params!r}: use 'auto', 'all' or a list of parameter names")
            return "auto"
        return tuple(params)

    def effect(self, robot: Robot) -> AnyEffect | str | None:
        """The effects asked for: None, ``"auto"``, or one or several effects of ``robot``.

        Raises:
            DataError: text that is not ``auto``, ``none`` or ``EFFECT:JOINT[+EFFECT:JOINT...]``.
        """
        extension = self.extension
        if extension is None or extension == "none":
            return None
        if not isinstance(extension, str) or extension == "auto":
            return extension
        if ":" not in extension:
            raise DataError(
                f"extension={extension!r}: write auto, none or EFFECT:JOINT (for example joint_compliance:J)"
            )
        parts = [Extension.parse(robot, text.strip(), self.payload) for text in extension.split("+")]
        return combined(parts)
