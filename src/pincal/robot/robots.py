"""Robots: resolve a ROBOT argument, load its URDF into Pinocchio and take the base-to-tip chain.

A :class:`Robot` holds the reduced Pinocchio model (every joint off the base-to-tip path, and any
joint not asked for, is locked), the names and kinds of the chain's joints, and the nominal
chain written as ``base_T_tip(q) = C_0 · exp(S_1 q_1) · C_1 · ... · exp(S_n q_n) · C_n``:
constant placements ``C_k`` (the URDF's joint origins, then the tip frame's placement) and the
joints' local unit twists ``S_j``. Lengths are metres, angles radians.
"""

from __future__ import annotations

import importlib.metadata
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from pincal.errors import RobotError
from pincal.options import BUNDLED
from pincal.robot.descriptions import URDF_SUFFIXES, robot_description
from pincal.robot.inertias import borrow_inertias
from pincal.robot.joint_kinds import (
    actuated_joints,
    joint_limits,
    joint_path,
    reference_configuration,
    tree_joints,
)
from pincal.robot.marker_tips import is_marker_spec, marker_spec, parse_marker_tips
from pincal.robot.urdf_parse import parse_urdf
from pincal.workers import share

if TYPE_CHECKING:
    from pincal.robot.ur_frames import URKinematics

_FRAME_PREFERENCE = (pin.FrameType.BODY, pin.FrameType.FIXED_JOINT, pin.FrameType.OP_FRAME)


def bundled_urdf(name: str) -> Path:
    """Path of a bundled robot's URDF.

    Args:
        name: one of :data:`BUNDLED`.
    """
    if name not in BUNDLED:
        raise RobotError(f"unknown robot {name!r}: give a .urdf path or one of {', '.join(BUNDLED)}")
    source, rel, _ = BUNDLED[name]
    if source == "pincal":
        package = Path(__file__).resolve().parents[1]  # pincal/
        for folder in (package / "urdf", package.parents[1] / "urdf"):  # installed, then source tree
            if (folder / rel).is_file():
                return folder / rel
        raise RobotError(f"bundled URDF {rel} is missing from this installation of pincal")
    dist = importlib.metadata.distribution("example-robot-data")
    path = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots"))) / rel
    if not path.is_file():
        raise RobotError(f"example-robot-data has no {rel}: reinstall example-robot-data")
    return path


@dataclass(frozen=True, eq=False)
class Robot:
    """A serial chain from the URDF's root to a tip frame, on a reduced Pinocchio model.

    Attributes:
        name: the ROBOT argument as given (bundled name or path).
        urdf_path: the URDF file.
        model: reduced Pinocchio model whose joints are exactly the chain's joints, in order.
        tip: name of the tip frame (the frame whose point or pose is measured).
        tip_frame_id: index of the tip frame in ``model``.
        joint_names: names of the chain's actuated joints, base to tip.
        prismatic: for each chain joint, True when it is prismatic (its value is in metres).
        lower: lower joint limits [rad or m] (-inf for continuous joints).
        upper: upper joint limits [rad or m] (+inf for continuous joints).
        urdf_joints: every joint name of the URDF (including those locked or off the chain).
        urdf_text: the URDF the model was built from (a xacro's output, a kinematics YAML applied).
        lent_text: that URDF with the masses lent by ``inertias`` (empty when none were lent):
            what a corrected URDF is written from, so that its gravity torques are the fit's.
        marker_frames: ``tip=1=FRAME_A,2=FRAME_B``: each marker label's frame (else empty).
        tips: a tree (markers on several frames): those frames, ``tip`` first, else empty.
    """

    name: str
    urdf_path: Path
    model: pin.Model
    tip: str
    tip_frame_id: int
    joint_names: tuple[str, ...]
    prismatic: tuple[bool, ...]
    lower: np.ndarray
    upper: np.ndarray
    urdf_joints: tuple[str, ...] = ()
    urdf_text: str = field(default="", repr=False)
    lent_text: str = field(default="", repr=False)
    marker_frames: dict[str, str] = field(default_factory=dict)
    tips: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        share(self)  # to and from worker processes by reference (a fold's calibration holds it)

    @property
    def is_tree(self) -> bool:
        """Whether markers are on several frames (the chain is then a tree)."""
        return len(self.tips) > 1

    @property
    def tip_spec(self) -> str:
        """The ``tip=`` that loads this chain again (``1=FRAME_A,2=FRAME_B`` for markers by label)."""
        return marker_spec(self.marker_frames) if self.marker_frames else self.tip

    def marker_tip(self, label: str) -> int:
        """The index in :attr:`tips` of the frame marker ``label`` is on (0: the tip).

        Raises:
            RobotError: ``tip=`` names frames by label and not this one.
        """
        if not self.marker_frames:
            return 0
        if label not in self.marker_frames:
            given = ", ".join(self.marker_frames)
            raise RobotError(
                f"the data has marker {label}, which tip= does not place on a frame (it names {given}): "
                f"add {label}=FRAME to tip="
            )
        return max(0, list(self.tips).index(self.marker_frames[label])) if self.tips else 0

    @cached_property
    def parents(self) -> tuple[int, ...]:
        """A tree's parent joint of each chain joint (-1: the base), else empty."""
        if not self.is_tree:
            return ()
        return tuple(int(self.model.parents[j]) - 1 for j in self._joint_ids)

    @cached_property
    def tip_joints(self) -> tuple[int, ...]:
        """A tree's chain joint each of :attr:`tips` hangs on, else empty."""
        if not self.is_tree:
            return ()
        return tuple(int(self.model.frames[_find_frame(self.model, f)].parentJoint) - 1 for f in self.tips)

    @property
    def n_joints(self) -> int:
        """Number of actuated joints in the chain."""
        return len(self.joint_names)

    @cached_property
    def axes(self) -> np.ndarray:
        """Local unit twists ``S_j`` of the chain's joints, (n, 6) in Pinocchio order (v, ω)."""
        data = self.model.createData()
        pin.forwardKinematics(self.model, data, pin.neutral(self.model))
        return np.array([np.asarray(data.joints[j].S).reshape(6) for j in self._joint_ids])

    @cached_property
    def placements(self) -> tuple[pin.SE3, ...]:
        """Nominal constant placements ``C_0 ... C_n`` of the chain (joint origins, then tip)."""
        joints = [self.model.jointPlacements[j].copy() for j in self._joint_ids]
        if self.is_tree:  # each tip's placement on its joint
            return (
                *joints,
                *(self.model.frames[_find_frame(self.model, f)].placement.copy() for f in self.tips),
            )
        return (*joints, self.model.frames[self.tip_frame_id].placement.copy())

    @property
    def _joint_ids(self) -> range:
        return range(1, self.model.njoints)

    def configuration(self, q: np.ndarray) -> np.ndarray:
        """Pinocchio configuration vector of the reduced model for chain joint values ``q``.

        Args:
            q: joint values (n,) [rad for revolute, m for prismatic].
        """
        return self.configurations(np.asarray(q, dtype=float).reshape(1, self.n_joints))[0]

    def configurations(self, q: np.ndarray) -> np.ndarray:
        """:meth:`configuration` of each row of ``q`` (N, n) -> (N, nq), without a Python call per row.

        Args:
            q: joint values (N, n) [rad for revolute, m for prismatic].
        """
        q = np.asarray(q, dtype=float).reshape(-1, self.n_joints)
        out = np.empty((len(q), self.model.nq))
        for k, j in enumerate(self._joint_ids):
            joint = self.model.joints[j]
            if joint.nq == 2:  # continuous joint: (cos, sin)
                out[:, joint.idx_q], out[:, joint.idx_q + 1] = np.cos(q[:, k]), np.sin(q[:, k])
            else:
                out[:, joint.idx_q] = q[:, k]
        return out

    def frame_placement(self, q: np.ndarray) -> pin.SE3:
        """``base_T_tip`` by Pinocchio's forward kinematics (the reference for every model)."""
        data = self.model.createData()
        pin.framesForwardKinematics(self.model, data, self.configuration(q))
        return data.oMf[self.tip_frame_id].copy()

    def frame_jacobian(self, q: np.ndarray) -> np.ndarray:
        """Pinocchio's tip-frame Jacobian (6, n), LOCAL_WORLD_ALIGNED: rows (v [m/unit], ω [rad/unit])."""
        data = self.model.createData()
        pin.computeJointJacobians(self.model, data, self.configuration(q))
        pin.updateFramePlacements(self.model, data)
        return pin.getFrameJacobian(
            self.model, data, self.tip_frame_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        ).copy()

    def random_configurations(self, n: int, rng: np.random.Generator, margin: float = 0.0) -> np.ndarray:
        """Uniform joint values within the limits (continuous and ±2π joints drawn in [-π, π]).

        Args:
            n: number of configurations.
            rng: random generator.
            margin: fraction of each range left out at both ends.
        """
        lo = np.where(np.isfinite(self.lower), self.lower, -math.pi)
        hi = np.where(np.isfinite(self.upper), self.upper, math.pi)
        wide = (hi - lo) > 2 * math.pi
        lo, hi = np.where(wide, -math.pi, lo), np.where(wide, math.pi, hi)
        span = hi - lo
        return lo + span * (margin + (1 - 2 * margin) * rng.random((n, self.n_joints)))


def _deepest_body(model: pin.Model) -> str:
    """The body frame with the most joints between the base and it (the last such, on ties)."""
    bodies = [f for f in model.frames if f.type == pin.FrameType.BODY]
    best = max(len(joint_path(model, f.parentJoint)) for f in bodies)
    return next(f.name for f in reversed(bodies) if len(joint_path(model, f.parentJoint)) == best)


def _find_frame(model: pin.Model, name: str) -> int:
    matches = [i for i, f in enumerate(model.frames) if f.name == name]
    if not matches:
        links = sorted({f.name for f in model.frames if f.type == pin.FrameType.BODY})
        raise RobotError(f"no frame named {name!r} in the URDF; links are: {', '.join(links)}")
    for kind in _FRAME_PREFERENCE:
        for i in matches:
            if model.frames[i].type == kind:
                return i
    return matches[0]


def load_robot(
    robot: str | Path,
    tip: str | None = None,
    joints: Iterable[str] | None = None,
    locked: Mapping[str, float] | None = None,
    *,
    xacro_args: Mapping[str, str] | None = None,
    package_paths: Mapping[str, Path] | None = None,
    kinematics: str | Path | URKinematics | None = None,
    inertias: str | Path | None = None,
) -> Robot:
    """Load a robot and reduce it to the chain from its base to ``tip``.

    Args:
        robot: a ``.urdf`` or ``.xacro`` path, or a bundled name (see :data:`BUNDLED`).
        tip: the measured frame; defaults to the bundled robot's documented tip, or the last link.
        joints: if given, only these chain joints stay actuated (for example the data's columns);
            the other chain joints are locked.
        locked: values for locked joints [rad or m]; unspecified ones are locked at neutral.
        xacro_args, package_paths, kinematics: a xacro's arguments and ``$(find)`` folders, and a
            UR kinematics YAML applied on top (see :func:`pincal.robot.descriptions.robot_description`).
        inertias: a URDF (or bundled name) whose links lend their masses to the links of the same
            name that have none (:func:`pincal.robot.inertias.borrow_inertias`), for gravity torques;
            ``urdf_text`` stays the URDF's own.

    Raises:
        RobotError: unknown name, unreadable URDF, unknown tip frame or joint.
    """
    name = str(robot)
    markers = parse_marker_tips(tip) if tip is not None and is_marker_spec(tip) else {}
    frames = list(dict.fromkeys(markers.values()))
    tip = frames[0] if frames else tip
    if name in BUNDLED:
        path = bundled_urdf(name)
        tip = tip or BUNDLED[name][2]
    else:
        path = Path(name)
        if path.suffix.lower() not in URDF_SUFFIXES:
            raise RobotError(f"unknown robot {name!r}: give a .urdf path or one of {', '.join(BUNDLED)}")
        if not path.exists():
            raise RobotError(f"URDF file not found: {path}")
    text = robot_description(path, xacro_args, package_paths, kinematics)
    lent = "" if inertias is None else _with_inertias(text, inertias)
    full, mimic = parse_urdf(path, lent or text)
    if tip is None:
        tip = _deepest_body(full)
    tip_id = _find_frame(full, tip)
    if full.frames[tip_id].parentJoint == 0:
        raise RobotError(
            f"frame {tip!r} has no joint between the base and it: choose a tip on the arm with tip="
        )
    if len(frames) > 1:
        keep = tree_joints(full, [_find_frame(full, f) for f in frames], frames, joints, mimic)
    else:
        keep = actuated_joints(full, tip_id, tip, joints, mimic)
    q_ref = reference_configuration(full, locked)
    lock = [j for j in range(1, full.njoints) if j not in keep]
    model = pin.buildReducedModel(full, lock, q_ref) if lock else full
    tip_id = _find_frame(model, tip)
    if model.frames[tip_id].parentJoint != model.njoints - 1 and model.njoints > 1 and len(frames) < 2:
        raise RobotError(f"frame {tip!r} is not at the end of the chain")  # pragma: no cover
    names = tuple(model.names[1:])
    prismatic, lower, upper = joint_limits(model)
    return Robot(
        name=name,
        urdf_path=path,
        model=model,
        tip=tip,
        tip_frame_id=tip_id,
        joint_names=names,
        prismatic=prismatic,
        lower=lower,
        upper=upper,
        urdf_joints=tuple(full.names[1:]),
        urdf_text=text,
        lent_text=lent,
        marker_frames=markers,
        tips=tuple(frames) if len(frames) > 1 else (),
    )


def _with_inertias(text: str, donor: str | Path) -> str:
    """``text`` with the masses of the URDF or bundled robot ``donor`` (see :func:`load_robot`)."""
    name = str(donor)
    path = bundled_urdf(name) if name in BUNDLED else Path(name)
    if not path.is_file():
        raise RobotError(f"inertias={name}: no such URDF file, nor a bundled robot ({', '.join(BUNDLED)})")
    return borrow_inertias(text, robot_description(path), name)
