"""Which model parameters to fit: forward selection scored by cross-validation on the fitted poses.

With few poses, fitting every identifiable parameter fits the noise and the effects no rigid model holds, and
predicts new poses worse than a smaller model. :func:`select_parameters` starts from the registration and
tool alone (and any extension) and adds, one at a time, the model parameter that gives the lowest cross-
validated RMS, until no candidate adds rank. The chosen set is the shortest prefix of that path whose cross-
validated RMS is within ``min_gain`` (relative) of the path's minimum, unless fitting every parameter scores
within ``keep_all`` (5 %) of it: the prefix's score is biased low by the choosing, so a smaller model must
win clearly (114 Panda poses: the full model predicts 7 % better than the prefix, its score only 1.4 % above
the lowest; 37 TIAGo poses: the prefix wins, 2.28 against 4.38 mm).

Every candidate is scored in closed form on the problem linearised at the registration-only fit:
with ``H`` the hat matrix of the current columns and ``e`` the fit's residual, a group of rows
``g`` predicted by a fit on the other rows leaves ``(I - H_gg)⁻¹ e_g`` (PRESS); adding a column
``u`` (orthonormalised) changes ``H`` by ``u uᵀ`` and ``e`` by ``-u uᵀe``. A group is a pose
(leave-one-out) or a fold; for distance data, the rows of every pair with a pose in it. A tie
(scores within :data:`TIE`) goes to the first in the model's order. The chosen step's score is
biased low: :func:`pincal.auto.selection.cross_validate_selection` re-runs the selection per fold.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pincal.data.dataset import Dataset
from pincal.identify.fixed_points import blind_jacobian
from pincal.identify.folds import held_out_rows
from pincal.identify.identifiability import RCOND
from pincal.identify.solver import SETUP_KEYS, Setup, register, set_up
from pincal.kinematics.effects import AnyEffect
from pincal.robot.robots import Robot
from pincal.workers import limited

#: Take the shortest prefix of the path within this fraction of its lowest cross-validated RMS...
MIN_GAIN = 0.01
#: ... unless fitting every parameter is within this fraction of the lowest: then fit them all.
KEEP_ALL = 0.05


@dataclass(frozen=True)
class SelectionStep:
    """One step of the forward selection.

    Attributes:
        added: the parameter added at this step (None for the start: registration and tool only).
        cv_rms_mm: cross-validated RMS after the step [mm] (pose data: rotations weighted by the
            rotation weight [m/rad]; distance data: over pairs).
        fit_rms_mm: RMS on the fitted poses after the step [mm], same units.
    """

    added: str | None
    cv_rms_mm: float
    fit_rms_mm: float


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


#: A group whose ``I - H_gg`` has an eigenvalue below this is determined by the fit alone.
SINGULAR = 1e-10
TIE = 1e-9  #: Relative margin within which two candidates' scores tie.


class _LeaveOut:
    """``(I - H_gg)⁻¹`` of every held-out group ``g``, kept up to date as columns join the basis.

    Adding a unit column ``u`` orthogonal to the basis changes ``I - H_gg`` by ``-u_g u_gᵀ``, whose
    inverse follows by Sherman-Morrison: one small inverse per group at the start, then vector
    work per candidate and step.
    """

    def __init__(self, q: np.ndarray, groups: list[np.ndarray]) -> None:
        by_size: dict[int, list[np.ndarray]] = {}
        for g in groups:
            by_size.setdefault(len(g), []).append(g)
        self.blocks: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        for size, same in by_size.items():
            rows = np.array(same)  # (G, s)
            qg = q[rows]
            w, v = np.linalg.eigh(np.eye(size) - qg @ qg.transpose(0, 2, 1))
            singular = w.min(axis=1) <= SINGULAR  # the group alone determines a column
            w[singular] = 1.0
            self.blocks.append((rows, (v / w[:, None, :]) @ v.transpose(0, 2, 1), singular))

    def _update(self, rows: np.ndarray, a_inv: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, ...]:
        ug = u[rows]  # (G, s, C)
        ai_u = a_inv @ ug
        return ug, ai_u, 1.0 - np.sum(ug * ai_u, axis=1)  # ..., (G, C)

    def scores(self, res: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cross-validated and in-sample sums of squares [m²] when each column of ``u``
        (orthonormal to the basis, or zero) is added; ``res`` is orthogonal to the basis."""
        e = res[:, None] - u * (u.T @ res)  # (m, C) residual after each addition
        sse = np.zeros(u.shape[1])
        for rows, a_inv, singular in self.blocks:
            ug, ai_u, denom = self._update(rows, a_inv, u)
            ai_e = a_inv @ e[rows]
            lost = singular[:, None] | (denom <= SINGULAR)
            factor = np.sum(ug * ai_e, axis=1) / np.where(lost, 1.0, denom)
            loo = ai_e + ai_u * factor[:, None, :]
            sse += np.where(lost, np.inf, np.sum(loo**2, axis=1)).sum(axis=0)
        return sse, np.sum(e**2, axis=0)

    def copy(self) -> _LeaveOut:
        """An independent copy (a walk adds columns to its own)."""
        out = object.__new__(_LeaveOut)
        out.blocks = list(self.blocks)
        return out

    def add(self, col: np.ndarray) -> None:
        """Take the unit column ``col`` into the basis."""
        for k, (rows, a_inv, singular) in enumerate(self.blocks):
            _, ai_u, denom = self._update(rows, a_inv, col[:, None])
            lost = denom[:, 0] <= SINGULAR
            a_inv = a_inv + ai_u @ ai_u.transpose(0, 2, 1) / np.where(lost, 1.0, denom[:, 0])[:, None, None]
            self.blocks[k] = (rows, a_inv, singular | lost)


@dataclass(frozen=True, eq=False)
class Design:
    """A problem linearised for the forward selection, the same for every residual walked on it.

    Attributes:
        jac: Jacobian in natural units, the blind directions of fixed points removed (m, P).
        basis: orthonormal basis of the always-fitted columns (registration, tool, extension) (m, r).
        tol: a column shorter than this (after projection) adds no rank.
        groups: the residual rows of each held-out group.
        candidates: indices of the model parameters that may be added.
        names: every unknown's name.
        n_units: what a cross-validated sum of squares is averaged over (poses, or pairs held out).
        n_fit_units: what an in-sample sum of squares is averaged over.
        room: the most columns a fit without any one group can hold.
        leave_out: ``(I - H_gg)⁻¹`` of every group for ``basis`` (copied by each walk).
    """

    jac: np.ndarray
    basis: np.ndarray
    tol: float
    groups: list[np.ndarray]
    candidates: list[int]
    names: tuple[str, ...]
    n_units: int
    n_fit_units: int
    room: int
    leave_out: _LeaveOut

    def project(self, res: np.ndarray) -> np.ndarray:
        """``res`` without its part in the always-fitted columns: the residual of their fit."""
        return res - self.basis @ (self.basis.T @ res)


def design(setup: Setup, theta: np.ndarray, folds: int | None = None, seed: int = 0) -> Design:
    """The problem linearised at ``theta`` (the fit of the extension, registration and tool
    alone) for :func:`walk`."""
    problem, data = setup.problem, setup.data
    jac = setup.linearised(theta)[1]
    fitted = np.array([name not in setup.model.held for name in problem.names])
    jac = blind_jacobian(problem, theta, jac, fitted, setup.scale)[0] * setup.scale
    n_geo = setup.model.n_params
    tol = RCOND * float(np.max(np.linalg.norm(jac, axis=0)))
    left, sv, _ = np.linalg.svd(jac[:, n_geo:], full_matrices=False)  # always fitted
    q = left[:, sv > tol]
    groups = held_out_rows(problem, folds, seed)
    pairs = problem.measurement.measure.by_pairs
    n_units, n_fit = (sum(len(g) for g in groups), len(jac)) if pairs else (len(data), len(data))
    candidates = [k for k in range(n_geo) if problem.names[k] not in setup.model.held]
    room = len(jac) - max(len(g) for g in groups) - 1
    leave_out = _LeaveOut(q, groups)
    return Design(jac, q, tol, groups, candidates, tuple(problem.names), n_units, n_fit, room, leave_out)


def selection_path(
    setup: Setup, theta: np.ndarray, folds: int | None = None, seed: int = 0, max_params: int | None = None
) -> tuple[list[SelectionStep], bool]:
    """The forward-selection path on the problem linearised at ``theta`` (the fit of the
    extension, registration and tool alone), and whether it went on until no candidate added rank.
    """
    plan = design(setup, theta, folds, seed)
    path, complete, _ = walk(plan, setup.linearised(theta)[0], max_params)
    return path, complete


def walk(
    plan: Design, res: np.ndarray, max_params: int | None = None
) -> tuple[list[SelectionStep], bool, list[int]]:
    """The forward-selection path of the residual ``res`` [m] on ``plan``, whether it went on until
    no candidate added rank, and the unknowns added (indices, in order)."""
    q, res = plan.basis, plan.project(res)
    leave_out = plan.leave_out.copy()

    def rms(sse: np.ndarray, units: float) -> np.ndarray:
        return np.sqrt(sse / units) * 1e3

    cv0, fit0 = leave_out.scores(res, np.zeros((len(res), 1)))
    path = [SelectionStep(None, float(rms(cv0, plan.n_units)[0]), float(rms(fit0, plan.n_fit_units)[0]))]
    candidates, added = list(plan.candidates), list[int]()
    while candidates:
        if (max_params is not None and len(path) > max_params) or q.shape[1] + 1 > plan.room:
            return path, False, added
        cols = plan.jac[:, candidates]
        for _ in range(2):  # Gram-Schmidt twice keeps the basis orthonormal
            cols = cols - q @ (q.T @ cols)
        norms = np.linalg.norm(cols, axis=0)
        valid = norms > plan.tol
        if not valid.any():
            break
        u = np.where(valid, cols / np.where(valid, norms, 1.0), 0.0)
        sse, fit = leave_out.scores(res, u)
        cv = np.where(valid, rms(sse, plan.n_units), np.inf)
        best = int(np.flatnonzero(cv <= np.min(cv) * (1.0 + TIE))[0])  # a tie: the first candidate
        if not np.isfinite(cv[best]):
            break
        added.append(candidates[best])
        name = plan.names[candidates[best]]
        path.append(
            SelectionStep(name, float(cv[best]), float(rms(fit[best : best + 1], plan.n_fit_units)[0]))
        )
        q = np.column_stack([q, u[:, best]])
        leave_out.add(u[:, best])
        res = res - u[:, best] * (u[:, best] @ res)
        candidates = [c for k, c in enumerate(candidates) if k != best and valid[k]]
    return path, True, added


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
