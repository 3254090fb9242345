"""Which model parameters to fit (:mod:`pincal.identify.forward_selection`: forward selection scored by
cross-validation on the fitted poses), and :func:`cross_validate_selection`, which judges the whole
procedure ``calibrate(..., params="auto")`` by K-fold cross-validation.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pincal.auto.choice import choice_of
from pincal.auto.crossval import cross_validate
from pincal.data.dataset import Dataset
from pincal.identify.evaluation import ErrorStats
from pincal.robot.robots import Robot


@dataclass(frozen=True)
class SelectionCrossValidation:
    """Held-out errors of the whole procedure: selection and fit on K-1 folds, judged on the last.

    Attributes:
        folds: number of folds.
        before: nominal kinematics with registration and tool fitted on the other folds.
        after: the selected model fitted on the other folds.
        chosen: the parameters each fold's selection chose.
    """

    folds: int
    before: ErrorStats
    after: ErrorStats
    chosen: tuple[tuple[str, ...], ...]


def cross_validate_selection(
    robot: Robot,
    data: Dataset,
    model: str = "placements",
    measure: str | None = None,
    folds: int = 5,
    seed: int = 0,
    **options: Any,
) -> SelectionCrossValidation:
    """K-fold cross-validation of the whole procedure ``calibrate(..., params="auto")``: the
    selection re-run on each fold's fitted poses, judged on the held-out ones.

    Args:
        robot: the robot.
        data: all poses.
        model: the parameterization.
        measure: the measurement (default as :func:`pincal.calibrate`).
        folds: K of the outer cross-validation (``len(data)`` for leave-one-out).
        seed: seed of the outer partition.
        **options: passed to :func:`pincal.calibrate` (each fold takes ``partial=True``).
    """
    cv = cross_validate(robot, data, model, measure, folds, seed, **{**options, "params": "auto"})
    choices = [choice_of(c) for c in cv.calibrations]
    chosen = tuple(c.selection.chosen if c is not None and c.selection else () for c in choices)
    return SelectionCrossValidation(folds, cv.before, cv.after, chosen)
