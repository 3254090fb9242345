"""Closed-form screening of candidate effects on the problem linearised at the geometric fit.

A candidate effect adds one or two columns ``E`` to the geometric fit's Jacobian ``J`` (its
identifiable model, registration and tool columns, at the fit θ̂, where the residuals are ``r``).
Near θ̂ the problem is linear, ``r(θ̂ + δ) ≈ r + [J E] δ``, so a K-fold cross-validation needs no
nonlinear solve: each fold's fit is the least-squares ``δ`` of the other folds' rows, and its
held-out error is ``r + [J E] δ`` on the fold's rows. ``J``'s part of the normal equations is
formed once per fold and shared by every candidate; a candidate adds ``Jᵀ E`` and ``Eᵀ E``.

Nothing of size rows × unknowns is held: one pass over the poses (block by block for a large
problem, :mod:`pincal.identify.chunked`) sums the Gram matrix of ``[J E r]`` (``E`` the columns of
every candidate given, at once) for each group of rows held out in the same folds, apart for the
rows a held-out error counts (a pose's position rows). A fold's fit is then the normal equations
of the groups it trains on, and its held-out errors' sum of squares the quadratic form
``[δ; 1]ᵀ Z [δ; 1]`` of the groups it holds out.

:func:`pincal.auto.diagnose.diagnose` ranks the candidates by this linearised cross-validated RMS and
runs the nonlinear calibration and cross-validation only for the few best. The folds, the
held-out errors (a pose's 3-D position error; for distance data every pair with a held-out pose)
are those of the nonlinear path; :mod:`pincal.auto.screen_null` draws noise through the same
rows.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from pincal.auto.bordered import least_squares_steps
from pincal.data.dataset import Dataset
from pincal.identify import chunked
from pincal.identify.calibration import Calibration
from pincal.identify.folds import pose_folds
from pincal.identify.identifiability import RCOND
from pincal.identify.measurements import Problem
from pincal.kinematics.effects import AnyEffect, combined


@dataclass(frozen=True)
class Screen:
    """A candidate judged on the linearised problem.

    Attributes:
        cv_rms_mm: linearised K-fold cross-validated RMS [mm].
        rss: residual sum of squares of the linearised fit on all rows [m²].
        params: the effect's parameters of that fit (in the extension's units).
        identifiable: whether the data tells the effect from the geometry.
    """

    cv_rms_mm: float
    rss: float
    params: np.ndarray
    identifiable: bool


@dataclass(frozen=True, eq=False)
class Design:
    """The rows of a small linearised problem, kept for draws of noise through the same screen
    (:mod:`pincal.auto.screen_null`).

    Attributes:
        problem: the problem the rows are of (its data and pairs).
        jac: (R, c) the columns ``[J E]`` (the geometry's, then every candidate's).
        groups: (R,) each row's group: the bit mask of the folds that hold it out.
        counted: (R,) whether a held-out error counts the row (a pose's position rows).
        n_folds: the number of folds.
    """

    problem: Problem
    jac: np.ndarray
    groups: np.ndarray
    counted: np.ndarray
    n_folds: int

    def held(self, fold: int) -> np.ndarray:
        """(R,) the rows fold ``fold`` holds out."""
        return (self.groups >> fold & 1).astype(bool)


class GroupSums:
    """Gram matrices of rows ``X`` (here ``[J E r]``) summed by group: a group is the set of folds
    its rows are held out in (a bit mask), the rows a held-out error counts apart."""

    def __init__(self) -> None:
        self.counted: dict[int, np.ndarray] = {}
        self.other: dict[int, np.ndarray] = {}
        self.n_counted: dict[int, int] = {}

    def add(self, rows: np.ndarray, groups: np.ndarray, counted: np.ndarray) -> None:
        """Add rows (R, c), each row's group (R,) and whether a held-out error counts it (R,)."""
        for group in np.unique(groups).tolist():
            here = groups == group
            for into, which in ((self.counted, here & counted), (self.other, here & ~counted)):
                part = rows[which]
                into[group] = into.get(group, 0.0) + part.T @ part
            self.n_counted[group] = self.n_counted.get(group, 0) + int(np.count_nonzero(here & counted))

    def gram(self, fold: int | None = None, held: bool = False) -> np.ndarray:
        """``XᵀX`` over every row (``fold`` None), the rows fold ``fold`` trains on, or (``held``)
        the counted rows it holds out."""
        out: np.ndarray | float = 0.0
        for group in sorted(self.counted):
            inside = fold is not None and bool(group >> fold & 1)
            if fold is None or inside == held:
                out = out + self.counted[group] + (0.0 if held else self.other[group])
        return np.asarray(out)

    def n_held(self, fold: int) -> int:
        """Counted rows fold ``fold`` holds out."""
        return sum(n for group, n in self.n_counted.items() if group >> fold & 1)


class Linearised:
    """The geometric fit's residuals and Jacobian, summed by folds, ready for extra columns.

    Args:
        base: the geometric fit.
        data: its poses.
        folds: number of folds; seed: their seed (:func:`pincal.identify.folds.pose_folds`).
        pool: candidate effects whose columns are summed in the same pass (others are summed
            when screened, one more pass each).
    """

    def __init__(
        self, base: Calibration, data: Dataset, folds: int, seed: int, pool: Sequence[AnyEffect] | None = None
    ) -> None:
        self.base, self.data = base, data
        self.kind = base.measurement.measure
        self.free = np.flatnonzero(base.identifiability.identifiable)
        held = pose_folds(data, folds, seed)
        self.n_folds = len(held)
        self.bits = np.zeros(len(data) + 1, dtype=np.int64)  # last: no pose (a known distance's row)
        for k, rows in enumerate(held):
            self.bits[rows] |= 1 << k
        self.large = chunked.is_large(base.problem(data))
        self.design: Design | None = None  # the rows themselves, kept when the data is small
        self.sums, self.columns, self.residuals = self._pass(list(pool or []), keep=True)

    def _parts(self) -> list[tuple[Dataset, int]]:
        """The data in blocks of poses with their first pose's index (one part unless large)."""
        if not self.large:
            return [(self.data, 0)]
        n, size = len(self.data), chunked.BLOCK_POSES
        return [(self.data.subset(np.arange(a, min(a + size, n))), a) for a in range(0, n, size)]

    def _pass(
        self, pool: Sequence[AnyEffect], keep: bool = False
    ) -> tuple[GroupSums, dict[str, np.ndarray], np.ndarray]:
        """One pass over the poses: the sums of ``[J E r]`` with the columns ``E`` of every effect
        of ``pool`` (after the effects the base fit holds), each effect's columns in ``E``, and
        the residuals; with ``keep``, a small problem's rows in :attr:`design`."""
        base = self.base
        n_model = base.model.n_params + (base.extension.n_params if base.extension is not None else 0)
        held = base.extension.parts if base.extension is not None else ()
        both = combined([*held, *(part for ext in pool for part in ext.parts)])
        n_new = sum(ext.n_params for ext in pool)
        theta = np.concatenate([base.theta[:n_model], np.zeros(n_new), base.theta[n_model:]])
        moved = np.where(self.free < n_model, self.free, self.free + n_new)
        cols = np.concatenate([moved, np.arange(n_model, n_model + n_new)]).astype(int)
        columns, at = {}, len(self.free)
        for ext in pool:
            columns[ext.label], at = np.arange(at, at + ext.n_params), at + ext.n_params
        sums, residuals, width = GroupSums(), [], self.kind.width
        measurement = replace(base.measurement, pairs=None)
        for part, first in self._parts():
            problem = Problem(base.model, measurement, part, both)
            res, jac = problem.rows(theta, cols)
            owners = self.kind.owners(problem)
            groups = np.bitwise_or.reduce(self.bits[np.where(owners >= 0, owners + first, -1)], axis=1)
            counted = np.arange(len(res)) % width < 3
            sums.add(np.column_stack([jac, res]), groups, counted)
            residuals.append(res)
            if keep and not self.large:
                self.design = Design(problem, jac, groups, counted, self.n_folds)
        return sums, columns, np.concatenate(residuals)

    def _sums_of(self, extension: AnyEffect | None) -> tuple[GroupSums, np.ndarray]:
        """The sums holding ``extension``'s columns, and the indices of ``[J E]`` in them."""
        base = np.arange(len(self.free))
        if extension is None:
            return self.sums, base
        sums, columns = self.sums, self.columns
        if extension.label not in columns:
            sums, columns, _ = self._pass([extension])
        return sums, np.concatenate([base, columns[extension.label]])

    def folds_fit(self) -> bool:
        """Whether every fold leaves more residual rows than the baseline has unknowns, so that
        its refits would run (else they say how many poses the cross-validation needs)."""
        if self.design is None:  # large data: folds of thousands of poses
            return True
        trained = (np.count_nonzero(~self.design.held(k)) for k in range(self.n_folds))
        return all(n > len(self.free) for n in trained)

    def screen(self, extension: AnyEffect | None = None) -> Screen:
        """The linearised cross-validation and all-row fit, with ``extension``'s columns or none."""
        sums, take = self._sums_of(extension)
        return self._screened(sums, [take])[0]

    def screen_all(self, pool: Sequence[AnyEffect]) -> tuple[Screen, list[Screen]]:
        """:meth:`screen` of the baseline and of each effect of ``pool``: every fold's fits by
        bordered solves on its baseline's factor (:func:`~pincal.auto.bordered.least_squares_steps`),
        the same figures to rounding as one solve per candidate and fold."""
        if any(ext.label not in self.columns for ext in pool):  # columns summed in another pass
            return self.screen(), [self.screen(ext) for ext in pool]
        base = np.arange(len(self.free))
        screens = self._screened(
            self.sums, [base] + [np.concatenate([base, self.columns[e.label]]) for e in pool]
        )
        return screens[0], screens[1:]

    def _screened(self, sums: GroupSums, takes: list[np.ndarray]) -> list[Screen]:
        """The screen of each take (columns of ``[J E]`` in ``sums``, the baseline's first)."""
        n_base = len(self.free)
        total = sums.gram()
        norms = np.sqrt(np.diag(total)[:-1])
        norms = np.where(norms > 0, norms, 1.0)
        scale = np.outer(np.append(1.0 / norms, 1.0), np.append(1.0 / norms, 1.0))  # unit columns
        squares, entries = np.zeros(len(takes)), 0
        for k in range(self.n_folds):
            held = sums.gram(k, held=True) * scale
            for i, (rows, step) in enumerate(_steps(sums.gram(k) * scale, takes)):
                squares[i] += max(float(step @ held[np.ix_(rows, rows)] @ step), 0.0)
            entries += sums.n_held(k) // min(self.kind.width, 3)
        total = total * scale
        absorbed = _unabsorbed(total, n_base)
        out = []
        for i, (rows, step) in enumerate(_steps(total, takes)):
            rss = max(float(step @ total[np.ix_(rows, rows)] @ step), 0.0)
            extra = takes[i][n_base:] - n_base
            identifiable = _identifiable(absorbed[np.ix_(extra, extra)]) if extra.size else True
            cv = float(np.sqrt(squares[i] / max(entries, 1))) * 1e3
            out.append(Screen(cv, rss, step[n_base:-1] / norms[takes[i][n_base:]], identifiable))
        return out


def _steps(gram: np.ndarray, takes: list[np.ndarray]) -> list[tuple[np.ndarray, np.ndarray]]:
    """For each take (columns of ``[J E]``): its rows and columns of ``gram`` (of ``[J E r]``), with
    ``r``'s, and ``[δ; 1]`` for its least-squares step of ``r + [J E] δ``."""
    steps = least_squares_steps(gram[:-1, :-1], gram[:-1, -1:], takes)
    last = len(gram) - 1
    return [(np.append(take, last), np.append(-step[:, 0], 1.0)) for take, step in zip(takes, steps)]


def _unabsorbed(total: np.ndarray, n_base: int) -> np.ndarray:
    """What of every candidate column the geometry's columns cannot absorb, for all at once:
    ``EᵀE - EᵀJ (JᵀJ)⁺ JᵀE`` (unit columns)."""
    jj, je, ee = total[:n_base, :n_base], total[:n_base, n_base:-1], total[n_base:-1, n_base:-1]
    return ee - je.T @ np.linalg.lstsq(jj, je, rcond=1e-12)[0]


def _identifiable(schur: np.ndarray) -> bool:
    """Whether an effect's columns stay apart from the geometry's (their Schur complement)."""
    return bool(np.sqrt(max(float(np.linalg.eigvalsh(schur).min()), 0.0)) > RCOND)
