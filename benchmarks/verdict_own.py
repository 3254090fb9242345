"""The audit of ``verdict_audit.py`` on pincal's OWN simulator (issue 30).

The same cases, references, runs, table and acceptance as ``benchmarks/verdict_audit.py`` (imported
from it); only the truth differs: it is drawn with :mod:`pincal.simulation.truth`.

Simulation (per robot, seed and effect):

* the robot is ``pincal.load_robot("ur5")`` or ``("panda")`` (pincal's bundled URDF and default tip);
* the truth is :func:`pincal.simulation.truth.random_truth`: 0.5 mm and 0.5 mrad std per axis on every
  joint origin, 1 mrad std on every joint zero, the instrument 2-4 m away at a random orientation,
  the measured point ~5 cm std per coordinate from the tip frame;
* commands from ``Robot.random_configurations`` (the outer 5 % of each range avoided);
* measured point = the :class:`~pincal.simulation.truth.TrueRobot`'s target position (pincal's chain
  kinematics) at the reached angles, + the effect, + Gaussian noise (``--sigma`` mm per axis).

The effects are ``verdict_audit.make_effect``'s, evaluated on this truth: joint errors through the
TrueRobot's forward kinematics at q + error (sin3, cubic, the pair), point displacements from its
joint origins and tip (bending) or along the pose order (drift), gravity torques from
:func:`pincal.kinematics.gravity.gravity_torques` (the URDF's inertias). Each is scaled so that its RMS
displacement of the measured point is M x the noise floor (sqrt(3) * sigma).

The linearised references (``rigidR``, ``listR``) are ``verdict_audit``'s, computed on a Pinocchio
model holding the TrueRobot's joint placements; that model is checked to give the TrueRobot's points
(within 1 nm) before each case.

Usage::

    python benchmarks/verdict_own.py [--quick] [--robots ur5 panda] [--poses 60 100]
        [--multiples 3 6 10] [--seeds 1] [--sigma 0.05] [--jobs 1] [--json FILE] [--keep DIR]

``--quick``: ur5 only, N = 60, M in {3, 10}, one seed. Exit status 1 when a criterion fails.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
from verdict_audit import (
    EFFECTS,
    Case,
    Result,
    Robot,
    RobotSpec,
    Truth,
    main,
    run_and_collect,
    simulate_effect,
)

import pincal
import pincal.kinematics.effects
import pincal.simulation.truth
from pincal.kinematics.chain import Frames, forward
from pincal.kinematics.gravity import gravity_torques
from pincal.simulation.truth import TrueRobot, random_truth

AGREE_M = 1e-9  # [m] the Pinocchio copy of the truth must give the TrueRobot's points within this


@dataclass
class OwnRobot(Robot):
    """The audit's robot on pincal's own model (its reduced Pinocchio model, tip and joints)."""

    own: pincal.Robot | None = None

    @classmethod
    def of(cls, spec: RobotSpec) -> OwnRobot:
        """``pincal.load_robot(spec.name)`` with the spec's effect joints."""
        own = pincal.load_robot(spec.name)
        return cls(spec, own.model, own.tip, list(own.joint_names), own)


@dataclass
class OwnTruth(Truth):
    """A :class:`~pincal.simulation.truth.TrueRobot` behind the audit's :class:`Truth`: its points, joint
    origins and tip come from pincal's kinematics; the Pinocchio model (the TrueRobot's placements)
    serves only the references' perturbed models."""

    true: TrueRobot | None = None

    @classmethod
    def of(cls, true: TrueRobot, q_check: np.ndarray) -> OwnTruth:
        """The truth ``true``; raises RuntimeError when the Pinocchio copy and the TrueRobot differ by
        more than ``AGREE_M`` on the commands ``q_check`` (N, n, rad)."""
        robot = true.robot
        chain = true.model.chain(true.x)
        model = pin.Model(robot.model)
        for j in range(1, model.njoints):
            model.jointPlacements[j] = chain.placements[j - 1]
        frame = model.frames[robot.tip_frame_id]
        frame.placement = chain.placements[-1]
        model.frames[robot.tip_frame_id] = frame
        tool = np.array(true.tool.translation)
        out = cls(model, np.zeros(robot.n_joints), true.instrument_T_base, tool, robot.tip_frame_id, true)
        gap = np.abs(Truth.points(out, q_check) - out.points(q_check)).max()
        if gap > AGREE_M:
            raise RuntimeError(f"{robot.name}: the Pinocchio copy of the truth is {gap:.2e} m off")
        return out

    @property
    def _true(self) -> TrueRobot:
        assert self.true is not None
        return self.true

    def _frames(self, q: np.ndarray) -> Frames:
        return forward(self._true.model.chain(self._true.x), q)

    def points(
        self,
        q: np.ndarray,
        model: pin.Model | None = None,
        registration: pin.SE3 | None = None,
        tool: np.ndarray | None = None,
    ) -> np.ndarray:
        """Measured points (N, 3) [m], instrument frame, noise-free, at reached angles ``q`` (rad): the
        TrueRobot's; with a perturbed model, registration or tool, the Pinocchio copy's."""
        if model is None and registration is None and tool is None:
            return self._true.target(q)[0]
        return super().points(q, model, registration, tool)

    def base_points(self, q: np.ndarray) -> np.ndarray:
        """Measured points (N, 3) [m] in the base frame at reached angles ``q`` (rad)."""
        frames = self._frames(q)
        return frames.tip_translation + frames.tip_rotation @ self.tool

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """Gravity torques (N, n) [N·m] from the URDF's inertias
        (:func:`pincal.kinematics.gravity.gravity_torques`)."""
        return gravity_torques(self._true.robot, q)

    def joint_origins(self, q: np.ndarray, joint_id: int) -> np.ndarray:
        """Positions (N, 3) [m], base frame, of the origin of the joint of Pinocchio id ``joint_id``."""
        return self._frames(q).translations[2 * (joint_id - 1)]


def own_case(
    case: Case, robot: OwnRobot, sigma_mm: float
) -> tuple[Result, np.ndarray, np.ndarray, np.ndarray]:
    """Simulate one case on pincal's own truth: the result to fill, the commands (N, n, rad), the
    measured points and the noise-free ones (N, 3, m); noise ``sigma_mm`` per axis."""
    assert robot.own is not None
    key = [case.seed, case.n_poses, int(case.multiple * 10), EFFECTS.index(case.effect), len(robot.joints)]
    seed = int(np.random.SeedSequence(key).generate_state(1)[0])
    rng = np.random.default_rng(seed)
    q_cmd = robot.own.random_configurations(case.n_poses, rng, margin=0.05)
    truth = OwnTruth.of(random_truth(robot.own, seed), q_cmd[:5])
    result, points, clean = simulate_effect(case, robot, truth, q_cmd, rng, sigma_mm)
    return result, q_cmd, points, clean


def run_own(case: Case, robots: dict[str, Robot], sigma_mm: float, workdir: Path) -> Result:
    """Simulate one case with pincal's simulator, run calibrate and diagnose, collect what they said."""
    robot = robots[case.robot]
    assert isinstance(robot, OwnRobot)
    result, q_cmd, points, clean = own_case(case, robot, sigma_mm)
    return run_and_collect(result, robot, q_cmd, points, clean, sigma_mm, workdir)


if __name__ == "__main__":
    sys.exit(main(run=run_own, load=OwnRobot.of, doc=__doc__))
