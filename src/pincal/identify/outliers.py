"""Outlier poses: a pose whose residual is far outside the others' (a lost tracker beam, a
mistyped row) is flagged by row number and left out of the fit.

The screen refits with a robust loss first (``soft_l1``, whose scale is the residuals' robust
spread), so one bad pose cannot drag the model towards itself and hide. Each pose then gets a
score, the size of its residual (the norm of its 3 or 6 residuals, or for distance data the RMS
of the pairs it belongs to), and a pose is an outlier when its score exceeds
``median + threshold · 1.4826 · MAD`` of all the scores, that is ``threshold`` robust standard
deviations above the typical pose. On many poses the threshold rises so that noise alone
flags no pose (:func:`noise_threshold`): among 10⁶ poses of Gaussian noise the largest is about
6 robust standard deviations above the median, and flagging it would be a false outlier (and a
second fit). A pose's score is the norm of its position and weighted rotation residuals, whose
noises differ: its tail is set by the ratio of their robust spreads (:func:`pose_sf`), and is
heavier than six equal components' (with the rotation rows' noise 5/3 of the position rows', the
threshold of six equal components flagged pure noise among 10⁶ poses in 1 data set of 20, where
it should in 1 of 100). At most :data:`MAX_FRACTION` of the poses are excluded (the worst
first): beyond that, the residuals are heavy-tailed rather than spoiled by a few poses, and the
screen leaves them alone.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pincal.identify.measurements import Problem
from pincal.options import THRESHOLD

MAX_FRACTION = 0.2  # of the poses, at most
MIN_POSES = 8  # fewer poses: no screen (too few for a robust spread)
#: Chance that the screen flags any pose of pure noise, over all the poses (:func:`noise_threshold`).
FAMILY_LEVEL = 0.01


def pose_scores(problem: Problem, theta: np.ndarray, res: np.ndarray | None = None) -> np.ndarray:
    """The size of each pose's residual (N,) [m], rotations weighted as in the fit (``res``: the
    residuals at ``theta``, when already computed)."""
    res = problem.residuals(theta) if res is None else res
    n = len(problem.data)
    if problem.measurement.measure.by_pairs:
        sq = np.zeros(n)
        count = np.zeros(n)
        for col in (0, 1):
            np.add.at(sq, problem.pairs[:, col], res**2)
            np.add.at(count, problem.pairs[:, col], 1)
        return np.sqrt(sq / np.maximum(count, 1))
    rows = problem.row_poses()
    mine = rows >= 0
    return np.sqrt(np.bincount(rows[mine], res[mine] ** 2, minlength=n))


def robust_scale(residuals: np.ndarray) -> float:
    """Robust standard deviation of residual components (1.4826 · median |r|) [m]."""
    return float(1.4826 * np.median(np.abs(residuals)))


def far_off(scores: np.ndarray, threshold: float = THRESHOLD) -> np.ndarray:
    """Which scores (N,) exceed ``median + threshold · 1.4826 · MAD`` (a mask)."""
    median = float(np.median(scores))
    mad = float(np.median(np.abs(scores - median)))
    return scores > median + threshold * 1.4826 * max(mad, 1e-3 * median, 1e-12)


def chi_sf(x: float, k: int) -> float:
    """``P(|Z| > x)`` for ``Z`` a standard Gaussian vector of ``k`` components (chi's survival)."""
    half = x * x / 2.0
    if k % 2 == 0:
        return math.exp(-half) * sum(half**i / math.factorial(i) for i in range(k // 2))
    terms, term = 0.0, x
    for i in range(1, (k - 1) // 2 + 1):
        terms, term = terms + term, term * x * x / (2 * i + 1)
    return math.erfc(x / math.sqrt(2.0)) + math.sqrt(2.0 / math.pi) * math.exp(-half) * terms


#: Gauss-Legendre nodes and weights on [-1, 1] for :func:`pose_sf`'s integral.
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(96)


def pose_sf(x: float, ratio: float) -> float:
    """``P(|a|² + ratio² |b|² > x²)`` for ``a``, ``b`` standard Gaussian 3-vectors: the survival of a
    pose's score when its weighted rotation residuals' noise is ``ratio`` times its position
    residuals' (:func:`chi_sf` with 6 components when ``ratio`` is 1). By the law of total
    probability over ``|a| = v``: ``P(|a| > x) + ∫₀ˣ f(v) P(ratio |b| > √(x² - v²)) dv``, ``f``
    the density of ``|a|``, integrated by Gauss-Legendre."""
    if ratio == 1.0:
        return chi_sf(x, 6)
    v = 0.5 * x * (_NODES + 1.0)
    density = math.sqrt(2.0 / math.pi) * v**2 * np.exp(-0.5 * v**2)
    rest = np.sqrt(np.maximum(x * x - v * v, 0.0)) / ratio
    tail = np.array([chi_sf(float(r), 3) for r in rest])
    return chi_sf(x, 3) + 0.5 * x * float(np.sum(_WEIGHTS * density * tail))


def _solve(f: Any, lo: float, hi: float) -> float:
    """The root of the decreasing ``f`` in ``[lo, hi]`` (bisection to 1e-10)."""
    while hi - lo > 1e-10:
        mid = (lo + hi) / 2.0
        lo, hi = (mid, hi) if f(mid) > 0 else (lo, mid)
    return (lo + hi) / 2.0


def noise_threshold(n: int, k: int, level: float = FAMILY_LEVEL, ratio: float = 1.0) -> float:
    """Robust standard deviations above the median (as :func:`far_off` counts them) that the
    largest of ``n`` pose scores of pure noise (norms of ``k`` Gaussian residuals; for a pose's 6,
    its rotation rows' noise ``ratio`` times its position rows', :func:`pose_sf`) passes with
    chance ``level``."""

    def sf(x: float) -> float:
        return pose_sf(x, ratio) if k == 6 else chi_sf(x, k)

    median = _solve(lambda x: sf(x) - 0.5, 0.0, 50.0)
    mad = _solve(lambda d: 0.5 - (sf(max(median - d, 0.0)) - sf(median + d)), 0.0, 50.0)
    top = _solve(lambda x: sf(x) - level / max(n, 1), 0.0, 50.0)
    return (top - median) / (1.4826 * mad)


def noise_ratio(problem: Problem, res: np.ndarray) -> float:
    """For pose data, the robust spread of the weighted rotation residuals over the position
    residuals' (1 for other data): pose scores' tails depend on it."""
    width = problem.measurement.measure.width
    if width != 6:
        return 1.0
    rows = res[: len(problem.data) * width].reshape(-1, width)
    position = robust_scale(rows[:, :3])
    return robust_scale(rows[:, 3:]) / position if position > 0 else 1.0


def find_outliers(
    problem: Problem,
    theta: np.ndarray,
    solve: Any,
    threshold: float = THRESHOLD,
) -> tuple[np.ndarray, np.ndarray]:
    """Outlier poses of a fitted problem.

    Args:
        problem: the residual function on all the poses.
        theta: the least-squares estimate on all the poses.
        solve: ``solve(theta, loss, f_scale) -> theta``, the solver the fit used.
        threshold: robust standard deviations above the median pose score.

    Returns:
        Indices of the outlier poses (worst first) and every pose's score [m] under the robust fit.
    """
    n = len(problem.data)
    if n < MIN_POSES or threshold <= 0:
        return np.empty(0, dtype=int), np.zeros(n)
    f_scale = max(robust_scale(problem.residuals(theta)), 1e-9)  # [m]
    robust = solve(theta, "soft_l1", f_scale)
    res = problem.residuals(robust)
    scores = pose_scores(problem, robust, res)
    ratio = noise_ratio(problem, res)
    threshold = max(threshold, noise_threshold(n, problem.measurement.measure.width, ratio=ratio))
    bad = np.flatnonzero(far_off(scores, threshold))
    bad = bad[np.argsort(-scores[bad])]
    if len(bad) > MAX_FRACTION * n:
        return np.empty(0, dtype=int), scores
    return bad, scores
