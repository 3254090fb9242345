"""Which model parameters to fit (:mod:`pincal.forward_selection`: forward selection scored by
cross-validation on the fitted poses), and :func:`cross_validate_selection`, which judges the whole
procedure ``calibrate(..., params="auto")`` by K-fold cross-validation.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .choice import choice_of
from .crossval import cross_validate
from .data import Dataset
from .evaluation import ErrorStats
from .forward_selection import KEEP_ALL as KEEP_ALL  # re-exported: where tests and older callers find them
from .forward_selection import MIN_GAIN as MIN_GAIN
from .forward_selection import Selection as Selection
from .forward_selection import SelectionStep as SelectionStep
from .forward_selection import choose_step as choose_step
from .forward_selection import select_on as select_on
from .forward_selection import select_parameters as select_parameters
from .forward_selection import selection_path as selection_path
from .robots import Robot


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
