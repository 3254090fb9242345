"""Which model parameters to fit: forward selection scored by cross-validation on the fitted poses.

With few poses, fitting every identifiable parameter fits the noise and the effects no rigid model holds, and
predicts new poses worse than a smaller model. :func:`select_parameters` starts from the registration and
tool alone (and any extension) and adds, one at a time, the model parameter that gives the lowest cross-
validated RMS, until no candidate adds rank. The chosen set is the shortest prefix of that path whose cross-
validated RMS is within ``min_gain`` (relative) of the path's minimum, unless fitting every parameter scores
within ``keep_all`` (5 %) of it: the prefix's score is biased low by the choosing, so a smaller model must
win clearly (114 Panda poses: the full model predicts 7 % better than the prefix, its score only 1.4 % above
the lowest; 37 TIAGo poses: the prefix wins, 2.28 against 4.38 mm).

Every candidate is scored in closed form on the problem linearised at the registration-only fit
(:mod:`pincal.identify.selection_walk`: linearised leave-one-out, a tie to the first in the
model's order). The chosen step's score is biased low:
:func:`pincal.auto.selection.cross_validate_selection` re-runs the selection per fold.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pincal.data.dataset import Dataset
from pincal.identify.selection_walk import SelectionStep, design, walk
from pincal.identify.solver import SETUP_KEYS, Setup, register, set_up
from pincal.kinematics.effects import AnyEffect
from pincal.robot.robots import Robot
from pincal.workers import limited

#: Take the shortest prefix of the path within this fraction of its lowest cross-validated RMS...
MIN_GAIN = 0.01
#: ... unless fitting every parameter is within this fraction of the lowest: then fit them all.
KEEP_ALL = 0.05


@dataclass(frozen=True)
class Selection:
    """The parameters chosen and the path that chose them.

    Attributes:
        model: the parameterization the names belong to.
        chosen: the chosen parameters, in the order they were added (pass as ``params=`` to
            :func:`pincal.calibrate`).
        path: every step until no candidate adds rank; ``path[len(chosen)]`` is the chosen one.
        folds: K of the cross-validation, or None for leave-one-out.
        min_gain: the parsimony margin.
        keep_all: the margin within which every parameter is kept.
        keeps_all: every identifiable parameter was kept (fit them with ``params="all"``).
    """

    model: str
    chosen: tuple[str, ...]
    path: tuple[SelectionStep, ...]
    folds: int | None
    min_gain: float
    keep_all: float = KEEP_ALL
    keeps_all: bool = False

    @property
    def cv_rms_mm(self) -> float:
        """Cross-validated RMS of the chosen step [mm] (linearised)."""
        return self.path[len(self.chosen)].cv_rms_mm

    @property
    def all_cv_rms_mm(self) -> float:
        """Cross-validated RMS of the path's end, every parameter fitted [mm] (linearised)."""
        return self.path[-1].cv_rms_mm

    @property
    def params(self) -> tuple[str, ...] | None:
        """What to pass as ``params=`` to :func:`pincal.calibrate` (None: every parameter)."""
        return None if self.keeps_all else self.chosen

    @property
    def rule(self) -> str:
        """The rule that chose, in words."""
        return (
            f"every parameter when fitting them all is within {self.keep_all:.0%} of the lowest "
            f"cross-validated RMS of the path, else the shortest prefix within {self.min_gain:.0%} of it"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {
            "model": self.model,
            "chosen": list(self.chosen),
            "keeps_all": self.keeps_all,
            "cv_rms_mm": self.cv_rms_mm,
            "all_cv_rms_mm": self.all_cv_rms_mm,
            "folds": self.folds or "leave-one-out",
            "min_gain": self.min_gain,
            "keep_all": self.keep_all,
            "rule": self.rule,
            "path": [
                {"added": s.added, "cv_rms_mm": s.cv_rms_mm, "fit_rms_mm": s.fit_rms_mm} for s in self.path
            ],
        }


def selection_path(
    setup: Setup, theta: np.ndarray, folds: int | None = None, seed: int = 0, max_params: int | None = None
) -> tuple[list[SelectionStep], bool]:
    """The forward-selection path on the problem linearised at ``theta`` (the fit of the
    extension, registration and tool alone), and whether it went on until no candidate added rank.
    """
    plan = design(setup, theta, folds, seed)
    path, complete, _ = walk(plan, setup.linearised(theta)[0], max_params)
    return path, complete


def choose_step(path: list[SelectionStep], complete: bool, min_gain: float, keep_all: float) -> int:
    """The chosen step of a path: its end (every parameter) when the end's score is within
    ``keep_all`` of the lowest, else the shortest prefix within ``min_gain`` of the lowest."""
    scores = np.array([step.cv_rms_mm for step in path])
    if complete and scores[-1] <= (1.0 + keep_all) * scores.min():
        return len(path) - 1
    return int(np.flatnonzero(scores <= (1.0 + min_gain) * scores.min())[0])


@limited
def select_parameters(
    robot: Robot,
    data: Dataset,
    model: str = "placements",
    measure: str | None = None,
    *,
    folds: int | None = None,
    seed: int = 0,
    min_gain: float = MIN_GAIN,
    keep_all: float = KEEP_ALL,
    max_params: int | None = None,
    extension: AnyEffect | None = None,
    **options: Any,
) -> Selection:
    """Forward selection of the model parameters by cross-validation on ``data`` alone.

    Args:
        robot: the robot.
        data: the poses to fit (the only data looked at).
        model: the parameterization whose parameters are candidates.
        measure: ``position``, ``pose`` or ``distance`` (default as :func:`pincal.calibrate`).
        folds: K of the cross-validation, or None for leave-one-out over poses.
        seed: seed of the folds (K-fold only).
        min_gain: choose the shortest prefix of the path whose cross-validated RMS is within this
            fraction of the path's lowest ...
        keep_all: ... unless the whole path (every parameter) is within this fraction of it.
        max_params: end the path after this many parameters.
        extension: an effect fitted with the registration and tool at every step.
        **options: the measurement set-up, as :func:`pincal.calibrate` takes it (registration,
            tool, rotation weight, pairs); other keys are ignored.
    """
    known = {k: options[k] for k in SETUP_KEYS if k in options}
    setup = set_up(robot, data, model, measure, extension=extension, **known)
    return select_on(setup, folds, seed, min_gain, keep_all, max_params)


def select_on(
    setup: Setup,
    folds: int | None = None,
    seed: int = 0,
    min_gain: float = MIN_GAIN,
    keep_all: float = KEEP_ALL,
    max_params: int | None = None,
    start: np.ndarray | None = None,
) -> Selection:
    """:func:`select_parameters` on a set-up problem, from ``start`` (default: :func:`register`'s)."""
    start = register(setup, with_extension=True) if start is None else start
    path, complete = selection_path(setup, start, folds, seed, max_params)
    stop = choose_step(path, complete, min_gain, keep_all)
    chosen = tuple(str(step.added) for step in path[1 : stop + 1])
    keeps_all = complete and stop == len(path) - 1
    return Selection(setup.model.kind, chosen, tuple(path), folds, min_gain, keep_all, keeps_all)
