"""Rotation vectors of stacked rotations: ``pin.log3`` and ``pin.Jlog3`` vectorised over poses."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from pincal.kinematics.turns import skew


def log3(rot: np.ndarray) -> np.ndarray:
    """``pin.log3`` of stacked rotations (N, 3, 3) -> rotation vectors (N, 3) [rad]."""
    cos = np.clip((np.trace(rot, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    angle = np.arccos(cos)
    vee = np.stack([rot[:, 2, 1] - rot[:, 1, 2], rot[:, 0, 2] - rot[:, 2, 0], rot[:, 1, 0] - rot[:, 0, 1]], 1)
    small = angle < 1e-4  # θ / (2 sin θ) by its series
    factor = np.where(small, 0.5 + angle**2 / 12.0, angle / (2.0 * np.sin(np.where(small, 1.0, angle))))
    out = factor[:, None] * vee
    for p in np.flatnonzero(angle > np.pi - 1e-2):  # near a half turn, R - Rᵀ says too little
        out[p] = pin.log3(rot[p])
    return out


def jlog3(rot: np.ndarray, log: np.ndarray | None = None) -> np.ndarray:
    """``pin.Jlog3`` of stacked rotations (N, 3, 3) -> (N, 3, 3), given or computing their logs."""
    log = log3(rot) if log is None else log
    angle = np.linalg.norm(log, axis=1)
    small = angle < 1e-2  # the closed form cancels below; the series' next term is θ⁴/30240
    safe = np.where(small, 1.0, angle)
    closed = 1.0 / safe**2 - (1.0 + np.cos(safe)) / (2.0 * safe * np.sin(safe))
    coef = np.where(small, 1.0 / 12.0 + angle**2 / 720.0, closed)
    k = skew(log)
    return np.eye(3) + 0.5 * k + coef[:, None, None] * (k @ k)
