"""A simulated "true robot" and instrument, for tests, the demo and the notebooks.

The truth is any model with parameters (by default ``placements``: 6-DoF errors of every joint
origin plus joint zero offsets), seen through an instrument at an unknown pose, measuring a
point (or a frame) fixed on the tip at an unknown place, with Gaussian noise. Fixed-point data
(:func:`simulate_points`) has no instrument: a ball on the tip is held in sockets, each row the
commands that put the true ball there. Everything is seeded and deterministic.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pinocchio as pin

from pincal.data.dataset import Dataset
from pincal.errors import DataError
from pincal.kinematics.chain import forward, joint_jacobian
from pincal.kinematics.effects import AnyEffect, Extension, combined
from pincal.kinematics.models import Model, PlacementsModel
from pincal.kinematics.turns import skew
from pincal.robot.robots import Robot


@dataclass(frozen=True, eq=False)
class TrueRobot:
    """The robot as it really is, and the instrument that measures it.

    Attributes:
        model: the parameterization the truth is written in.
        x: its parameters (the geometric errors).
        instrument_T_base: the instrument's registration.
        tool: ``tip_T_target``; its translation is the measured point on the tip [m].
        extension: a hidden non-geometric effect, or None.
        effect: the hidden effect's parameters.
    """

    model: Model
    x: np.ndarray
    instrument_T_base: pin.SE3
    tool: pin.SE3
    extension: AnyEffect | None = None
    effect: np.ndarray | None = None

    @property
    def robot(self) -> Robot:
        """The nominal robot."""
        return self.model.robot

    def target(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """True target positions (N, 3) [m] and rotations (N, 3, 3) in the instrument frame."""
        q = np.atleast_2d(q)
        if self.extension is not None and self.effect is not None:
            q = q + self.extension.joint_error(q, self.effect)
        frames = forward(self.model.chain(self.x), q)
        rot = frames.tip_rotation @ self.tool.rotation
        pos = frames.tip_translation + frames.tip_rotation @ self.tool.translation
        reg = self.instrument_T_base
        return pos @ reg.rotation.T + reg.translation, reg.rotation @ rot

    def measure(
        self,
        q: np.ndarray,
        noise: float = 3e-5,
        rot_noise: float | None = None,
        seed: int = 0,
    ) -> Dataset:
        """Measure the target at joint values ``q`` (N, n).

        Args:
            q: joint values [rad or m].
            noise: standard deviation of each position coordinate [m].
            rot_noise: standard deviation of each orientation axis [rad]; None measures no
                orientation (position data).
            seed: seed of the noise.
        """
        rng = np.random.default_rng(seed)
        pos, rot = self.target(q)
        pos = pos + rng.normal(0.0, noise, pos.shape)
        quats = None
        if rot_noise is not None:
            quats = np.empty((len(pos), 4))
            for i, r in enumerate(rot):
                noisy = pin.exp3(rng.normal(0.0, rot_noise, 3)) @ r
                qt = pin.Quaternion(noisy)
                quats[i] = (qt.w, qt.x, qt.y, qt.z)
        return Dataset(self.robot.joint_names, np.array(q, dtype=float), pos, quats)


def random_truth(
    robot: Robot,
    seed: int = 0,
    translation_std: float = 0.5e-3,
    rotation_std: float = 0.5e-3,
    offset_std: float = 1e-3,
    instrument: bool = True,
    tool_std: float = 0.05,
    tool_distance: tuple[float, float] | None = None,
) -> TrueRobot:
    """A random true robot: placement errors, joint offsets, instrument pose and tool point.

    Args:
        robot: the nominal robot.
        seed: random seed.
        translation_std: 1σ of each joint origin's translation error [m].
        rotation_std: 1σ of each joint origin's rotation error [rad].
        offset_std: 1σ of each joint's zero offset [rad] (or [m] for prismatic joints).
        instrument: place the instrument at a random pose 2-4 m away; False puts it at the base.
        tool_std: 1σ of each coordinate of the measured point on the tip [m].
        tool_distance: instead, the point at a random direction and a distance drawn uniformly
            in this range from the tip frame's origin [m].
    """
    rng = np.random.default_rng(seed)
    model = PlacementsModel(robot)
    n = robot.n_joints
    x = np.zeros((n, 6))
    x[:, :3] = rng.normal(0.0, translation_std, (n, 3))
    x[:, 3:] = rng.normal(0.0, rotation_std, (n, 3))
    x += robot.axes * rng.normal(0.0, offset_std, (n, 1))
    reg = pin.SE3.Identity()
    if instrument:
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        reg = pin.SE3(
            pin.exp3(rng.uniform(-np.pi, np.pi) * _unit(rng.normal(size=3))), direction * rng.uniform(2, 4)
        )
    tool = pin.SE3(pin.exp3(rng.normal(0.0, 0.3, 3)), rng.normal(0.0, tool_std, 3))
    if tool_distance is not None:
        tool.translation = _unit(rng.normal(size=3)) * rng.uniform(*tool_distance)
    return TrueRobot(model, x.reshape(-1), reg, tool)


def hide_effect(
    truth: TrueRobot, extension: Extension, q: np.ndarray, rms: float, seed: int = 0
) -> TrueRobot:
    """The same truth with an effect whose tip displacement over poses ``q`` has RMS ``rms`` [m].

    The direction of the effect's parameters (for a harmonic, its phase) is drawn with ``seed``;
    a compliance always sags (``c < 0``, as a real joint does).
    """
    rng = np.random.default_rng(seed)
    direction = _unit(rng.normal(size=extension.n_params))
    if extension.effect == "joint_compliance":  # a joint sags under its load (c < 0), never rises
        direction = -np.abs(direction)
    direction *= 1e-5 / np.abs(extension.regressors(q) @ direction).max()  # a small probe, 1e-5 rad
    base = truth.target(q)[0]
    moved = replace(truth, extension=extension, effect=direction).target(q)[0]
    size = float(np.sqrt(np.mean(np.sum((moved - base) ** 2, axis=1))))
    return replace(truth, extension=extension, effect=direction * rms / size)


def hide_effects(
    truth: TrueRobot, extensions: list[Extension], q: np.ndarray, rms: float | list[float], seed: int = 0
) -> TrueRobot:
    """The same truth with several effects at once, each with a tip displacement over poses ``q``
    of RMS ``rms`` [m] on its own (one figure for all, or one each; :func:`hide_effect`)."""
    sizes = [float(rms)] * len(extensions) if isinstance(rms, (int, float)) else [float(r) for r in rms]
    each = [hide_effect(truth, e, q, r, seed + k) for k, (e, r) in enumerate(zip(extensions, sizes))]
    params = np.concatenate([t.effect for t in each if t.effect is not None])
    return replace(truth, extension=combined(extensions), effect=params)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def simulate(
    robot: Robot,
    n_fit: int = 60,
    n_test: int = 100,
    seed: int = 0,
    noise: float = 3e-5,
    rot_noise: float | None = None,
    truth: TrueRobot | None = None,
    margin: float = 0.05,
) -> tuple[TrueRobot, Dataset, Dataset]:
    """A seeded experiment: the truth, ``n_fit`` fitted poses and ``n_test`` held-out poses.

    Args:
        robot: the nominal robot.
        n_fit: poses to fit.
        n_test: held-out poses.
        seed: seed of the truth, the poses and the noise.
        noise: 1σ of each position coordinate [m].
        rot_noise: 1σ of orientation noise [rad], or None for position data.
        truth: a given truth (default :func:`random_truth` with ``seed``).
        margin: fraction of each joint range left out at both ends.
    """
    truth = truth or random_truth(robot, seed)
    rng = np.random.default_rng(seed + 1)
    q = robot.random_configurations(n_fit + n_test, rng, margin)
    fit = truth.measure(q[:n_fit], noise, rot_noise, seed + 2)
    test = truth.measure(q[n_fit:], noise, rot_noise, seed + 3)
    return truth, fit, test


def points_truth(
    robot: Robot, seed: int = 0, ball: tuple[float, float] = (0.03, 0.08), **errors: Any
) -> TrueRobot:
    """A random true robot for fixed-point data: :func:`random_truth`'s geometric errors (keyword
    ``errors``), no instrument, and a ball on the tip at a random direction and a distance drawn
    in ``ball`` [m] from the tip frame's origin (the tool, unknown to a fit)."""
    rng = np.random.default_rng(seed + 7919)
    ball_at = _unit(rng.normal(size=3)) * rng.uniform(*ball)
    truth = random_truth(robot, seed, instrument=False, **errors)
    return replace(truth, tool=pin.SE3(np.eye(3), ball_at))


def simulate_points(
    truth: TrueRobot | Robot,
    points_m: np.ndarray,
    n_rows: int,
    noise_m: float,
    rng: np.random.Generator | int = 0,
    names: Sequence[str] | None = None,
    margin: float = 0.05,
    tol: float = 1e-11,
) -> Dataset:
    """Fixed-point data (:mod:`pincal.identify.fixed_points`): the ball held in sockets by hand.

    Each row is a commanded configuration found by damped least squares on the TRUE robot (its
    geometry, its hidden effect: the joints reach ``q + e(q)``, and its tool: the ball's centre on
    the tip) from a random start within the joint limits, that puts the ball at its socket plus an
    isotropic Gaussian error. The instrument of ``truth`` plays no part.

    Args:
        truth: the true robot (a :class:`~pincal.Robot` is its nominal self, ball at the tip's origin).
        points_m: (K, 3) the sockets in the base frame [m].
        n_rows: rows in all, shared out in blocks of (nearly) equal size, point by point.
        noise_m: 1σ of each coordinate of where the ball really is [m].
        rng: random generator or seed (starts, then noise).
        names: the sockets' names (default ``"0"``, ``"1"``...).
        margin: fraction of each joint range left out at both ends of the starts.
        tol: the largest position error of a reached row [m].

    Raises:
        DataError: some socket was not reached from 20 random starts per row.
    """
    if isinstance(truth, Robot):
        zero = np.zeros(PlacementsModel(truth).n_params)
        truth = TrueRobot(PlacementsModel(truth), zero, pin.SE3.Identity(), pin.SE3.Identity())
    rng = np.random.default_rng(rng) if isinstance(rng, int) else rng
    sockets = np.atleast_2d(np.asarray(points_m, dtype=float))
    labels = np.arange(n_rows) * len(sockets) // n_rows
    targets = sockets[labels] + rng.normal(0.0, noise_m, (n_rows, 3))
    q = np.empty((n_rows, truth.robot.n_joints))
    todo = np.arange(n_rows)
    for _ in range(20):
        found, ok = reach(
            truth, targets[todo], truth.robot.random_configurations(len(todo), rng, margin), tol
        )
        q[todo[ok]] = found[ok]
        todo = todo[~ok]
        if not todo.size:
            break
    if todo.size:
        raise DataError(f"rows {todo.tolist()}: their socket is out of the true robot's reach")
    point_names = tuple(names) if names is not None else tuple(str(k) for k in range(len(sockets)))
    return Dataset(truth.robot.joint_names, q, np.zeros((n_rows, 3)), labels=labels, point_names=point_names)


def ball_positions(truth: TrueRobot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where the true ball is (N, 3) [m] in the base frame for commands ``q`` (N, n), the tip's
    rotations (N, 3, 3), and the chain's Jacobian of the ball (N, 3, n) [m/rad]."""
    reached = np.atleast_2d(q)
    if truth.extension is not None and truth.effect is not None:
        reached = reached + truth.extension.joint_error(reached, truth.effect)
    chain = truth.model.chain(truth.x)
    frames = forward(chain, reached)
    arm = frames.tip_rotation @ truth.tool.translation
    jac = joint_jacobian(chain, frames)
    return frames.tip_translation + arm, frames.tip_rotation, jac[:, :3] - skew(arm) @ jac[:, 3:]


def reach(
    truth: TrueRobot, targets: np.ndarray, q: np.ndarray, tol: float, damping: float = 1e-4
) -> tuple[np.ndarray, np.ndarray]:
    """Damped least squares from ``q`` (N, n), projected on the joint limits after each step (at
    most 0.2 rad or m): the commands found and which reach their targets (N, 3) within ``tol``
    (the joint error's own derivative is left out: the error itself is exact)."""
    lo, hi = truth.robot.lower, truth.robot.upper
    err = np.full(len(q), np.inf)
    for _ in range(300):
        pos, _, jac = ball_positions(truth, q)
        miss = targets - pos
        err = np.linalg.norm(miss, axis=1)
        if err.max(initial=0.0) <= tol:
            break
        gram = jac @ np.transpose(jac, (0, 2, 1)) + damping**2 * np.eye(3)
        dq = (np.transpose(jac, (0, 2, 1)) @ np.linalg.solve(gram, miss[:, :, None]))[:, :, 0]
        size = np.abs(dq).max(axis=1, keepdims=True)
        q = np.clip(q + dq * np.minimum(1.0, 0.2 / np.maximum(size, 1e-12)), lo, hi)
    return q, err <= tol
