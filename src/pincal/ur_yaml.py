"""UR kinematics YAML in and out: the per-robot calibration file ``ur_description`` and the UR
driver read (``default_kinematics.yaml``'s format, the driver's ``kinematics_config``).

The file holds, for each of ``shoulder, upper_arm, forearm, wrist_1, wrist_2, wrist_3``, the
origin ``x, y, z`` [m] and ``roll, pitch, yaw`` [rad] of the joint that moves that link
(``shoulder_pan_joint`` ... ``wrist_3_joint``), plus the controller's calibration ``hash``.
``ur_description`` (``urdf/ur_macro.xacro``) builds the chain from it exactly so:

    base_link -[fixed, rpy 0 0 π]-> base_link_inertia -[shoulder origin, axis z]-> shoulder_link
    -[upper_arm]-> upper_arm_link -[forearm]-> forearm_link -[wrist_1]-> ... -> wrist_3_link
    -[fixed, rpy 0 -π/2 -π/2]-> flange -[fixed, rpy π/2 0 π/2]-> tool0

every joint origin's rpy meaning R = Rz(yaw) Ry(pitch) Rx(roll), as everywhere in URDF. The
two fixed tool joints compose to the identity: tool0 is wrist_3_link's frame.

:func:`pincal.ur_frames.apply_ur_kinematics` puts a YAML on a UR URDF of the same type (the
nominal model ``load_robot(..., kinematics=FILE)`` calibrates); :func:`calibrated_ur_kinematics`
reads the six origins back from a calibration: the corrected URDF's joint origins
(:func:`pincal.urdf_writer.corrected_origins`), which the YAML holds as they are.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from lxml import etree

from .errors import DataError, RobotError
from .files import atomic_write
from .inputs import read_bytes
from .json_text import json_text
from .robots import Robot
from .ur_frames import BASE_INERTIA, JOINTS, PARSER, URChain

if TYPE_CHECKING:
    from .calibration import Calibration

#: The YAML's segments, base to tip: the links the joints of :data:`JOINTS` move.
SEGMENTS = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
KEYS = ("x", "y", "z", "roll", "pitch", "yaw")
#: The unit tags xacro's YAML loader knows (``!degrees 90``), as factors to radians or metres.
_UNITS = {"!radians": 1.0, "!degrees": math.pi / 180, "!meters": 1.0, "!millimeters": 1e-3}
_MAX_BYTES = 1_000_000
_HASH_PARAM = re.compile(r"<param\s+name\s*=\s*[\"']kinematics/hash[\"']\s*>([^<]*)</param>")
#: The bundled URs' nominal DH lengths d1, a2, a3, d4, d5, d6 [m], from which ``ur_description``'s
#: ``config/<type>/default_kinematics.yaml`` are made (the tests check them against the URDFs).
DEFAULT_DH = {
    "ur3": (0.1519, -0.24365, -0.21325, 0.11235, 0.08535, 0.0819),
    "ur5": (0.089159, -0.425, -0.39225, 0.10915, 0.09465, 0.0823),
    "ur10": (0.1273, -0.612, -0.5723, 0.163941, 0.1157, 0.0922),
}


@dataclass(frozen=True, eq=False)
class URKinematics:
    """The six joint origins of a UR kinematics YAML.

    Attributes:
        origins: ``shoulder_pan_joint`` ... ``wrist_3_joint`` origins, each in its parent link's frame.
        calibration_hash: the ``hash`` entry (the controller's calibration checksum), or None.
    """

    origins: tuple[pin.SE3, ...]
    calibration_hash: str | None = None

    def chain(self, q: np.ndarray) -> pin.SE3:
        """``base_link_T_tool0`` at joint angles ``q`` (6,) [rad], as ``ur_description`` builds it."""
        out = BASE_INERTIA
        for origin, angle in zip(self.origins, np.asarray(q, dtype=float).reshape(6)):
            out = out * origin * pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, float(angle)), np.zeros(3))
        return out

    def to_yaml(self, header: str = "") -> str:
        """The YAML text, numbers written shortest-exact (``repr``), ``hash`` under ``kinematics``."""
        lines = [f"# {line}".rstrip() for line in header.splitlines()] + ["kinematics:"]
        for segment, origin in zip(SEGMENTS, self.origins):
            values = [*origin.translation, *pin.rpy.matrixToRpy(origin.rotation)]
            lines.append(f"  {segment}:")
            lines += [f"    {key}: {_number(v)}" for key, v in zip(KEYS, values)]
        lines.append(f"  hash: {json.dumps(self.calibration_hash or self.default_hash())}")
        return "\n".join(lines) + "\n"

    def default_hash(self) -> str:
        """A hash made from the values, for a file whose source had none."""
        text = " ".join(repr(float(v)) for o in self.origins for v in o.homogeneous[:3].ravel())
        return "calib_pincal_" + hashlib.sha256(text.encode()).hexdigest()[:16]


def default_ur_kinematics(name: str) -> URKinematics:
    """``ur_description``'s default kinematics of a bundled UR (``ur3``, ``ur5`` or ``ur10``).

    Raises:
        RobotError: another name.
    """
    if name not in DEFAULT_DH:
        raise RobotError(f"no default UR kinematics for {name!r}: give one of {', '.join(DEFAULT_DH)}")
    d1, a2, a3, d4, d5, d6 = DEFAULT_DH[name]
    entries = [(0, 0, d1, 0, 0, 0), (0, 0, 0, math.pi / 2, 0, 0), (a2, 0, 0, 0, 0, 0), (a3, 0, d4, 0, 0, 0),
               (0, -d5, 0, math.pi / 2, 0, 0), (0, d6, 0, math.pi / 2, math.pi, math.pi)]  # fmt: skip
    return URKinematics(tuple(pin.SE3(pin.rpy.rpyToMatrix(*e[3:]), np.array(e[:3], float)) for e in entries))


def _number(value: float) -> str:
    """``repr`` as YAML 1.1 reads it back as that float (PyYAML needs a dot before an exponent)."""
    text = repr(float(value) + 0.0)
    return text.replace("e", ".0e", 1) if "e" in text and "." not in text else text


def _loader() -> Any:
    """PyYAML's safe loader, plus xacro's unit tags (``!degrees 90``)."""
    import yaml

    class Loader(yaml.SafeLoader):
        pass

    for tag, factor in _UNITS.items():
        Loader.add_constructor(tag, lambda loader, node, k=factor: float(loader.construct_scalar(node)) * k)
    return Loader


def read_ur_kinematics(path: str | Path) -> URKinematics:
    """Read a UR kinematics YAML.

    Raises:
        DataError: unreadable file, not YAML, or a segment or number missing or not finite.
    """
    import yaml

    path = Path(path)
    try:
        text = read_bytes(path, "kinematics YAML", _MAX_BYTES).decode("utf-8")  # bounded (issue 33)
        doc = yaml.load(text, Loader=_loader())  # a SafeLoader
    except RecursionError:  # brackets nested deeper than Python's stack
        raise DataError(f"cannot read the kinematics YAML {path}: nested too deeply") from None
    except (OSError, UnicodeDecodeError, yaml.YAMLError, ValueError) as exc:
        raise DataError(f"cannot read the kinematics YAML {path}: {' '.join(str(exc).split())}") from None
    section = doc.get("kinematics") if isinstance(doc, dict) else None
    if not isinstance(section, dict):
        raise DataError(
            f"{path} has no 'kinematics:' section: give a UR kinematics YAML (ur_description's format)"
        )
    origins = []
    for segment in SEGMENTS:
        entry = section.get(segment)
        try:
            values = [float(entry[key]) for key in KEYS] if isinstance(entry, dict) else []
        except (TypeError, KeyError, ValueError):
            values = []
        if not values:
            raise DataError(f"{path}: kinematics.{segment} needs numbers {', '.join(KEYS)}")
        if not all(math.isfinite(v) and abs(v) < 100 for v in values):
            raise DataError(f"{path}: kinematics.{segment} has a value that is not finite or is over 100")
        origins.append(pin.SE3(pin.rpy.rpyToMatrix(*values[3:]), np.array(values[:3])))
    found = section.get("hash", doc.get("hash"))
    return URKinematics(tuple(origins), None if found is None else str(found))


def robot_ur_chain(robot: Robot) -> URChain:
    """The UR joints of a loaded robot's URDF, checked to be ``ur_description``'s frames and the
    robot's whole chain.

    Raises:
        DataError: another URDF, UR joints locked, or joint frames other than ``ur_description``'s.
    """
    text = robot.urdf_text or Path(robot.urdf_path).read_text(encoding="utf-8")
    chain = URChain.find(etree.fromstring(text.encode("utf-8"), PARSER))
    if robot.joint_names != tuple(chain.prefix + j for j in JOINTS):
        raise DataError(
            f"a UR kinematics YAML holds the six UR joints: the chain has {', '.join(robot.joint_names)}"
        )
    if not chain.in_ur_frames():
        raise DataError(
            "a UR kinematics YAML holds ur_description's joint frames, which this URDF does not use: "
            "give the robot's kinematics YAML with --kinematics (for a nominal robot, ur_description's "
            "config/<type>/default_kinematics.yaml)"
        )
    return chain


def calibrated_ur_kinematics(cal: Calibration, calibration_hash: str | None = None) -> URKinematics:
    """The calibration as a UR kinematics YAML's six origins (the corrected URDF's joint origins).

    Args:
        cal: a calibration of a UR robot in ``ur_description``'s frames (:func:`robot_ur_chain`).
        calibration_hash: the ``hash`` to write (the source YAML's); None takes the URDF's
            ``kinematics/hash`` parameter (``ur_description``'s ros2_control tag), else makes one.
    """
    from .urdf_writer import corrected_origins

    chain = robot_ur_chain(cal.robot)
    origins = corrected_origins(cal)
    if calibration_hash is None:  # ur_description writes it into its ros2_control tag
        found = _HASH_PARAM.search(cal.robot.urdf_text)
        calibration_hash = found.group(1).strip() if found else None
    return URKinematics(tuple(origins[chain.prefix + j] for j in JOINTS), calibration_hash)


def is_yaml(path: str | Path | None) -> bool:
    """True when ``path`` names a UR kinematics YAML (``.yaml`` or ``.yml``)."""
    return path is not None and Path(path).suffix.lower() in (".yaml", ".yml")


def write_ur_kinematics(
    cal: Calibration, path: str | Path, calibration_hash: str | None = None
) -> tuple[Path, Path]:
    """Write the calibration as a UR kinematics YAML and its sidecar ``<stem>.calibration.json``
    (registration and tool), atomically.

    Raises:
        DataError: not a UR robot in ``ur_description``'s frames, or the output folder is missing.
    """
    from .urdf_writer import check_output, sidecar, sidecar_path

    path = Path(path)
    check_output(path, cal.robot)
    kinematics = calibrated_ur_kinematics(cal, calibration_hash)
    header = (
        f"UR kinematics calibrated by pincal ({cal.model.kind} model, {cal.measurement.kind} data) for "
        f"{cal.robot.name}.\nGive it to ur_description as kinematics_params (the UR driver's "
        "kinematics_config).\nThe hash is the source file's: the controller calibration this one refines."
    )
    side = sidecar_path(path)
    atomic_write(path, kinematics.to_yaml(header))
    extra = sidecar(cal, path.name)
    extra.update(urdf=None, ur_kinematics=path.name)
    atomic_write(side, json_text(extra))
    return path, side
