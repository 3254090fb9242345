"""Cross-validation folds: which poses each fold holds out, and which residual rows they are."""

from __future__ import annotations

import numpy as np

from pincal.data.dataset import Dataset
from pincal.identify.measurements import Problem

__all__ = ["fold_indices", "held_out_rows", "held_out_squares", "pose_folds"]


def fold_indices(n: int, folds: int, seed: int = 0) -> list[np.ndarray]:
    """Random partition of ``n`` poses into ``folds`` held-out index sets (sorted)."""
    order = np.random.default_rng(seed).permutation(n)
    return [np.sort(f) for f in np.array_split(order, folds)]


def pose_folds(data: Dataset, folds: int | None, seed: int = 0) -> list[np.ndarray]:
    """Held-out row sets of ``data``: :func:`fold_indices` of its poses (``folds`` None: each pose
    alone); with several markers per pose, a pose's rows (one per marker seen) go together."""
    if data.marker is None:
        n = len(data)
        return [np.array([i]) for i in range(n)] if folds is None else fold_indices(n, folds, seed)
    poses, at = np.unique(data.row_numbers, return_inverse=True)
    n = len(poses)
    sets = [np.array([i]) for i in range(n)] if folds is None else fold_indices(n, min(folds, n), seed)
    return [np.flatnonzero(np.isin(at, s)) for s in sets]


def held_out_rows(problem: Problem, folds: int | None, seed: int) -> list[np.ndarray]:
    """Residual rows of each held-out group (a pose, or a fold of poses; for distance data, the
    rows of every pair with a pose in it): linearised cross-validation's groups."""
    n_poses = len(problem.data)
    held = pose_folds(problem.data, folds, seed)
    if problem.measurement.measure.by_pairs:  # the pairs the data has (all, Gao's or given)
        groups = [np.flatnonzero(np.isin(problem.pairs, h).any(axis=1)) for h in held]
        return [g for g in groups if len(g)]
    group = np.full(n_poses + 1, -1)  # each pose's group, and last -1: no group
    for k, h in enumerate(held):
        group[h] = k
    of_row = group[problem.row_poses()]  # a known distance's row (pose -1) is in none
    order = np.argsort(of_row, kind="stable")
    bounds = np.searchsorted(of_row[order], np.arange(len(held) + 1))
    return [order[a:b] for a, b in zip(bounds[:-1], bounds[1:])]


def held_out_squares(
    jac: np.ndarray, spread: np.ndarray, fitted: np.ndarray, groups: list[np.ndarray]
) -> np.ndarray:
    """Each group's squared leave-group-out error of a linear fit, in closed form: the norm of
    ``(I - H_gg)⁺ r_g`` over its rows ``g``, ``H = J · spreadᵀ`` the fit's hat matrix.

    Groups of one size go through one batched solve (a pose's rows: every group alike).

    Args:
        jac: the fit's Jacobian (R, k).
        spread: ``J (JᵀJ + Λ)⁻¹`` (R, k) for the fit's penalty ``Λ`` (none, or the pull's).
        fitted: the fit's residuals (R,), or (R, D) for ``D`` residual vectors sharing the fit.
        groups: the residual rows of each held-out group.

    Returns:
        (G,) or (G, D) squared errors [the residuals' unit squared].
    """
    many = fitted if fitted.ndim == 2 else fitted[:, None]
    out = np.empty((len(groups), many.shape[1]))
    sizes = np.array([len(g) for g in groups])
    for size in np.unique(sizes):
        which = np.flatnonzero(sizes == size)
        rows = np.array([groups[k] for k in which]).reshape(len(which), int(size))  # (G, s)
        hat = jac[rows] @ spread[rows].transpose(0, 2, 1)  # (G, s, s)
        err = np.linalg.pinv(np.eye(int(size)) - hat) @ many[rows]  # (G, s, D)
        out[which] = np.sum(err**2, axis=1)
    return out if fitted.ndim == 2 else out[:, 0]
