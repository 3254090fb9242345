"""The direction each joint moved into each row: what lost motion (reversal error) follows.

Rows are taken in the order the robot visited them (a CSV's order, a recording's time stamps,
a program's targets as programmed).
"""

from __future__ import annotations

import numpy as np

#: A joint whose command moves by this or less [rad or m] keeps its direction (contracts.md).
STILL = 1e-9


def move_directions(q: np.ndarray) -> np.ndarray:
    """Each joint's direction of motion into each row (N, n), rows in the order visited: +1 when
    the command rose from the previous row, -1 when it fell, the previous row's direction when it
    moved by :data:`STILL` or less (the joint stays on its flank), 0 on the first row."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    step = np.vstack([np.zeros((1, q.shape[1])), np.diff(q, axis=0)])
    sign = np.sign(step) * (np.abs(step) > STILL)
    rows = np.arange(len(q))[:, None] * (sign != 0)
    last = np.maximum.accumulate(rows, axis=0)  # the last row where each joint moved
    return np.take_along_axis(sign, last, axis=0)
