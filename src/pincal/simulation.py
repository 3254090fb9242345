"""A simulated "true robot" and instrument, for tests, the demo and the notebooks.

The truth is any model with parameters (by default ``placements``: 6-DoF errors of every joint
origin plus joint zero offsets), seen through an instrument at an unknown pose, measuring a
point (or a frame) fixed on the tip at an unknown place, with Gaussian noise. Everything is
seeded and deterministic.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin

from .data import Dataset
from .effects import Extension
from .kinematics import forward
from .models import Model, PlacementsModel
from .robots import Robot


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
    extension: Extension | None = None
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
    return TrueRobot(model, x.reshape(-1), reg, tool)


def hide_effect(
    truth: TrueRobot, extension: Extension, q: np.ndarray, rms: float, seed: int = 0
) -> TrueRobot:
    """The same truth with an effect whose tip displacement over poses ``q`` has RMS ``rms`` [m].

    The direction of the effect's parameters (for a harmonic, its phase) is drawn with ``seed``.
    """
    rng = np.random.default_rng(seed)
    direction = _unit(rng.normal(size=extension.n_params))
    direction *= 1e-5 / np.abs(extension.regressors(q) @ direction).max()  # a small probe, 1e-5 rad
    base = truth.target(q)[0]
    moved = replace(truth, extension=extension, effect=direction).target(q)[0]
    size = float(np.sqrt(np.mean(np.sum((moved - base) ** 2, axis=1))))
    return replace(truth, extension=extension, effect=direction * rms / size)


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
