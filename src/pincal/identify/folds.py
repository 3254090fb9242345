"""Cross-validation folds: which poses each fold holds out, and which residual rows they are."""

from __future__ import annotations

import numpy as np

from pincal.data.dataset import Dataset
from pincal.identify.measurements import Problem

__all__ = ["fold_indices", "held_out_rows", "pose_folds"]


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
