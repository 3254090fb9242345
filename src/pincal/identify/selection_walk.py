"""The forward selection's walk in closed form, for one residual or many at once.

Every candidate is scored on the problem linearised at the registration-only fit: with ``H`` the
hat matrix of the current columns and ``e`` the fit's residual, a group of rows ``g`` predicted by
a fit on the other rows leaves ``(I - H_gg)⁻¹ e_g`` (PRESS); adding a column ``u``
(orthonormalised) changes ``H`` by ``u uᵀ`` and ``e`` by ``-u uᵀe``. A group is a pose
(leave-one-out) or a fold; for distance data, the rows of every pair with a pose in it. A tie
(scores within :data:`TIE`) goes to the first in the model's order.

:func:`walks` takes ``D`` residuals (the guard's null draws of pure noise) through the same
algebra at once: each draw keeps its own projected candidates, residual and leave-one-out
inverses, stacked along a first axis, so NumPy's work per step is one call for every draw
instead of one per draw (the walk's cost on a few dozen poses is mostly the calls). :func:`walk`
is the walk of one residual.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pincal.identify.fixed_points import blind_jacobian
from pincal.identify.folds import held_out_rows
from pincal.identify.identifiability import RCOND
from pincal.identify.solver import Setup

#: A group whose ``I - H_gg`` has an eigenvalue below this is determined by the fit alone.
SINGULAR = 1e-10
TIE = 1e-9  #: Relative margin within which two candidates' scores tie.
#: Draws walked together do at most about this much work per step in their leave-one-out
#: algebra (draws x Σ group size² x candidates): larger stacks leave the processor's cache, and
#: large groups gain nothing from batching (measured on 20 draws: 37 TIAGo poses fastest 10-20
#: at a time, 40 UR5 poses of pose data 5-10, their distances one at a time).
BATCH_WORK = 400_000


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


class _LeaveOut:
    """``(I - H_gg)⁻¹`` of every held-out group ``g`` and every draw, kept up to date as each
    draw's columns join its basis.

    Adding a unit column ``u`` orthogonal to the basis changes ``I - H_gg`` by ``-u_g u_gᵀ``, whose
    inverse follows by Sherman-Morrison: one small inverse per group at the start, then vector
    work per candidate and step. Each block holds the groups of one size: their rows (G, s), the
    inverses (D, G, s, s) and which groups the fit alone determines (D, G).
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
            self.blocks.append((rows, ((v / w[:, None, :]) @ v.transpose(0, 2, 1))[None], singular[None]))

    def for_draws(self, keep: np.ndarray) -> _LeaveOut:
        """The inverses of the draws ``keep`` (indices; a one-draw start is repeated)."""
        out = object.__new__(_LeaveOut)
        out.blocks = [(rows, a_inv[keep], singular[keep]) for rows, a_inv, singular in self.blocks]
        return out

    def scores(self, res: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cross-validated and in-sample sums of squares [m²] of each draw when each column of
        ``u`` (D, R, C; orthonormal to the draw's basis, or zero) is added; ``res`` (D, R) is
        orthogonal to the basis: (D, C) each."""
        e = res[:, :, None] - u * (u.transpose(0, 2, 1) @ res[:, :, None]).transpose(0, 2, 1)
        sse = np.zeros((u.shape[0], u.shape[2]))
        for rows, a_inv, singular in self.blocks:
            ug = u[:, rows]  # (D, G, s, C)
            ai_u = _matmul(a_inv, ug)
            denom = 1.0 - np.sum(ug * ai_u, axis=2)  # (D, G, C)
            ai_e = _matmul(a_inv, e[:, rows])
            lost = singular[:, :, None] | (denom <= SINGULAR)
            factor = np.sum(ug * ai_e, axis=2) / np.where(lost, 1.0, denom)
            loo = ai_e + ai_u * factor[:, :, None, :]
            sse += np.where(lost, np.inf, np.sum(loo**2, axis=2)).sum(axis=1)
        return sse, np.sum(e**2, axis=1)

    def add(self, col: np.ndarray) -> None:
        """Take each draw's unit column ``col`` (D, R) into its basis."""
        for k, (rows, a_inv, singular) in enumerate(self.blocks):
            ug = col[:, rows]  # (D, G, s)
            ai_u = _matmul(a_inv, ug[..., None])[..., 0]
            denom = 1.0 - np.sum(ug * ai_u, axis=2)  # (D, G)
            lost = denom <= SINGULAR
            outer = ai_u[..., :, None] * ai_u[..., None, :]
            a_inv = a_inv + outer / np.where(lost, 1.0, denom)[..., None, None]
            self.blocks[k] = (rows, a_inv, singular | lost)


def _matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` of stacks (D, G, i, j) and (D, G, j, k), as one stack of D G matrices: NumPy
    multiplies a three-dimensional stack by BLAS, a four-dimensional one about five times slower."""
    flat = a.reshape(-1, *a.shape[2:]) @ b.reshape(-1, *b.shape[2:])
    return flat.reshape(*a.shape[:2], *flat.shape[1:])


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
        leave_out: ``(I - H_gg)⁻¹`` of every group for ``basis`` (taken by each walk).
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

    def rms_mm(self, sse: np.ndarray, fitted: bool = False) -> np.ndarray:
        """Sums of squares [m²] as RMS [mm], cross-validated (or ``fitted``)."""
        return np.sqrt(sse / (self.n_fit_units if fitted else self.n_units)) * 1e3


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


#: A walk: its path, whether it went on until no candidate added rank, the unknowns it added.
Walk = tuple[list[SelectionStep], bool, list[int]]


def walk(plan: Design, res: np.ndarray, max_params: int | None = None) -> Walk:
    """The forward-selection path of the residual ``res`` [m] on ``plan``, whether it went on until
    no candidate added rank, and the unknowns added (indices, in order)."""
    return walks(plan, res[:, None], max_params)[0]


def walks(plan: Design, res: np.ndarray, max_params: int | None = None) -> list[Walk]:
    """:func:`walk` of each column of ``res`` (R, D), walked together in stacks of at most
    :func:`batch_size` draws."""
    size = batch_size(plan)
    return [
        w for a in range(0, res.shape[1], size) for w in _Walks(plan, res[:, a : a + size]).run(max_params)
    ]


def batch_size(plan: Design) -> int:
    """How many draws are walked together: their leave-one-out algebra does at most about
    :data:`BATCH_WORK` per step (one draw at least)."""
    per_draw = sum(len(g) ** 2 for g in plan.groups) * max(1, len(plan.candidates))
    return max(1, BATCH_WORK // per_draw)


def draw_batches(plan: Design, draws: int) -> list[np.ndarray]:
    """The draws ``0 .. draws - 1`` in at least two batches (for two cores) of nearly equal size,
    none larger than :func:`batch_size`: each batch is one stack of :func:`walks`."""
    return np.array_split(np.arange(draws), min(draws, max(2, -(-draws // batch_size(plan)))))


class _Walks:
    """The walks of several residuals at once: the draws still walking, each with its candidate
    columns projected out of its basis, its residual, its open candidates and its leave-one-out
    inverses stacked along a first axis (every draw's basis has ``rank`` columns)."""

    def __init__(self, plan: Design, res: np.ndarray) -> None:
        n_draws = res.shape[1]
        self.plan = plan
        self.res = plan.project(res).T.copy()  # (D, R)
        self.rank = plan.basis.shape[1]  # the columns of each draw's basis
        cols = plan.jac[:, plan.candidates]
        for _ in range(2):  # Gram-Schmidt twice keeps the basis orthonormal
            cols = cols - plan.basis @ (plan.basis.T @ cols)
        self.cols = np.repeat(cols[None], n_draws, axis=0)  # (D, R, C): the candidates, projected
        self.open = np.ones((n_draws, len(plan.candidates)), dtype=bool)
        self.walking = np.arange(n_draws)
        self.leave_out = plan.leave_out.for_draws(np.zeros(n_draws, dtype=int))
        cv0, fit0 = self.leave_out.scores(self.res, np.zeros((n_draws, len(res), 1)))
        cv, fit = plan.rms_mm(cv0[:, 0]), plan.rms_mm(fit0[:, 0], fitted=True)
        self.paths = [[SelectionStep(None, float(c), float(f))] for c, f in zip(cv, fit)]
        self.added: list[list[int]] = [[] for _ in range(n_draws)]
        self.complete = [True] * n_draws

    def run(self, max_params: int | None) -> list[Walk]:
        """Every draw's walk, in the order of the residuals."""
        steps = 0
        while True:
            self._keep(np.any(self.open, axis=1))  # no candidate left: complete
            if not self.walking.size:
                break
            if (max_params is not None and steps + 1 > max_params) or self.rank + 1 > self.plan.room:
                for d in self.walking:
                    self.complete[d] = False
                break
            self._step()
            steps += 1
        return [(path, done, added) for path, done, added in zip(self.paths, self.complete, self.added)]

    def _step(self) -> None:
        """Add each walking draw's best open candidate; stop the draws that can add none."""
        plan = self.plan
        order = np.argsort(~self.open, axis=1, kind="stable")[:, : self.open.sum(axis=1).max()]
        cols = np.take_along_axis(self.cols, order[:, None, :], axis=2)  # each draw's open ones first
        norms = np.linalg.norm(cols, axis=1)  # (D, C)
        valid = np.take_along_axis(self.open, order, axis=1) & (norms > plan.tol)
        u = np.where(valid[:, None, :], cols / np.where(valid, norms, 1.0)[:, None, :], 0.0)
        sse, fit = self.leave_out.scores(self.res, u)
        cv = np.where(valid, plan.rms_mm(sse), np.inf)
        best = np.argmax(cv <= np.min(cv, axis=1, keepdims=True) * (1.0 + TIE), axis=1)  # a tie: the first
        rows = np.arange(len(best))
        moving = np.isfinite(cv[rows, best])
        fit_mm = plan.rms_mm(fit[rows, best], fitted=True)
        for j in np.flatnonzero(moving):
            d, index = self.walking[j], plan.candidates[order[j, best[j]]]
            self.added[d].append(index)
            self.paths[d].append(SelectionStep(plan.names[index], float(cv[j, best[j]]), float(fit_mm[j])))
        column = u[rows, :, best]  # (D, R)
        self.rank += 1
        self.cols = self.cols - column[:, :, None] * (column[:, None, :] @ self.cols)  # modified G-S
        self.leave_out.add(column)
        self.res = self.res - column * np.sum(column * self.res, axis=1, keepdims=True)
        np.put_along_axis(self.open, order, valid, axis=1)  # a column with no rank left stays out
        self.open[rows, order[rows, best]] = False
        self._keep(moving)

    def _keep(self, keep: np.ndarray) -> None:
        """Go on with the draws ``keep`` (mask) only: the others' walks are complete."""
        if keep.all():
            return
        self.walking, self.cols, self.res, self.open = (
            a[keep] for a in (self.walking, self.cols, self.res, self.open)
        )
        self.leave_out = self.leave_out.for_draws(np.flatnonzero(keep))
