"""Chain kinematics vectorised over poses, and the one Jacobian mechanism every model shares.

Every parameterization writes the robot as a serial chain

    base_T_tip(q) = C_0 · exp(S_1 q_1) · C_1 · exp(S_2 q_2) · ... · exp(S_n q_n) · C_n

with constant placements ``C_k`` (functions of the model's parameters) and local unit joint
twists ``S_j``. The chain has ``2n + 1`` *positions*: position ``2k`` is the frame after ``C_k``,
position ``2j - 1`` the frame after joint ``j``'s motion. A parameter acts on the chain as a
right-perturbation ``exp(ζ ε)`` at one or more positions, with a local twist ``ζ``; its effect on
the tip is then ``Ad(base_T_position) ζ``. A joint's own column is the same thing with ``ζ = S_j``
at position ``2j - 1``, which is what :func:`joint_jacobian` uses and what the tests compare to
Pinocchio's frame Jacobian.

Arrays are batched over poses: rotations ``(N, 3, 3)``, translations ``(N, 3)`` [m]. Twists and
Jacobian rows are in Pinocchio's order (v, ω). Tip Jacobians are LOCAL_WORLD_ALIGNED: the velocity
[m/unit] of the tip origin and the angular velocity [rad/unit], both in base axes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pincal.kinematics.turns import Turns, moved, skew, stacked_dot
from pincal.robot.robots import Robot


@dataclass(frozen=True)
class Chain:
    """A chain's constant placements and joint twists.

    A tree (several markers on the branches of a robot, issue 41) has ``parents`` and
    ``tip_joints``: joint ``j``'s placement ``C_j`` is then in the frame after its parent joint's
    motion (the base for -1), and ``placements`` ends with one placement per tip frame, each on
    the joint ``tip_joints`` names. A chain leaves both empty (each joint's parent the previous
    one, one tip on the last joint).

    Attributes:
        placements: ``C_0 ... C_n`` as SE3 (a tree: ``C_0 ... C_{n-1}``, then each tip's).
        axes: joint twists ``S_j`` (n, 6) in the frame after ``C_{j-1}``, order (v, ω).
        parents: a tree's parent joint of each joint (-1: the base), else empty.
        tip_joints: a tree's joint each tip frame hangs on, else empty.
    """

    placements: tuple[pin.SE3, ...]
    axes: np.ndarray
    parents: tuple[int, ...] = ()
    tip_joints: tuple[int, ...] = ()

    @classmethod
    def nominal(cls, robot: Robot) -> Chain:
        """The chain of the robot's URDF joint origins and tip placement."""
        return cls(robot.placements, robot.axes, robot.parents, robot.tip_joints)

    def with_joints(self, placements: list[pin.SE3] | tuple[pin.SE3, ...]) -> Chain:
        """The same chain (axes, tips, tree) with the joints' placements ``C_0 ... C_{n-1}`` replaced."""
        n = self.axes.shape[0]
        return Chain((*placements[:n], *self.placements[n:]), self.axes, self.parents, self.tip_joints)

    def registered(self, reg: pin.SE3) -> Chain:
        """The chain seen from an instrument at ``reg`` (``instrument_T_base``): every joint on
        the base premultiplied."""
        roots = [0] if not self.parents else [j for j, p in enumerate(self.parents) if p < 0]
        placements = list(self.placements)
        for j in roots:
            placements[j] = reg * placements[j]
        return Chain(tuple(placements), self.axes, self.parents, self.tip_joints)


@dataclass(frozen=True)
class Frames:
    """World frames of every chain position, for a batch of poses.

    A tree's frames (:func:`forward` with ``row_tips``) hold a position per tip after the
    joints' (``2n + t``); each pose's tip is its own (``row_tips``), and ``reach`` says which
    positions move it (the joints between the base and its tip, and the tip itself).

    Attributes:
        rotations: (2n + 1, N, 3, 3) ``base_R_position`` (a tree: (2n + T, N, 3, 3)).
        translations: (2n + 1, N, 3) ``base_p_position`` [m].
        row_tips: a tree's tip of each pose (N,), else None (the last position).
        reach: a tree's (2n + T, N) whether position k moves pose i's tip, else None (all do).
        first_tip: a tree's position of its first tip (2n).
    """

    rotations: np.ndarray
    translations: np.ndarray
    row_tips: np.ndarray | None = None
    reach: np.ndarray | None = None
    first_tip: int = 0

    @property
    def tip_rotation(self) -> np.ndarray:
        """``base_R_tip`` (N, 3, 3)."""
        if self.row_tips is None:
            return self.rotations[-1]
        return self.rotations[self._tip_positions, np.arange(len(self.row_tips))]

    @property
    def tip_translation(self) -> np.ndarray:
        """``base_p_tip`` (N, 3) [m]."""
        if self.row_tips is None:
            return self.translations[-1]
        return self.translations[self._tip_positions, np.arange(len(self.row_tips))]

    @property
    def _tip_positions(self) -> np.ndarray:
        assert self.row_tips is not None
        return self.first_tip + self.row_tips

    def acting(self, k: int) -> np.ndarray | None:
        """(N, 1, 1) 1 where position ``k`` moves the pose's tip, else 0; None when every one does."""
        return None if self.reach is None else self.reach[k][:, None, None].astype(float)


def forward(chain: Chain, q: np.ndarray, row_tips: np.ndarray | None = None) -> Frames:
    """World frames of all chain positions for joint values ``q`` (N, n) [rad or m]; a tree's
    (:func:`forward_tree`) with each pose's tip ``row_tips`` (N,) (default: the first)."""
    if chain.parents:
        return forward_tree(chain, q, row_tips)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n_poses, n = q.shape
    rotations = np.empty((2 * n + 1, n_poses, 3, 3))
    translations = np.empty((2 * n + 1, n_poses, 3))
    rotations[0], translations[0] = chain.placements[0].rotation, chain.placements[0].translation
    turn = Turns(chain.axes, q)
    for j in range(n):
        turn.apply(j, rotations[2 * j], translations[2 * j], rotations[2 * j + 1], translations[2 * j + 1])
        moved(
            rotations[2 * j + 1],
            translations[2 * j + 1],
            chain.placements[j + 1],
            rotations[2 * j + 2],
            translations[2 * j + 2],
        )
    return Frames(rotations, translations)


def forward_tree(chain: Chain, q: np.ndarray, row_tips: np.ndarray | None = None) -> Frames:
    """World frames of a tree's positions (see :class:`Chain`, :class:`Frames`): joint ``j``'s at
    ``2j`` (after ``C_j``) and ``2j + 1`` (after its motion), tip ``t``'s at ``2n + t``."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n_poses, n = q.shape
    n_tips = len(chain.tip_joints)
    rotations = np.empty((2 * n + n_tips, n_poses, 3, 3))
    translations = np.empty((2 * n + n_tips, n_poses, 3))
    base = (np.broadcast_to(np.eye(3), (n_poses, 3, 3)), np.zeros((n_poses, 3)))
    turn = Turns(chain.axes, q)
    for j in range(n):
        p = chain.parents[j]
        rot, pos = base if p < 0 else (rotations[2 * p + 1], translations[2 * p + 1])
        moved(rot, pos, chain.placements[j], rotations[2 * j], translations[2 * j])
        turn.apply(j, rotations[2 * j], translations[2 * j], rotations[2 * j + 1], translations[2 * j + 1])
    for t, j in enumerate(chain.tip_joints):
        rot, pos = rotations[2 * j + 1], translations[2 * j + 1]
        moved(rot, pos, chain.placements[n + t], rotations[2 * n + t], translations[2 * n + t])
    tips = np.zeros(n_poses, dtype=int) if row_tips is None else np.asarray(row_tips, dtype=int)
    return Frames(rotations, translations, tips, tree_reach(chain, tips), 2 * n)


def tree_reach(chain: Chain, row_tips: np.ndarray) -> np.ndarray:
    """(2n + T, N): whether position k moves pose i's tip (``row_tips``) in a tree."""
    n, n_tips = chain.axes.shape[0], len(chain.tip_joints)
    table = np.zeros((2 * n + n_tips, n_tips), dtype=bool)
    for t, j in enumerate(chain.tip_joints):
        table[2 * n + t, t] = True
        while j >= 0:
            table[2 * j : 2 * j + 2, t] = True
            j = chain.parents[j]
    return table[:, row_tips]


def twist_columns(
    rot: np.ndarray, pos: np.ndarray, zeta: np.ndarray, point: np.ndarray, rotation: bool = True
) -> tuple[np.ndarray, np.ndarray | None]:
    """Effect of right-perturbations ``exp(ζ ε)`` of frames on a point attached beyond them.

    Args:
        rot, pos: the perturbed frames, ``R`` (N, 3, 3) and ``p`` (N, 3) [m], or one frame.
        zeta: local twists (6, m), order (v, ω).
        point: the moved point (N, 3) [m], in the same axes as ``p``.
        rotation: whether to return the angular velocity too.

    Returns:
        The point's velocity ``R ζ_v + (R ζ_ω) × (point - p)`` (N, 3, m) [m/unit] and the
        angular velocity ``R ζ_ω`` (N, 3, m) [rad/unit] (None unless ``rotation``).
    """
    if rot.shape == (3, 3):  # one frame for every point: its columns once, then a cross product
        return _one_frame_columns(rot, pos, zeta, point, rotation)
    if rot.shape != (len(point), 3, 3):
        rot = np.broadcast_to(rot, (len(point), 3, 3))
    rot = np.ascontiguousarray(rot)
    arm = skew(point - pos) @ rot  # [lever]× R: v = R ζ_v - lever × (R ζ_ω)
    v = stacked_dot(np.concatenate([rot, -arm], axis=2), zeta)
    return v, stacked_dot(rot, zeta[3:]) if rotation else None


def _one_frame_columns(
    rot: np.ndarray, pos: np.ndarray, zeta: np.ndarray, point: np.ndarray, rotation: bool
) -> tuple[np.ndarray, np.ndarray | None]:
    """:func:`twist_columns` of one frame ``R`` (3, 3), ``p`` (3,) for every point: ``R ζ_v`` and
    ``R ζ_ω`` are the same for all, and each point adds ``(R ζ_ω) × (point - p)``."""
    along, turn = rot @ zeta[:3], rot @ zeta[3:]  # (3, m) each
    x, y, z = ((point - pos).T[i][:, None] for i in range(3))  # (N, 1) each
    v = np.empty((len(point), 3, zeta.shape[1]))
    v[:, 0] = along[0] + turn[1] * z - turn[2] * y
    v[:, 1] = along[1] + turn[2] * x - turn[0] * z
    v[:, 2] = along[2] + turn[0] * y - turn[1] * x
    return v, np.broadcast_to(turn, v.shape).copy() if rotation else None


def summed_columns(
    frames: Frames,
    twists: np.ndarray,
    point: np.ndarray,
    rotation: bool = False,
    to_log: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Columns of parameters that perturb chain positions on their right, summed over positions.

    Every position's ``[R | -[point - p]× R]`` (N, 3, 6) is laid side by side, and one matrix
    product with the stacked twists gives all columns: the same arithmetic as
    :func:`twist_columns` per position, without a NumPy call per position and parameter.

    Args:
        frames: output of :func:`forward`; a tree's positions move only the rows of their branch.
        twists: (K, 6, c) local twist of each of ``c`` parameters at each of the first ``K``
            positions (zero where a parameter does not act).
        point: the moved point (N, 3) [m], in the frames' axes.
        rotation: also return the angular velocity.
        to_log: (N, 3, 3) map applied to the angular velocity (implies ``rotation``).

    Returns:
        The point's velocity (N, 3, c) [m/unit] and the (mapped) angular velocity (N, 3, c)
        [rad/unit], or None unless asked.
    """
    n, c = len(point), twists.shape[2]
    at = np.flatnonzero(np.any(twists != 0.0, axis=(1, 2)))
    rotation = rotation or to_log is not None
    if at.size == 0:
        return np.zeros((n, 3, c)), np.zeros((n, 3, c)) if rotation else None
    rot = frames.rotations[at]  # (K, N, 3, 3)
    if frames.reach is not None:  # a tree: the position moves only its branch's rows
        rot = rot * frames.reach[at][:, :, None, None]
    lever = point[None] - frames.translations[at]  # (K, N, 3)
    turned = rot.transpose(1, 2, 0, 3)  # (N, 3 rows, K, 3)
    side = np.empty((n, 3, len(at), 6))  # [R | -[lever]× R] of every position, side by side
    side[..., :3] = turned
    x, y, z = (lever[:, :, i].T[:, :, None] for i in range(3))  # (N, K, 1)
    side[:, 0, :, 3:] = z * turned[:, 1] - y * turned[:, 2]
    side[:, 1, :, 3:] = x * turned[:, 2] - z * turned[:, 0]
    side[:, 2, :, 3:] = y * turned[:, 0] - x * turned[:, 1]
    v = (side.reshape(3 * n, 6 * len(at)) @ twists[at].reshape(6 * len(at), c)).reshape(n, 3, c)
    if not rotation:
        return v, None
    turns = rot.transpose(1, 2, 0, 3).reshape(3 * n, 3 * len(at))
    w = (turns @ twists[at, 3:].reshape(3 * len(at), c)).reshape(n, 3, c)
    return v, w if to_log is None else to_log @ w


def tip_jacobian(frames: Frames, twists: np.ndarray, point: np.ndarray | None = None) -> np.ndarray:
    """Tip Jacobian of right-perturbations given at chain positions.

    Args:
        frames: output of :func:`forward`.
        twists: (2n + 1, 6, p) local twist of each of ``p`` parameters at each position
            (zero where a parameter does not act).
        point: the point whose velocity the rows give (N, 3) [m] (default: the tip's origin).

    Returns:
        (N, 6, p) LOCAL_WORLD_ALIGNED Jacobian of the tip: rows (v [m/unit], ω [rad/unit]).
    """
    point = frames.tip_translation if point is None else point
    v, w = summed_columns(frames, twists, point, rotation=True)
    return np.concatenate([v, w], axis=1)


def joint_jacobian(chain: Chain, frames: Frames) -> np.ndarray:
    """Tip Jacobian with respect to the joint values (N, 6, n), LOCAL_WORLD_ALIGNED.

    Joint ``j`` is a right-perturbation by ``S_j`` at position ``2j - 1``: the same mechanism as
    every parameter, so comparing this with :meth:`Robot.frame_jacobian` checks it.
    """
    n = chain.axes.shape[0]
    twists = np.zeros((2 * n + 1, 6, n))
    for j in range(n):
        twists[2 * j + 1, :, j] = chain.axes[j]
    return tip_jacobian(frames, twists)


def right_twists(
    factors: list[pin.SE3], local: list[tuple[int, int, np.ndarray]], n_params: int
) -> np.ndarray:
    """Right-perturbation twists of a product of factors ``C = F_0 · F_1 · ... · F_m``.

    Args:
        factors: the factors ``F_i``.
        local: entries ``(parameter, i, ζ)``: the parameter perturbs ``F_i`` on its right by the
            local twist ``ζ`` (6,).
        n_params: number of parameter columns.

    Returns:
        (6, n_params) twists of the same perturbations on the right of the whole product ``C``:
        ``Ad(suffix⁻¹) ζ``, with ``suffix = F_{i+1} · ... · F_m``.
    """
    out = np.zeros((6, n_params))
    suffixes = [pin.SE3.Identity()] * len(factors)
    acc = pin.SE3.Identity()
    for i in range(len(factors) - 1, -1, -1):
        suffixes[i] = acc
        acc = factors[i] * acc
    for param, i, zeta in local:
        out[:, param] += suffixes[i].actInv(pin.Motion(zeta)).vector
    return out
