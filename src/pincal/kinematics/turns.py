"""A joint's motion and a constant placement applied to frames batched over poses.

:func:`pincal.kinematics.chain.forward` composes a chain's frames from these: each joint's kind
(prismatic, revolute about one of its frame's own axes, revolute about another axis) is worked out
once per chain's axes, and each batch's sines and cosines once.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import pinocchio as pin


def skew(v: np.ndarray) -> np.ndarray:
    """Skew-symmetric matrices of vectors (..., 3) -> (..., 3, 3)."""
    if v.ndim == 1:  # one vector: a literal, several times faster than the indexed writes
        x, y, z = v.tolist()
        return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def stacked_dot(rot: np.ndarray, mat: np.ndarray) -> np.ndarray:
    """``rot @ mat`` for stacked matrices (N, 3, k) and one matrix (k, m): a single BLAS call."""
    return (rot.reshape(-1, rot.shape[2]) @ mat).reshape(rot.shape[0], 3, mat.shape[1])


def moved(rot: np.ndarray, pos: np.ndarray, c: pin.SE3, out_rot: np.ndarray, out_pos: np.ndarray) -> None:
    """Write the frames (N, 3, 3), (N, 3) followed by the constant placement ``c`` into ``out_rot``,
    ``out_pos``."""
    flat = rot.reshape(-1, 3)
    out_rot[...] = (flat @ c.rotation).reshape(rot.shape)
    np.add(pos, (flat @ c.translation).reshape(pos.shape), out=out_pos)


@functools.lru_cache(maxsize=64)
def _turn_kinds(axes: bytes, n: int) -> tuple[tuple[str, Any], ...]:
    """How each of ``n`` joints of local twists ``axes`` (bytes of (n, 6)) moves its frame:
    ``("prismatic", v)``; ``("about", (i, k, sign))``, a revolute joint about one of the
    frame's own axes, which mixes columns ``i`` and ``k`` of ``R``; ``("general", K)``, about
    the unit axis of skew matrix ``K``."""
    kinds: list[tuple[str, Any]] = []
    for v, w in ((row[:3], row[3:]) for row in np.frombuffer(axes).reshape(n, 6)):
        along = np.flatnonzero(w)
        if along.size == 0:
            kinds.append(("prismatic", v.copy()))
        elif along.size == 1 and abs(w[along[0]]) == 1.0:
            i, k = ((1, 2), (2, 0), (0, 1))[along[0]]
            kinds.append(("about", (i, k, float(w[along[0]]))))
        else:
            kinds.append(("general", skew(w)))
    return tuple(kinds)


class Turns:
    """The joints' motions for a batch of joint values (N, n): sines and cosines taken once."""

    def __init__(self, axes: np.ndarray, q: np.ndarray) -> None:
        self.kinds = _turn_kinds(np.ascontiguousarray(axes, dtype=float).tobytes(), axes.shape[0])
        self.q = q
        self.sin, self.cos = np.sin(q.T)[:, :, None], np.cos(q.T)[:, :, None]  # (n, N, 1)

    def apply(
        self, j: int, rot: np.ndarray, pos: np.ndarray, out_rot: np.ndarray, out_pos: np.ndarray
    ) -> None:
        """Write the frames (N, 3, 3), (N, 3) moved by joint ``j`` into ``out_rot``, ``out_pos``: a
        revolute joint through the frame's origin turns it by ``I + s K + (1 - c) K²``; about one
        of the frame's own axes (most URDF joints), that mixes two columns of ``R``."""
        kind, how = self.kinds[j]
        if kind == "prismatic":
            out_rot[...] = rot
            np.add(pos, (rot @ how) * self.q[:, j, None], out=out_pos)
            return
        out_pos[...] = pos
        s, c = self.sin[j], self.cos[j]
        if kind == "about":
            i, k, sign = how
            s = s if sign > 0 else -s
            out_rot[...] = rot
            col_i, col_k = rot[:, :, i], rot[:, :, k]
            out_rot[:, :, i] = c * col_i + s * col_k
            out_rot[:, :, k] = c * col_k - s * col_i
            return
        rot_k = stacked_dot(rot, how)
        out_rot[...] = rot + s[:, :, None] * rot_k + (1.0 - c)[:, :, None] * stacked_dot(rot_k, how)
