"""The automatic choice on many poses: made on a random subset, the fit on every pose.

``params="auto"`` and ``extension="auto"`` cross-validate: every candidate is refitted once per
fold, and the selection holds the dense Jacobian of all poses. Above :data:`CHOICE_POSES` poses,
:func:`choose_on_subset` makes that choice (the parameters kept, the extension named) on a random
subset of :data:`CHOICE_POSES` poses (seed given), and the calibration then fits the chosen
model on every pose, block by block (:mod:`pincal.identify.chunked`). The command line says so before it
starts. A choice made on 20,000 poses is not noticeably worse: the cross-validated errors that
decide it are then averages over thousands of poses per fold.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from pincal.data.dataset import Dataset
from pincal.identify.calibration import Calibration
from pincal.robot.robots import Robot

#: Poses above which the automatic choice is made on a random subset of this many.
CHOICE_POSES = 20_000


def needs_subset(data: Dataset, params: Any, extension: Any) -> bool:
    """Whether the choice of ``params``/``extension`` ("auto") is made on a subset of ``data``."""
    return len(data) > CHOICE_POSES and "auto" in (params, extension)


def subset_note(data: Dataset, seed: int) -> str:
    """What the command line says before it starts."""
    return (
        f"{len(data):,} poses: the automatic choice (parameters, extension, cross-validation) is made on "
        f"a random subset of {CHOICE_POSES:,} of them (seed {seed}); the chosen model is then fitted "
        f"on all {len(data):,} (--params all --extend none fits every pose without a choice)"
    )


def calibrate_choosing(
    fit: Callable[..., Calibration],
    robot: Robot,
    data: Dataset,
    say: Callable[[str], None] | None = None,
    **options: Any,
) -> Calibration:
    """``fit(robot, data, **options)``, its automatic choice made on a random subset above
    :data:`CHOICE_POSES` poses (said first through ``say``), the chosen model fitted on every
    pose; the calibration carries the subset's choice (its diagnosis among it)."""
    if not needs_subset(data, options.get("params"), options.get("extension")):
        return fit(robot, data, **options)
    if say is not None:
        say(subset_note(data, options.get("seed", 0)))
    test = options.pop("test", None)  # held-out poses score the fit on every pose, not the choice
    chosen, on_all = choose_on_subset(fit, robot, data, **options)
    return replace(fit(robot, data, test=test, **on_all), choice=chosen.choice)


def choose_on_subset(
    fit: Callable[..., Calibration], robot: Robot, data: Dataset, **options: Any
) -> tuple[Calibration, dict[str, Any]]:
    """The calibration on a random subset of :data:`CHOICE_POSES` poses, and the options that fit
    its choice (parameters and extension, no new choice) on every pose.

    Args:
        fit: :func:`pincal.calibrate`.
        robot, data: the chain, every pose.
        options: the keyword arguments of ``fit`` (``params``, ``extension`` among them; ``seed``,
            default 0, also draws the subset).
    """
    draw = np.random.default_rng(options.get("seed", 0))
    keep = np.sort(draw.choice(len(data), CHOICE_POSES, replace=False))
    chosen = fit(robot, data.subset(keep), **options)
    choice = chosen.choice
    params = None if choice is None or choice.params is None else list(choice.params)
    return chosen, {**options, "params": params, "extension": chosen.extension or "none", "nested": False}
