"""Pairs of poses for distance data: every pair, or the pairs of Gao et al. (2013)."""

from __future__ import annotations

from itertools import combinations

import numpy as np

from pincal.errors import DataError


def all_pairs(n: int) -> np.ndarray:
    """Every pair ``(i, j)``, ``i < j``, of ``n`` poses: (n(n-1)/2, 2)."""
    return np.array(list(combinations(range(n), 2)), dtype=int).reshape(-1, 2)


def gao_pairs(n: int) -> np.ndarray:
    """Gao et al. (2013) eq. 21 (0-based): (i, i+n/2), (2i, 2i-1), (4i, 4i-2), (4i-1, 4i-3).

    For the paper's 28 poses these are its 42 pairs; other ``n`` take the pairs that exist.
    """
    pairs = set()
    for i in range(1, n // 2 + 1):
        pairs.add((i, i + n // 2))
        pairs.add((2 * i - 1, 2 * i))
    for i in range(1, n // 4 + 1):
        pairs.add((4 * i - 2, 4 * i))
        pairs.add((4 * i - 3, 4 * i - 1))
    return np.array(sorted((a - 1, b - 1) for a, b in pairs if 1 <= a <= n and 1 <= b <= n and a != b))


def chosen_pairs(pairs: str | np.ndarray, n: int) -> np.ndarray | None:
    """The pairs of ``n`` poses a distance fit uses: ``"all"`` (None: every pair), ``"gao"``
    (:func:`gao_pairs`) or the pairs given (k, 2)."""
    if not isinstance(pairs, str):
        return np.asarray(pairs, dtype=int)
    if pairs not in ("all", "gao"):
        raise DataError(f"unknown pairing {pairs!r}: use all or gao")
    return gao_pairs(n) if pairs == "gao" else None
