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

:func:`pincal.robot.ur_frames.apply_ur_kinematics` puts a YAML on a UR URDF of the same type (the
nominal model ``load_robot(..., kinematics=FILE)`` calibrates); :func:`calibrated_ur_kinematics`
reads the six origins back from a calibration: the corrected URDF's joint origins
(:func:`pincal.export.urdf_writer.corrected_origins`), which the YAML holds as they are. The YAML's
reading (:class:`URKinematics`, :func:`read_ur_kinematics`) is :mod:`pincal.robot.ur_frames`', below the
robot loading that applies it; this module, above the fit, writes a calibration out.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING

from lxml import etree

from pincal.errors import DataError
from pincal.files import atomic_write
from pincal.json_text import json_text
from pincal.robot.robots import Robot
from pincal.robot.ur_frames import (
    JOINTS,
    PARSER,
    URChain,
    URKinematics,
)

if TYPE_CHECKING:
    from pincal.identify.calibration import Calibration

_HASH_PARAM = re.compile(r"<param\s+name\s*=\s*[\"']kinematics/hash[\"']\s*>([^<]*)</param>")


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
            "give the robot's kinematics YAML with kinematics= (for a nominal robot, ur_description's "
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
    from pincal.export.urdf_writer import corrected_origins

    chain = robot_ur_chain(cal.robot)
    origins = corrected_origins(cal.written)  # the URDF alone's geometry, as the URDF writes it
    if calibration_hash is None:  # ur_description writes it into its ros2_control tag
        found = _HASH_PARAM.search(cal.robot.urdf_text)
        calibration_hash = found.group(1).strip() if found else None
    return URKinematics(tuple(origins[chain.prefix + j] for j in JOINTS), calibration_hash)


def is_yaml(path: str | Path | None) -> bool:
    """True when ``path`` names a UR kinematics YAML (``.yaml`` or ``.yml``)."""
    return path is not None and Path(path).suffix.lower() in (".yaml", ".yml")


def write_ur_kinematics(
    cal: Calibration,
    path: str | Path,
    calibration_hash: str | None = None,
    *,
    accept_implausible: bool = False,
) -> tuple[Path, Path]:
    """Write the calibration as a UR kinematics YAML and its sidecar ``<stem>.calibration.json``
    (registration and tool), atomically.

    Args:
        cal: the calibration of a UR robot in ``ur_description``'s frames.
        path: the YAML to write; the sidecar goes beside it.
        calibration_hash: the controller calibration's hash this one refines (its source file's).
        accept_implausible: write a calibration its plausibility verdict refuses.

    Raises:
        DataError: not a UR robot in ``ur_description``'s frames, or the output folder is missing.
        ImplausibleError: the calibration cannot describe a real arm (``cal.plausibility``).
    """
    from pincal.export.urdf_writer import check_output, check_plausible, sidecar, sidecar_path

    check_plausible(cal, accept_implausible)
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
