"""The diagnosis' chance control: the null of its whole screen, the best of every candidate.

The diagnosis (:mod:`pincal.auto.diagnosis`) ranks every candidate effect by its linearised
cross-validated RMS (:mod:`pincal.auto.screening`) and names the best. On data the rigid model
explains, some candidate always looks best: the more candidates, the better the best looks by
chance. A test of that candidate alone (an F-test, even corrected for the number of candidates)
does not follow what the choice did.

:func:`screen_null` repeats the screen on pure noise: draws of measurement noise through the same
rows (the problem linearised at the geometric fit, the same folds, the same candidates), each
draw's statistic the **largest** gain ``baseline CV RMS / candidate CV RMS`` over every candidate.
Under the null hypothesis (the geometric model is right, the residuals are noise) the data's best
gain and the draws' are exchangeable, so a candidate whose gain ``g`` is reached by ``m`` of
``D`` draws has the family-wise p-value ``(1 + m) / (1 + D)``: a Monte Carlo test of the whole
screen, whatever the number of candidates.

The statistic does not depend on the noise's size (a ratio of RMS); for pose data it depends on
the orientation rows' noise relative to the position rows', drawn in the ratio the geometric
fit's residuals show. Noise is drawn on each measured point and carried to the rows as the
measurement kind carries it (:meth:`pincal.identify.kinds.MeasurementKind.noise_rows`: for
distance data to every pair of a point, which makes the pairs' errors correlated, as they are).
Above :data:`NULL_MAX_POSES` poses the null is drawn on a random subset of that many: on more
poses chance gains are smaller, so the subset's null is conservative.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from pincal.auto.bordered import least_squares_steps
from pincal.auto.screening import Design, Linearised, Screen
from pincal.kinematics.effects import AnyEffect

#: Family-wise level of the diagnosis' test, per cause sought.
ALPHA = 0.01
#: Draws per ``step / ALPHA``: twice as many as the smallest p-value the level needs.
DRAWS_PER_LEVEL = 2
#: Above this many poses the null is drawn on a random subset of this many.
NULL_MAX_POSES = 1000


@dataclass(frozen=True)
class ScreenNull:
    """The largest linearised gain over the candidates, on draws of pure noise.

    Attributes:
        gains: (D,) per draw, the best candidate's ``baseline CV RMS / candidate CV RMS``.
        candidates: how many candidates each draw's best is taken over.
    """

    gains: np.ndarray
    candidates: int

    @property
    def draws(self) -> int:
        """The number of draws."""
        return len(self.gains)

    def p_value(self, gain: float) -> float:
        """Family-wise p-value of a candidate whose linearised gain is ``gain``."""
        return float((1 + np.count_nonzero(self.gains >= gain)) / (1 + self.draws))


def draws_for(step: int) -> int:
    """Draws for the ``step``-th cause sought: its level is ``ALPHA / step`` (Bonferroni over the
    steps), reached by :data:`DRAWS_PER_LEVEL` times the smallest p-value it needs."""
    return math.ceil(DRAWS_PER_LEVEL * step / ALPHA) - 1


def screen_null(lin: Linearised, pool: Sequence[AnyEffect], draws: int, seed: int = 0) -> ScreenNull | None:
    """The null of the screen of ``pool`` (the identifiable candidates) on ``lin``'s problem.

    Args:
        lin: the problem linearised at the geometric fit, with ``pool``'s columns.
        pool: the candidates the diagnosis screens.
        draws: draws of pure noise.
        seed: their seed.

    Returns:
        The null, or None without candidates or without room for a fit.
    """
    if not pool:
        return None
    if lin.design is None:  # a large problem: the null of a random subset (conservative)
        rng = np.random.default_rng([seed, 1])
        index = np.sort(rng.choice(len(lin.data), NULL_MAX_POSES, replace=False))
        lin = Linearised(lin.base, lin.data.subset(index), lin.n_folds, seed, pool)
    design = lin.design
    if design is None or design.jac.shape[0] <= len(lin.free):
        return None
    noise = _noise(lin, design, draws, np.random.default_rng([seed, 2]))
    takes = [np.arange(len(lin.free))] + [
        np.concatenate([np.arange(len(lin.free)), lin.columns[ext.label]]) for ext in pool
    ]
    rms = held_out_rms(design, takes, noise, lin.kind.width)
    return ScreenNull(np.max(rms[0] / rms[1:], axis=0), len(pool))


def p_values(base: float, null: ScreenNull | None) -> Callable[[Screen], float]:
    """A screened candidate's family-wise p-value: of its linearised gain over the baseline's
    linearised cross-validated RMS ``base`` [mm], under ``null`` (1 without a null)."""

    def p_value(screen: Screen) -> float:
        return 1.0 if null is None else null.p_value(base / screen.cv_rms_mm)

    return p_value


def held_out_rms(design: Design, takes: Sequence[np.ndarray], res: np.ndarray, width: int) -> np.ndarray:
    """Linearised K-fold cross-validated RMS of residuals ``res`` (R, D) fitted on each set of
    columns of ``takes``: (len(takes), D) [the residuals' unit] (the held-out error of a pose:
    its 3-D position error; of a pair: its distance error)."""
    jac = design.jac
    norms = np.linalg.norm(jac, axis=0)
    jac = jac / np.where(norms > 0, norms, 1.0)  # unit columns: the normal equations stay well scaled
    squares, entries = np.zeros((len(takes), res.shape[1])), 0
    all_gram, all_moment = jac.T @ jac, jac.T @ res  # a fold's training terms: these less its own
    for fold in range(design.n_folds):
        held = design.held(fold)
        out = held & design.counted
        held_j = jac[held]
        gram, moment = all_gram - held_j.T @ held_j, all_moment - held_j.T @ res[held]
        out_j, out_r = jac[out], res[out]  # |r - J s|² = |r|² - 2 sᵀ(Jᵀr) + sᵀ(JᵀJ)s on the held-out rows
        out_gram, out_moment, out_sq = out_j.T @ out_j, out_j.T @ out_r, np.sum(out_r**2, axis=0)
        for k, (take, step) in enumerate(zip(takes, least_squares_steps(gram, moment, takes))):
            cross = np.sum(step * out_moment[take], axis=0)
            curve = np.sum(step * (out_gram[np.ix_(take, take)] @ step), axis=0)
            squares[k] += out_sq - 2.0 * cross + curve
        entries += int(np.count_nonzero(out)) // min(width, 3)
    return np.sqrt(np.maximum(squares, 0.0) / max(entries, 1))


def _noise(lin: Linearised, design: Design, draws: int, rng: np.random.Generator) -> np.ndarray:
    """(R, draws) residual rows of pure noise: unit noise per axis on each measured point, carried
    to the rows by the measurement kind; for pose data, orientation rows in the ratio to the
    position rows that the geometric fit's residuals show."""
    kind, problem = lin.kind, design.problem
    n_rows = design.jac.shape[0]
    points = rng.standard_normal((len(problem.data), 3, draws))
    rows = kind.noise_rows(problem, n_rows, points)
    if kind.width > 3:
        res = lin.residuals[: len(problem.data) * kind.width].reshape(-1, kind.width)
        position, rotation = np.sqrt(np.mean(res[:, :3] ** 2)), np.sqrt(np.mean(res[:, 3:] ** 2))
        ratio = rotation / position if position > 0 else 1.0
        turn = rng.standard_normal((len(problem.data), kind.width - 3, draws)) * ratio
        rows[: len(problem.data) * kind.width].reshape(len(problem.data), kind.width, draws)[:, 3:, :] = turn
    return rows
