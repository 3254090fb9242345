"""Diagnosis: what the rigid model still gets wrong, its physical cause, and the gain on new poses,
each candidate fitted with :func:`pincal.calibrate` (the method: :mod:`pincal.auto.diagnosis`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pincal.auto.diagnosis import (
    Diagnosis,
    diagnose_with,
)
from pincal.auto.pipeline import calibrate_unjudged
from pincal.data.dataset import Dataset
from pincal.kinematics.effects import Extension
from pincal.kinematics.gravity import Payload
from pincal.robot.robots import Robot


def diagnose(
    robot: Robot,
    data: Dataset,
    model: str = "placements",
    measure: str | None = None,
    folds: int = 5,
    seed: int = 0,
    effects: list[Extension] | None = None,
    payload: Payload | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    quick: bool = False,
    **options: Any,
) -> Diagnosis:
    """Find what the rigid model gets wrong.

    Args:
        robot: the robot.
        data: all poses.
        model: the geometric baseline (``placements``, ``poe`` or ``mdh`` give the same fit).
        measure: ``position``, ``pose`` or ``distance``.
        folds: K of the cross-validation.
        seed: seed of the folds.
        effects: the candidates (default: every effect on every joint, see
            :func:`pincal.kinematics.effects.candidates`).
        payload: a load on the tip, for the gravity torques.
        progress: called as ``progress(done, total, label)`` after each candidate.
        quick: judge nonlinearly only the finalists that could be named: their linearised gain
            reaches :data:`~pincal.auto.finalists.QUICK_GAIN` and their family-wise p-value the
            level of this step (the others are listed as screened).
        **options: passed to :func:`pincal.calibrate` (registration, tool, ...).
    """
    fit = calibrate_unjudged
    return diagnose_with(
        fit, robot, data, model, measure, folds, seed, effects, payload, progress, quick, **options
    )
