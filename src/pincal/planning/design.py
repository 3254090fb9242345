"""Optimal experimental design on identification rows: D- and I-optimal criteria, greedy and exchange.

A design is a set of candidate poses. Each pose ``k`` adds rows ``Gₖ`` (r, P) to the whitened,
column-scaled information matrix ``F = Σ Gₖᵀ Gₖ + δ I``. The design is judged on one or more
*hypotheses* ``h`` at once (the same poses seen with different guesses of an unknown tool point),
each with its own rows and information ``F_h``; the loss to minimise is summed over them:

* ``d``: ``-Σ_h log det F_h`` (D-optimality: the volume of the parameters' confidence ellipsoid);
* ``i``: ``Σ_h tr(W_h F_h⁻¹)`` (I-optimality: the mean squared prediction error over task poses,
  ``W_h = mean_t J_tᵀ J_t`` of the task rows in the same scaled parameters).

Adding (``s = +1``) or removing (``s = -1``) the rows ``G`` of one pose changes ``F⁻¹`` by the
Woodbury identity with ``S = I + s G F⁻¹ Gᵀ``: ``F⁻¹ ← F⁻¹ - s F⁻¹ Gᵀ S⁻¹ G F⁻¹``; the loss
changes by ``-log det S`` (d) or ``-s tr(S⁻¹ G F⁻¹ W F⁻¹ Gᵀ)`` (i), for every candidate at once.

The search is a greedy start (D-optimal, the only criterion defined before ``F`` has full rank),
then exchanges in the manner of Mitchell's DETMAX: add the candidate that lowers the loss most,
remove the pose whose removal raises it least; stop when that is the pose just added. Every
exchange lowers the loss, so it ends. :func:`swap` then makes Fedorov's exchanges on given pools
(e.g. small moves of each pose, :func:`pincal.planning.plan.plan_poses`): each pose in turn is
replaced by the candidate of its pool that lowers the loss most, when one does.

Rows may depend on the design itself (distance data: a pose's rows are its pairs with the chosen
poses), so they come from a function ``rows(h, candidates, chosen)`` -> (len(candidates), r, P).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

Rows = Callable[[int, np.ndarray, Sequence[int]], np.ndarray]
CRITERIA = ("i", "d")


def _change(
    criterion: str, finv: np.ndarray, weight: np.ndarray | None, g: np.ndarray, sign: float
) -> np.ndarray:
    """Change of one hypothesis' loss (len(g),) when the rows ``g`` (m, r, P) of each of m poses
    are added (``sign`` +1) or removed (-1); ``inf`` where a removal would make ``F`` singular."""
    m, r, p = g.shape
    flat = g.reshape(-1, p)
    gf = (flat @ finv).reshape(m, r, p)  # one BLAS product for all candidates
    s = np.eye(r) + sign * np.einsum("mrp,msp->mrs", gf, g)
    sign_det, logdet = np.linalg.slogdet(s)
    bad = (sign_det <= 0) | (logdet < -30.0)
    if criterion == "d" or weight is None:
        out = -logdet
    else:
        ga = (flat @ (finv @ weight @ finv)).reshape(m, r, p)
        b = np.einsum("mrp,msp->mrs", ga, g)
        s_safe = np.where(bad[:, None, None], np.eye(r), s)
        out = -sign * np.trace(np.linalg.solve(s_safe, b), axis1=1, axis2=2)
    return np.where(bad, np.inf, out)


def _update(finv: np.ndarray, g: np.ndarray, sign: float) -> np.ndarray:
    """``F⁻¹`` after adding (``sign`` +1) or removing (-1) the rows ``g`` (r, P)."""
    gf = g @ finv
    s = np.eye(len(g)) + sign * gf @ g.T
    return finv - sign * gf.T @ np.linalg.solve(s, gf)


def information(rows: Rows, h: int, chosen: Sequence[int], prior: np.ndarray) -> np.ndarray:
    """``F_h = F₀ + Σ Gₖᵀ Gₖ`` of the chosen poses, each pose's rows given the poses before it."""
    info = prior.copy()
    for n, k in enumerate(chosen):
        g = rows(h, np.array([k]), chosen[:n])[0]
        info += g.T @ g
    return info


def loss(criterion: str, infos: Sequence[np.ndarray], weights: Sequence[np.ndarray] | None) -> float:
    """The design's loss (lower is better): ``-Σ log det F_h`` or ``Σ tr(W_h F_h⁻¹)``."""
    if criterion == "d" or weights is None:
        return -float(sum(np.linalg.slogdet(f)[1] for f in infos))
    return float(sum(np.trace(w @ np.linalg.inv(f)) for f, w in zip(infos, weights)))


def greedy(rows: Rows, n_candidates: int, n: int, priors: Sequence[np.ndarray]) -> list[int]:
    """``n`` candidates chosen one at a time for the largest ``Σ_h log det F_h`` from ``F_h = F₀``."""
    n_hyp = len(priors)
    finvs = [np.linalg.inv(f) for f in priors]
    chosen: list[int] = []
    every = np.arange(n_candidates)
    for _ in range(n):
        change = np.sum([_change("d", f, None, rows(h, every, chosen), 1.0) for h, f in enumerate(finvs)], 0)
        change[chosen] = np.inf
        k = int(np.argmin(change))
        finvs = [_update(finvs[h], rows(h, np.array([k]), chosen)[0], 1.0) for h in range(n_hyp)]
        chosen.append(k)
    return chosen


def exchange(
    criterion: str,
    rows: Rows,
    n_candidates: int,
    start: Sequence[int],
    priors: Sequence[np.ndarray],
    weights: Sequence[np.ndarray] | None = None,
    max_exchanges: int = 200,
) -> list[int]:
    """Exchanges from ``start`` (DETMAX): add the best candidate, drop the least useful pose.

    Args:
        criterion: ``d`` or ``i``.
        rows: the rows of candidates given the chosen poses, per hypothesis.
        n_candidates: how many candidates there are.
        start: the starting design (indices), e.g. :func:`greedy`'s.
        priors: ``F₀`` per hypothesis: what is known before any pose (a small ridge ``δ I`` that
            keeps ``F`` invertible, plus the rows of known distances).
        weights: ``W_h`` per hypothesis (criterion ``i``).
        max_exchanges: at most this many exchanges.

    Returns:
        The design, of the same size as ``start``.
    """
    chosen, n_hyp = list(start), len(priors)
    finvs = [np.linalg.inv(information(rows, h, chosen, priors[h])) for h in range(n_hyp)]
    every = np.arange(n_candidates)

    def weight(h: int) -> np.ndarray | None:
        return None if weights is None else weights[h]

    for _ in range(max_exchanges):
        change = np.sum(
            [_change(criterion, f, weight(h), rows(h, every, chosen), 1.0) for h, f in enumerate(finvs)], 0
        )
        change[chosen] = np.inf
        k = int(np.argmin(change))
        grown = [*chosen, k]
        added = [_update(finvs[h], rows(h, np.array([k]), chosen)[0], 1.0) for h in range(n_hyp)]
        cost = np.zeros(len(grown))
        for h in range(n_hyp):
            mine = np.stack([rows(h, np.array([j]), [i for i in grown if i != j])[0] for j in grown])
            cost += _change(criterion, added[h], weight(h), mine, -1.0)
        drop = int(np.argmin(cost))
        if drop == len(grown) - 1:
            break
        others = [i for n, i in enumerate(grown) if n != drop]
        finvs = [_update(added[h], rows(h, np.array([grown[drop]]), others)[0], -1.0) for h in range(n_hyp)]
        chosen = others
    return chosen


def swap(
    criterion: str,
    rows: Rows,
    start: Sequence[int],
    priors: Sequence[np.ndarray],
    pools: Sequence[np.ndarray],
    weights: Sequence[np.ndarray] | None = None,
    tol: float = 1e-4,
) -> list[int]:
    """One pass of Fedorov's exchanges: pose ``n`` replaced by the best candidate of ``pools[n]``.

    Args:
        criterion: ``d`` or ``i``.
        rows: the rows of candidates given the chosen poses, per hypothesis.
        start: the design (indices).
        priors: ``F₀`` per hypothesis.
        pools: per pose of ``start``, the candidates (indices) that may replace it.
        weights: ``W_h`` per hypothesis (criterion ``i``).
        tol: a replacement must lower the loss by this much (relative for ``i``, absolute
            ``log det`` for ``d``).

    Returns:
        The design, of the same size, its loss never higher than ``start``'s.
    """
    chosen, n_hyp = list(start), len(priors)
    finvs = [np.linalg.inv(information(rows, h, chosen, priors[h])) for h in range(n_hyp)]
    ws: list[np.ndarray | None] = [None] * n_hyp if weights is None else list(weights)
    for pos, pool in enumerate(pools):
        pool = np.setdiff1d(np.asarray(pool, dtype=int), chosen)
        if not len(pool):
            continue
        others = chosen[:pos] + chosen[pos + 1 :]
        out = [rows(h, np.array([chosen[pos]]), others)[0] for h in range(n_hyp)]
        cost = sum(float(_change(criterion, f, w, g[None], -1.0)[0]) for f, w, g in zip(finvs, ws, out))
        if not np.isfinite(cost):
            continue
        removed = [_update(f, g, -1.0) for f, g in zip(finvs, out)]
        gain = np.sum(
            [_change(criterion, f, ws[h], rows(h, pool, others), 1.0) for h, f in enumerate(removed)], 0
        )
        k = int(np.argmin(gain))
        scale = 1.0 if criterion == "d" else sum(np.trace(w @ f) for w, f in zip(ws, finvs) if w is not None)
        if cost + gain[k] < -tol * scale:
            finvs = [_update(f, rows(h, pool[k : k + 1], others)[0], 1.0) for h, f in enumerate(removed)]
            chosen[pos] = int(pool[k])
    return chosen
