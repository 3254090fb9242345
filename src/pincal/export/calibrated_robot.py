"""A calibration read back from the files ``pincal calibrate -o FILE.urdf`` wrote: the corrected
URDF, and its sidecar ``FILE.calibration.json`` (tool, registration, joint-angle extension)."""

from __future__ import annotations

import json
import tempfile
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from pincal.errors import DataError
from pincal.export.effects_json import read_effects
from pincal.export.ur_yaml import is_yaml
from pincal.export.urdf_writer import moved_origins, robot_source, sidecar_path
from pincal.inputs import read_bytes
from pincal.kinematics.effects import AnyEffect, split_params
from pincal.robot.marker_tips import marker_spec
from pincal.robot.robots import Robot, load_robot

#: Largest sidecar read [bytes] (one is a few kB).
MAX_SIDECAR_BYTES = 10_000_000


@dataclass(frozen=True, eq=False)
class CalibratedRobot:
    """A calibration loaded from its files: corrected geometry, tool and joint-angle extension.

    Attributes:
        robot: the chain of the corrected URDF to the calibrated tip.
        tool: ``tip_T_tool``, the measured point (and frame, after pose data) on the tip [m].
        measure: what the calibration measured (``position``, ``pose`` or ``distance``).
        extension: the identified non-geometric effects (one or several), or None.
        effect: their parameters (units in ``extension.units``).
        instrument_T_base: the identified registration of the instrument, or None.
        urdf_alone: the written URDF alone (:attr:`alone`).
        markers: several markers (sidecar ``markers``): each label's frame and point on it [m]
            (the tool is then the identity), else None.
    """

    robot: Robot
    tool: pin.SE3
    measure: str = "position"
    extension: AnyEffect | None = None
    effect: np.ndarray = field(default_factory=lambda: np.zeros(0))
    instrument_T_base: pin.SE3 | None = None
    urdf_alone: CalibratedRobot | None = field(default=None, repr=False)

    @property
    def alone(self) -> CalibratedRobot:
        """What a URDF consumer gets: the written URDF with the sidecar's top-level registration
        and tool, no effect."""
        if self.urdf_alone is not None:
            return self.urdf_alone
        return replace(self, extension=None, effect=np.zeros(0))

    markers: dict[str, tuple[str, np.ndarray]] | None = None

    def reached(self, q: np.ndarray, directions: np.ndarray | None = None) -> np.ndarray:
        """Joint values (N, n) the robot reaches for commands ``q`` (N, n) [rad or m], the rows in
        the order the robot moves through them (lost motion reads each joint's direction from the
        previous row; the first row's is unknown), or moving in ``directions`` (N, n; +1, -1, 0)
        when given."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if self.extension is None:
            return q
        moves = None if directions is None else np.atleast_2d(directions)
        return q + self.extension.joint_error(q, self.effect, moves)

    def lost_motion(self) -> dict[str, float]:
        """Each joint with a lost motion effect, and its ``lost_motion`` parameter [rad or m]: the
        joint reaches ``q + v·s`` moving in direction ``s``, and a reversal jumps by ``2|v|``."""
        if self.extension is None:
            return {}
        pairs = split_params(self.extension, self.effect)
        return {e.joint: float(p[0]) for e, p in pairs if e.effect == "lost_motion"}

    def tool_pose(self, q: np.ndarray, previous: np.ndarray | None = None) -> pin.SE3:
        """``base_T_tool`` for one command ``q`` (n,) [rad or m], the effects included; a lost
        motion needs the command the robot came from, ``previous`` (n,) (None: unknown, no
        lost motion: use :meth:`tool_poses` for a sequence)."""
        rows = np.atleast_2d(q) if previous is None else np.vstack([previous, q])
        return self.robot.frame_placement(self.reached(rows)[-1]) * self.tool

    def tool_poses(self, q: np.ndarray) -> list[pin.SE3]:
        """``base_T_tool`` for each command of ``q`` (N, n), the rows in the order the robot
        visits them (each joint's lost motion from the row before; the first row's unknown)."""
        return [self.robot.frame_placement(row) * self.tool for row in self.reached(q)]

    @cached_property
    def tool_frame(self) -> tuple[pin.Model, int]:
        """A copy of the robot's Pinocchio model with a frame ``pincal_tool``, and that frame's id."""
        model = pin.Model(self.robot.model)
        tip = model.frames[self.robot.tip_frame_id]
        placement = tip.placement * self.tool
        frame = pin.Frame("pincal_tool", tip.parentJoint, self.robot.tip_frame_id, placement, pin.OP_FRAME)
        return model, model.addFrame(frame)


def rigid_transform(matrix: object, what: str, tol: float = 1e-6) -> pin.SE3:
    """A 4×4 homogeneous matrix as an SE3, refused unless finite and rigid.

    Args:
        matrix: nested lists or an array (4, 4): rotation and translation [m], last row 0 0 0 1.
        what: how to name the matrix in the message.
        tol: largest error of ``RᵀR = I``, ``det R = 1`` and the last row.

    Raises:
        ValueError: not 4×4 numbers, not finite, a translation of 1e6 m or more (which overflows
            the kinematics), or not a rotation and translation.
    """
    m = np.array(matrix, dtype=float)
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise ValueError(f"{what}: not a 4x4 matrix of finite numbers")
    if np.abs(m[:3, 3]).max() >= 1e6:
        raise ValueError(f"{what}: a translation of 1e6 m or more")
    rot = m[:3, :3]
    if (
        np.abs(rot.T @ rot - np.eye(3)).max() > tol
        or abs(np.linalg.det(rot) - 1.0) > tol
        or np.abs(m[3] - [0.0, 0.0, 0.0, 1.0]).max() > tol
    ):
        raise ValueError(f"{what}: the matrix is not a rotation and a translation")
    return pin.SE3(m)


def _registration(entry: Any) -> pin.SE3 | None:
    return None if entry is None else rigid_transform(entry["matrix"], "instrument_T_base")


def _calibrated(robot: Robot, side: dict[str, Any]) -> CalibratedRobot:
    """The full model a sidecar describes on the written URDF's chain ``robot``, with the URDF
    alone as its :attr:`~CalibratedRobot.alone`."""
    measure = str(side.get("measure", "position"))
    markers = read_markers(side.get("markers"))
    tool = _tool(side["tip_T_tool"], markers)
    reg = _registration(side["instrument_T_base"])
    alone = CalibratedRobot(robot, tool, measure, None, np.zeros(0), reg, markers=markers)
    full = side.get("complete")
    if full is not None:
        moves = {name: rigid_transform(m["matrix"], name) for name, m in full["joint_origins"].items()}
        robot = _moved(robot, moves)
        markers = read_markers(full.get("markers"))
        tool = _tool(full["tip_T_tool"], markers)
    registration = _registration(full["instrument_T_base"] if full is not None else side["instrument_T_base"])
    ext, effect = read_effects(robot, side.get("extension"))
    return CalibratedRobot(robot, tool, measure, ext, effect, registration, alone, markers)


def _tool(entry: Any, markers: dict[str, tuple[str, np.ndarray]] | None) -> pin.SE3:
    """A sidecar's ``tip_T_tool`` (the identity with several markers, where it is null)."""
    return pin.SE3.Identity() if markers else rigid_transform(entry["matrix"], "tip_T_tool")


def _moved(robot: Robot, moves: dict[str, pin.SE3]) -> Robot:
    """``robot`` with each joint origin of ``moves`` times its transform, loaded as a URDF."""
    return robot_from_urdf(moved_origins(robot_source(robot), moves), robot)


def robot_from_urdf(document: bytes, like: Robot) -> Robot:
    """The chain of ``like`` (its tip or markers' frames, its joints) in the URDF ``document``,
    loaded as a consumer loads the file."""
    with tempfile.TemporaryDirectory(prefix="pincal-") as folder:
        path = Path(folder) / "robot.urdf"
        path.write_bytes(document)
        return load_robot(path, tip=like.tip_spec, joints=like.joint_names)


def load_calibration(
    urdf: str | Path,
    sidecar: str | Path | None = None,
    *,
    nominal: str | Path | None = None,
    **robot_options: Any,
) -> CalibratedRobot:
    """Load what ``pincal calibrate -o FILE`` wrote: the corrected URDF (or UR kinematics YAML)
    and ``FILE.calibration.json``.

    Args:
        urdf: the corrected URDF, or the UR kinematics YAML written by ``-o FILE.yaml``.
        sidecar: its sidecar (default: ``<stem>.calibration.json`` beside it).
        nominal: for a YAML, the UR robot it applies to (a URDF or xacro path, or a bundled name).
        robot_options: for a YAML, :func:`pincal.load_robot`'s ``xacro_args``, ``package_paths``
            and ``inertias`` for ``nominal`` (its ``kinematics`` is the YAML).

    Raises:
        DataError: the sidecar is missing or is not a pincal sidecar; a YAML without ``nominal``.
        RobotError: the URDF cannot be loaded or lacks the sidecar's tip.
    """
    urdf = Path(urdf)
    if is_yaml(urdf) and nominal is None:
        raise DataError(
            f"{urdf} is a UR kinematics YAML: give the UR robot it applies to (the URDF it was calibrated on)"
        )
    path = Path(sidecar) if sidecar is not None else sidecar_path(urdf)
    try:
        side = json.loads(read_bytes(path, "calibration sidecar", MAX_SIDECAR_BYTES).decode("utf-8"))
    except RecursionError:  # brackets nested deeper than Python's stack
        raise DataError(f"cannot read the calibration sidecar {path}: nested too deeply") from None
    except DataError:
        if path.exists():
            raise  # a device, a pipe, too large (issue 33)
        raise DataError(
            f"no calibration sidecar {path}: give the URDF written by 'pincal calibrate -o', "
            "with its .calibration.json beside it"
        ) from None
    except (OSError, ValueError) as exc:
        raise DataError(f"cannot read the calibration sidecar {path}: {exc}") from None
    if not isinstance(side, dict):
        raise DataError(f"{path} is not a pincal calibration sidecar: not a JSON object")
    try:
        chain: dict[str, Any] = {"tip": sidecar_tip(side), "joints": side.get("joints")}
        if is_yaml(urdf):
            robot = load_robot(nominal or "", **chain, **{**robot_options, "kinematics": urdf})
        else:
            robot = load_robot(urdf, **chain)
        return _calibrated(robot, side)
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:  # issue 33: any shape
        raise DataError(f"{path} is not a pincal calibration sidecar: bad or missing {exc}") from None
    except DataError as exc:  # issue 33: a payload the sidecar gives is checked as --payload is
        raise DataError(f"{path}: {exc}") from None


def sidecar_tip(side: dict[str, Any]) -> str:
    """The ``tip=`` that loads a sidecar's chain: its ``tip``, or with markers on several frames
    each marker's (``1=FRAME_A,2=FRAME_B``)."""
    markers = side.get("markers") or {}
    frames = {str(k): str(m["frame"]) for k, m in dict(markers).items()}
    return marker_spec(frames) if len(set(frames.values())) > 1 else str(side["tip"])


def read_markers(entry: Any) -> dict[str, tuple[str, np.ndarray]] | None:
    """The sidecar's ``markers`` (``{LABEL: {"frame", "point_m"}}``) as label -> (frame, point [m]).

    Raises:
        ValueError, KeyError, TypeError: not that shape, or a point that is not 3 finite numbers.
    """
    if entry is None:
        return None
    out = {}
    for label, marker in dict(entry).items():
        point = np.array([float(v) for v in marker["point_m"]])
        if point.shape != (3,) or not np.all(np.isfinite(point)):
            raise ValueError(f"markers: the point of marker {label} is not 3 finite numbers")
        out[str(label)] = (str(marker["frame"]), point)
    return out or None
