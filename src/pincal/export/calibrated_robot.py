"""A calibration read back from the files ``pincal calibrate -o FILE.urdf`` wrote: the corrected
URDF, and its sidecar ``FILE.calibration.json`` (tool, registration, joint-angle extension)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from pincal.errors import DataError
from pincal.export.ur_yaml import is_yaml
from pincal.export.urdf_writer import sidecar_path
from pincal.inputs import read_bytes
from pincal.kinematics.chain import rigid_transform
from pincal.kinematics.effects import Extension, Payload
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
        extension: the identified non-geometric effect, or None.
        effect: its parameters (units in ``extension.units``).
        instrument_T_base: the identified registration of the instrument, or None.
    """

    robot: Robot
    tool: pin.SE3
    measure: str = "position"
    extension: Extension | None = None
    effect: np.ndarray = field(default_factory=lambda: np.zeros(0))
    instrument_T_base: pin.SE3 | None = None

    def reached(self, q: np.ndarray) -> np.ndarray:
        """Joint values (N, n) the robot reaches for commands ``q`` (N, n) [rad or m]."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        return q if self.extension is None else q + self.extension.joint_error(q, self.effect)

    def tool_pose(self, q: np.ndarray) -> pin.SE3:
        """``base_T_tool`` for one command ``q`` (n,) [rad or m], the extension included."""
        return self.robot.frame_placement(self.reached(q)[0]) * self.tool

    @cached_property
    def tool_frame(self) -> tuple[pin.Model, int]:
        """A copy of the robot's Pinocchio model with a frame ``pincal_tool``, and that frame's id."""
        model = pin.Model(self.robot.model)
        tip = model.frames[self.robot.tip_frame_id]
        placement = tip.placement * self.tool
        frame = pin.Frame("pincal_tool", tip.parentJoint, self.robot.tip_frame_id, placement, pin.OP_FRAME)
        return model, model.addFrame(frame)


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
        chain = {"tip": side["tip"], "joints": side.get("joints")}
        if is_yaml(urdf):
            robot = load_robot(nominal or "", **chain, **{**robot_options, "kinematics": urdf})
        else:
            robot = load_robot(urdf, **chain)
        reg, spec = side.get("instrument_T_base"), side.get("extension")
        ext, effect = None, np.zeros(0)
        if spec is not None:
            load = spec.get("payload")
            com = [float(c) for c in load["com_m"]] if load is not None else []
            payload = None if load is None else Payload(float(load["mass_kg"]), (com[0], com[1], com[2]))
            ext = Extension(robot, spec["effect"], spec["joint"], int(spec.get("harmonic", 1)), payload)
            effect = np.array([float(spec["parameters"][n]["value"]) for n in ext.names])
            if not np.all(np.isfinite([*effect, *com, payload.mass if payload else 0.0])):
                raise ValueError("extension: a parameter that is not a finite number")
        tool = rigid_transform(side["tip_T_tool"]["matrix"], "tip_T_tool")
        registration = None if reg is None else rigid_transform(reg["matrix"], "instrument_T_base")
        return CalibratedRobot(robot, tool, str(side.get("measure", "position")), ext, effect, registration)
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:  # issue 33: any shape
        raise DataError(f"{path} is not a pincal calibration sidecar: bad or missing {exc}") from None
    except DataError as exc:  # issue 33: a payload the sidecar gives is checked as --payload is
        raise DataError(f"{path}: {exc}") from None
