"""K-fold cross-validation over poses of a given fit: the error a calibration makes on poses it
did not fit (:func:`pincal.auto.crossval.cross_validate` fits with :func:`pincal.calibrate`; the pipeline,
above
this module, passes its own fit for the nested cross-validation).

For position and pose data, each fold's held-out poses are predicted with the registration and
tool fitted on the other folds. For distance data, the held-out errors are those of every pair
with at least one held-out pose (the other pose may have been fitted): this is how a distance
calibration is judged on new poses without an instrument registration. A pair whose two poses
are held out in different folds is judged twice, once by each fold's model.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from pincal.data.dataset import Dataset
from pincal.data.pairs import all_pairs
from pincal.errors import DataError, IdentifiabilityError
from pincal.identify.calibration import Calibration
from pincal.identify.evaluation import ErrorStats, pose_errors
from pincal.identify.folds import pose_folds
from pincal.identify.measurements import Problem
from pincal.kinematics.models import Model
from pincal.robot.robots import Robot
from pincal.workers import limited, parallel_map, worker_count

#: A fit: :func:`pincal.calibrate`'s signature, ``fit(robot, data, model, measure, **options)``.
Fit = Callable[..., Calibration]


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
def cross_validate_with(
    fit: Fit,
    robot: Robot,
    data: Dataset,
    model: str | Model = "placements",
    measure: str | None = None,
    folds: int = 7,
    seed: int = 0,
    *,
    progress: Callable[[int, int, str], None] | None = None,
    **options: Any,
) -> CrossValidation:
    """Calibrate with ``fit`` on K-1 folds, judge on the held-out fold, pool the held-out errors.

    The folds run in the worker processes, as many at a time as there are workers; the folds left
    over (the fifth of five on two cores) run here, each with the workers for its own parallel work
    (a whole calibration's diagnosis), so no core waits while one fold runs alone.

    Args:
        fit: the calibration, called as ``fit(robot, data, model, measure, **options)``.
        robot: the robot.
        data: all poses.
        model: the parameterization.
        measure: the measurement (default as :func:`pincal.calibrate`).
        folds: number of folds (``len(data)`` for leave-one-out).
        seed: seed of the partition.
        progress: called as ``progress(done, folds, label)`` after each fold.
        **options: passed to ``fit``; each fold fits what its poses identify
            (``partial=True``: a fold may lack the variety of the whole).
    """
    runs = FoldRuns.of(fit, (robot, data, model, measure), folds, seed, options)

    def done(k: int) -> None:
        if progress is not None:
            progress(k + 1, folds, f"cross-validation, fold {k + 1} of {folds}")

    n_folds, workers = len(runs.parts), worker_count()
    together = n_folds - n_folds % workers if n_folds > workers else n_folds
    answers = parallel_map(runs.fold, together, done=done)  # the folds are independent
    for k in range(together, n_folds):  # the last of 5 folds on 2 cores: here, with both cores inside
        answers.append(runs.fold(k))
        done(k)
    return runs.pooled(answers)


@dataclass(frozen=True, eq=False)
class FoldRuns:
    """A K-fold cross-validation as its independent fold fits: run by :func:`cross_validate_with`,
    or among other work in one :func:`~pincal.workers.parallel_map` (each :meth:`fold`, then
    :meth:`pooled`), with the same answer.

    Attributes:
        fit: the calibration.
        what: robot, data, model and measure.
        folds: K as asked (a data set of several markers per pose may give fewer parts).
        parts: the held-out rows of each fold.
        options: passed to ``fit``.
    """

    fit: Fit
    what: tuple[Robot, Dataset, str | Model, str | None]
    folds: int
    parts: tuple[np.ndarray, ...]
    options: dict[str, Any]

    @classmethod
    def of(cls, fit: Fit, what: tuple[Any, ...], folds: int, seed: int, options: dict[str, Any]) -> FoldRuns:
        """The folds of ``what`` (robot, data, model, measure) fitted with ``fit``
        (:func:`cross_validate_with`'s arguments).

        Raises:
            DataError: fewer than 2 or more folds than poses.
        """
        data = what[1]
        if not 2 <= folds <= len(data):
            raise DataError(
                f"cross-validation needs between 2 and {len(data)} folds (one per pose), got {folds}"
            )
        return cls(fit, tuple(what), folds, tuple(pose_folds(data, folds, seed)), dict(options))

    def fold(self, k: int) -> tuple[Calibration, list[np.ndarray]]:
        """The fit without fold ``k`` and its held-out errors (:func:`held_out_errors`)."""
        robot, data, model, measure = self.what
        kept = np.setdiff1d(np.arange(len(data)), self.parts[k])
        cal = _fold_fit(self.fit, (robot, data, kept, model, measure), self.folds, self.options)
        return cal, held_out_errors(cal, data, self.parts[k])

    def jobs(self) -> list[Callable[[], tuple[Calibration, list[np.ndarray]]]]:
        """Each fold's work as a job of no arguments."""
        return [functools.partial(self.fold, k) for k in range(len(self.parts))]

    def pooled(self, answers: list[tuple[Calibration, list[np.ndarray]]]) -> CrossValidation:
        """The cross-validation of every fold's answer, in fold order."""
        pooled = [[errs[j] for _, errs in answers] for j in range(3)]
        urdf, before, after = (ErrorStats.of(np.concatenate(p)) for p in pooled)
        return CrossValidation(self.folds, urdf, before, after, tuple(cal for cal, _ in answers))


def _fold_fit(fit: Fit, what: tuple[Any, ...], folds: int, options: dict[str, Any]) -> Calibration:
    """``fit`` on the poses ``kept`` of ``data`` (``what``: robot, data, kept, model, measure),
    or the error that says how many poses the cross-validation needs."""
    robot, data, kept, model, measure = what
    try:
        return fit(robot, data.subset(kept), model, measure, **{**options, "partial": True})
    except IdentifiabilityError as exc:  # said of the fold, it would ask for fewer poses than given
        if exc.poses_needed is None:
            raise
        fits = (n - -(-n // folds) for n in range(len(data), 10 * exc.poses_needed + folds + 1))
        least = len(data) + next(k for k, n in enumerate(fits) if n >= exc.poses_needed)
        raise IdentifiabilityError(
            f"{folds}-fold cross-validation fits {len(kept)} of the {len(data)} poses at a time, which "
            f"give too few equations: measure at least {least} poses, or use fewer folds (folds=)",
            least,
        ) from None
