"""K-fold cross-validation over poses of :func:`pincal.calibrate`: the error a calibration makes
on poses it did not fit (the folds and the pooling: :mod:`pincal.identify.kfold`, which takes the fit).
"""

from __future__ import annotations

from typing import Any

from pincal.auto.pipeline import calibrate_unjudged
from pincal.data.dataset import Dataset
from pincal.identify.kfold import CrossValidation, cross_validate_with
from pincal.kinematics.models import Model
from pincal.robot.robots import Robot


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
    return cross_validate_with(calibrate_unjudged, robot, data, model, measure, folds, seed, **options)
