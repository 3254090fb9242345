"""Warm starts: a fit begun from another fit of the same unknowns, not from the nominal model.

A fold of a cross-validation fits most of the poses the fit on all of them fitted, and a
candidate effect adds a few unknowns to the geometric fit: their minima lie close to that fit's,
and Levenberg-Marquardt started there needs fewer steps (the registration-only solve keeps its
closed-form first guess: as good a start). The start changes
where the solver begins, never what it minimises (the pull still holds the corrections near the
URDF, not near the start), so the answer is the same minimum within the solver's tolerances.

Unknowns are matched by name: the model's and the effects' (a name the start lacks begins at the
nominal value), and the registration, fixed points and tool as a block, which must have the same
names in both. The registration (and a pose's target frame) is a twist about each problem's own
first guess, so it is carried over as the transform it stands for
(:func:`pincal.identify.measurement.unpack`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pincal.identify.calibration import Calibration
from pincal.identify.measurement import Measurement, unpack
from pincal.identify.measurements import Problem


@dataclass(frozen=True, eq=False)
class WarmStart:
    """A fit to start another from.

    Attributes:
        names: the names of its unknowns θ.
        n_model: how many of them are the model's and the effects' (the rest: registration,
            fixed points, tool).
        measurement: its measurement model (the first guesses its twists are taken about).
        theta: its fit at the default pull (the solve a fit begins with, :func:`pincal.auto.fitting.fit`).
    """

    names: tuple[str, ...]
    n_model: int
    measurement: Measurement
    theta: np.ndarray

    @classmethod
    def of(cls, cal: Calibration) -> WarmStart:
        """The start a calibration gives: its fit at the default pull (else its fit)."""
        n_model = cal.model.n_params + (cal.extension.n_params if cal.extension else 0)
        theta = cal.theta if cal.default_pull_theta is None else cal.default_pull_theta
        return cls(tuple(cal.names), n_model, cal.measurement, theta)

    @classmethod
    def at(cls, problem: Problem, theta: np.ndarray) -> WarmStart:
        """The start a fit ``theta`` of ``problem`` gives."""
        return cls(tuple(problem.names), problem.n_model, problem.measurement, theta)

    def fit(self, problem: Problem, nominal: np.ndarray, free: np.ndarray) -> np.ndarray:
        """Where the fit of the unknowns ``free`` (mask) starts on ``problem``: its
        registration-only θ ``nominal`` with the free unknowns this start holds set to their
        values here (the others keep ``nominal``'s: the fit holds them there)."""
        warm = nominal.copy()
        index = {name: k for k, name in enumerate(self.names[: self.n_model])}
        for k, name in enumerate(problem.names[: problem.n_model]):
            if free[k] and name in index:
                warm[k] = self.theta[index[name]]
        if self._same_measurement(problem):
            rest = slice(problem.n_model, None)
            warm[rest] = np.where(free[rest], self._measured(problem, self.theta), nominal[rest])
        return warm

    def _same_measurement(self, problem: Problem) -> bool:
        """Whether ``problem``'s registration, points and tool are this start's unknowns."""
        same = tuple(problem.names[problem.n_model :]) == self.names[self.n_model :]
        return same and problem.measurement.kind == self.measurement.kind

    def _measured(self, problem: Problem, theta: np.ndarray) -> np.ndarray:
        """The registration, points and tool of this start's ``theta`` as ``problem``'s unknowns:
        the same transforms, as twists about ``problem``'s first guesses."""
        target = problem.measurement
        out = np.array(theta[self.n_model :], dtype=float)
        _, reg, tool = unpack(self.n_model, self.measurement, theta)
        if target.n_instrument:
            out[:6] = pin.log6(target.instrument_T_base.actInv(reg)).vector
        if target.n_tool == 6 and not target.markers:
            k = target.n_instrument + target.n_points
            out[k : k + 6] = pin.log6(target.tool.actInv(tool)).vector
        return out


def fits_better(problem: Problem, warm: np.ndarray, nominal: np.ndarray) -> bool:
    """Whether the start ``warm`` fits ``problem``'s poses better than ``nominal`` (a fit of
    poses that determine little, its registration turned far, may not: then start cold)."""
    at_nominal = problem.residuals(nominal)  # the registration's minimum, just evaluated
    at_warm = problem.residuals(warm)  # last: the fit begins there (a large problem keeps it)
    return bool(np.isfinite(at_warm).all() and at_warm @ at_warm < at_nominal @ at_nominal)
