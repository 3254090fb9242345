"""Nominal joint twists (product of exponentials) and Gao's closed-form twist Jacobian.

``base_T_tip(q) = exp(ξ_1 q_1) · ... · exp(ξ_n q_n) · M`` with each ``ξ_j`` the joint's unit
twist in the base frame at q = 0 and ``M`` the tip's home transform. Twists are in Pinocchio's
order (v, ω) unless a function says otherwise; Gao et al. (2013) write them (ω, v).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pinocchio as pin

from pincal.kinematics.chain import Chain, forward
from pincal.robot.robots import Robot


class Twists(NamedTuple):
    """Nominal POE description of a chain.

    Attributes:
        twists: (n, 6) joint twists ξ_j in the base frame at q = 0, order (v, ω); for a revolute
            joint |ω| = 1 and ω·v = 0 (v [m] = -ω × a point of the axis), for a prismatic one ω = 0.
        home: ``base_T_tip`` at q = 0.
        joint_frames: ``base_T_joint`` at q = 0 for each joint, so that ``ξ_j = Ad(G_j) S_j``.
    """

    twists: np.ndarray
    home: pin.SE3
    joint_frames: tuple[pin.SE3, ...]


def chain_twists(chain: Chain) -> Twists:
    """POE twists and home transform of a chain (see :class:`pincal.kinematics.chain.Chain`)."""
    n = chain.axes.shape[0]
    frames = forward(chain, np.zeros((1, n)))
    joint_frames = tuple(pin.SE3(frames.rotations[2 * j, 0], frames.translations[2 * j, 0]) for j in range(n))
    twists = np.array([g.act(pin.Motion(s)).vector for g, s in zip(joint_frames, chain.axes)])
    home = pin.SE3(frames.tip_rotation[0], frames.tip_translation[0])
    return Twists(twists.reshape(n, 6), home, joint_frames)


def nominal_twists(robot: Robot) -> Twists:
    """The robot's nominal POE twists, read from its URDF chain (checked against Pinocchio in tests)."""
    return chain_twists(Chain.nominal(robot))


def poe_forward(twists: np.ndarray, home: pin.SE3, q: np.ndarray) -> pin.SE3:
    """``base_T_tip = exp(ξ_1 q_1) ... exp(ξ_n q_n) · M`` for one configuration.

    Args:
        twists: (n, 6) base-frame twists, order (v, ω).
        home: ``M``, the tip at q = 0.
        q: (n,) joint values [rad or m].
    """
    out = pin.SE3.Identity()
    for xi, qj in zip(twists, q):
        out = out * pin.exp6(pin.Motion(xi * qj))
    return out * home


def gao_k(eta: np.ndarray) -> np.ndarray:
    """Gao et al. (2013) eq. 10: ``K`` with ``(δ(e^η) e^{-η})^∨ = K δη``, order (ω, v).

    Args:
        eta: twist (6,) in Gao's order (ω, v).

    Returns:
        (6, 6) matrix in Gao's order. It equals ``Ad(exp η) · Jexp6(η)`` of Pinocchio with both
        sides reordered, which the tests check.
    """
    w, v = eta[:3], eta[3:]
    a = float(np.linalg.norm(w))
    omega = np.zeros((6, 6))
    omega[:3, :3] = omega[3:, 3:] = _hat(w)
    omega[3:, :3] = _hat(v)
    if a < 1e-6:  # series limits of the coefficients
        c1, c2, c3, c4 = 0.5, 1.0 / 6.0, 1.0 / 24.0, 1.0 / 120.0
    else:
        s, c = np.sin(a), np.cos(a)
        c1 = (4 - a * s - 4 * c) / (2 * a**2)
        c2 = (4 * a - 5 * s + a * c) / (2 * a**3)
        c3 = (2 - a * s - 2 * c) / (2 * a**4)
        c4 = (2 * a - 3 * s + a * c) / (2 * a**5)
    o2 = omega @ omega
    return np.eye(6) + c1 * omega + c2 * o2 + c3 * (o2 @ omega) + c4 * (o2 @ o2)


def left_jacobian(eta: np.ndarray) -> np.ndarray:
    """``(δ(e^η) e^{-η})^∨ = K δη`` in Pinocchio's order (v, ω): ``Ad(exp η) · Jexp6(η)``."""
    motion = pin.Motion(np.asarray(eta, dtype=float))
    return pin.exp6(motion).action @ pin.Jexp6(motion)


def _hat(x: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])
