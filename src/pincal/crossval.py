"""K-fold cross-validation over poses: the error a calibration makes on poses it did not fit.

For position and pose data, each fold's held-out poses are predicted with the registration and
tool fitted on the other folds. For distance data, the held-out errors are those of every pair
with at least one held-out pose (the other pose may have been fitted): this is how a distance
calibration is judged on new poses without an instrument registration. A pair whose two poses
are held out in different folds is judged twice, once by each fold's model.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .calibration import Calibration
from .data import Dataset
from .errors import DataError, IdentifiabilityError
from .evaluation import ErrorStats, pose_errors
from .folds import fold_indices
from .folds import held_out_rows as held_out_rows  # where tests and older callers find it
from .measurements import Problem, all_pairs
from .models import Model
from .pipeline import calibrate
from .robots import Robot
from .threads import limited


@dataclass(frozen=True)
class CrossValidation:
    """Pooled held-out errors of a K-fold cross-validation.

    Attributes:
        folds: number of folds.
        urdf: the URDF as it is (nominal tool, registration fitted on the other folds).
        before: nominal kinematics with registration and tool fitted on the other folds.
        after: the calibrated model.
        calibrations: the calibration of each fold.
    """

    folds: int
    urdf: ErrorStats
    before: ErrorStats
    after: ErrorStats
    calibrations: tuple[Calibration, ...]

    @property
    def gain(self) -> float:
        """Mean held-out error before / after calibration."""
        return self.before.mean_mm / self.after.mean_mm

    @property
    def gain_vs_urdf(self) -> float:
        """Mean held-out error of the URDF as it is / after calibration."""
        return self.urdf.mean_mm / self.after.mean_mm


def held_out_errors(cal: Calibration, data: Dataset, held: np.ndarray) -> list[np.ndarray]:
    """Held-out errors [m] of the URDF, before and after, for one fold."""
    out = []
    for meas, theta in (
        (cal.urdf_measurement, cal.urdf_theta),
        (cal.measurement, cal.nominal_theta),
        (cal.measurement, cal.theta),
    ):
        if cal.measurement.measure.by_pairs:
            pairs = all_pairs(len(data))
            pairs = pairs[np.isin(pairs, held).any(axis=1)]
            problem = Problem(cal.model, replace(meas, pairs=pairs), data, cal.extension)
            out.append(np.abs(problem.residuals(theta)))
        else:
            out.append(pose_errors(cal.model, meas, theta, data.subset(held), cal.extension)[0])
    return out


@limited
def cross_validate(
    robot: Robot,
    data: Dataset,
    model: str | Model = "placements",
    measure: str | None = None,
    folds: int = 7,
    seed: int = 0,
    **options: Any,
) -> CrossValidation:
    """Calibrate on K-1 folds, judge on the held-out fold, pool the held-out errors.

    Args:
        robot: the robot.
        data: all poses.
        model: the parameterization.
        measure: the measurement (default as :func:`pincal.calibrate`).
        folds: number of folds (``len(data)`` for leave-one-out).
        seed: seed of the partition.
        **options: passed to :func:`pincal.calibrate`; each fold fits what its poses identify
            (``partial=True``: a fold may lack the variety of the whole).
    """
    if not 2 <= folds <= len(data):
        raise DataError(f"cross-validation needs between 2 and {len(data)} folds (one per pose), got {folds}")
    pooled: list[list[np.ndarray]] = [[], [], []]
    cals = []
    for held in fold_indices(len(data), folds, seed):
        fit = np.setdiff1d(np.arange(len(data)), held)
        try:
            cal = calibrate(robot, data.subset(fit), model, measure, **{**options, "partial": True})
        except IdentifiabilityError as exc:  # said of the fold, it would ask for fewer poses than given
            if exc.poses_needed is None:
                raise
            fits = (n - -(-n // folds) for n in range(len(data), 10 * exc.poses_needed + folds + 1))
            least = len(data) + next(k for k, n in enumerate(fits) if n >= exc.poses_needed)
            raise IdentifiabilityError(
                f"{folds}-fold cross-validation fits {len(fit)} of the {len(data)} poses at a time, which "
                f"give too few equations: measure at least {least} poses, or use fewer folds (--folds)",
                least,
            ) from None
        cals.append(cal)
        for store, errs in zip(pooled, held_out_errors(cal, data, held)):
            store.append(errs)
    urdf, before, after = (ErrorStats.of(np.concatenate(p)) for p in pooled)
    return CrossValidation(folds, urdf, before, after, tuple(cals))
