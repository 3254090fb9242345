"""Which joints of a URDF pincal calibrates, and a one-line refusal for the others.

The chain is the path from the URDF's root link to the tip. On it:

- revolute, continuous and prismatic joints are calibrated (a continuous joint is a revolute one
  without limits);
- a floating or planar joint in front of the arm (a ``world`` link before the robot's base link,
  as simulators and mobile-base descriptions have it) is held at its neutral pose, the identity:
  the base stands still while measuring, and the instrument registration holds where it stands.
  Its ``<origin>`` is kept as written in the corrected URDF;
- a floating or planar joint between the arm's joints is refused: the URDF needs it fixed;
- a mimic joint (its value tied to another joint's) is refused: pincal's joints are independent,
  so the tip must come before it, or the URDF must drop the ``<mimic>`` when the data gives its
  value.

Everything off the chain (grippers and their mimic fingers, other branches) is locked at
neutral and left as written; a fixed joint from a ``world`` link is part of the base placement.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

import numpy as np
import pinocchio as pin
from lxml import etree

from pincal.errors import RobotError

_PARSER = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False)


def joint_path(model: pin.Model, joint: int) -> list[int]:
    """Ids of the joints from the base to ``joint`` (included), base first."""
    path: list[int] = []
    while joint > 0:
        path.append(joint)
        joint = model.parents[joint]
    return path[::-1]


def mimic_joints(text: str) -> dict[str, str]:
    """The URDF's mimic joints: name -> the joint it mimics (empty if the text does not parse)."""
    try:
        root = etree.fromstring(text.encode("utf-8"), _PARSER)
    except etree.XMLSyntaxError:  # pragma: no cover - Pinocchio parsed it already
        return {}
    out = {}
    for joint in root.iter("joint"):
        mimic = joint.find("mimic")
        if mimic is not None and joint.get("name"):
            out[str(joint.get("name"))] = str(mimic.get("joint"))
    return out


def _kind(model: pin.Model, j: int) -> str:
    """``floating``, ``planar`` or Pinocchio's short name of a joint that is not 1-DoF."""
    name = model.joints[j].shortname()
    return {"JointModelFreeFlyer": "floating", "JointModelPlanar": "planar"}.get(name, name)


def actuated_joints(
    full: pin.Model,
    tip_id: int,
    tip: str,
    joints: Iterable[str] | None,
    mimic: Mapping[str, str],
) -> list[int]:
    """Ids in ``full`` of the joints left actuated: the base-to-tip path, or ``joints`` on it.

    Floating and planar joints in front of the first 1-DoF joint are left out (locked at their
    neutral pose by the caller).

    Raises:
        RobotError: a joint unknown or off the path, a multi-DoF joint between the arm's joints, a
            mimic joint on the chain, or no joint left to calibrate.
    """
    path = joint_path(full, full.frames[tip_id].parentJoint)
    first = next((k for k, j in enumerate(path) if full.joints[j].nv == 1), len(path))
    keep = path[first:]
    if joints is not None:
        wanted = set(joints)
        unknown = wanted - set(full.names[1:])
        if unknown:
            raise RobotError(f"the URDF has no joint named {', '.join(sorted(unknown))}")
        off_path = wanted - {full.names[j] for j in keep}
        base = wanted & {full.names[j] for j in path[:first]}
        if base:
            raise RobotError(
                f"joint(s) {', '.join(sorted(base))} hold the robot's base at its neutral pose: "
                "leave them out of the joints (they take no data column)"
            )
        if off_path:
            raise RobotError(f"joint(s) {', '.join(sorted(off_path))} are not between the base and {tip!r}")
        keep = [j for j in keep if full.names[j] in wanted]
    for j in keep:
        name = full.names[j]
        if full.joints[j].nv != 1:
            raise RobotError(
                f"joint {name!r} is a {_kind(full, j)} joint between the arm's joints: pincal "
                "calibrates revolute, continuous and prismatic joints; make it fixed in the URDF, "
                f"or choose a tip before it with tip="
            )
        if name in mimic:
            raise RobotError(
                f"joint {name!r} mimics {mimic[name]!r} and lies between the base and {tip!r}: "
                "pincal calibrates independent joints only; choose a tip before it with tip=, or "
                "remove its <mimic> from the URDF if your data gives its value"
            )
    if not keep:
        raise RobotError(
            f"no revolute, continuous or prismatic joint between the base and {tip!r}: "
            "choose a tip on the arm with tip="
        )
    return keep


def tree_joints(
    full: pin.Model,
    tip_ids: list[int],
    tips: list[str],
    joints: Iterable[str] | None,
    mimic: Mapping[str, str],
) -> list[int]:
    """:func:`actuated_joints` of a tree: the joints between the base and any of the frames
    ``tip_ids`` (named ``tips``), in the model's order, or ``joints`` among them.

    Raises:
        RobotError: as :func:`actuated_joints` does for each frame, or a joint off every path.
    """
    wanted = None if joints is None else set(joints)
    keep: set[int] = set()
    for tip_id, tip in zip(tip_ids, tips):
        path = {full.names[j] for j in joint_path(full, full.frames[tip_id].parentJoint)}
        on = None if wanted is None else [j for j in wanted if j in path]
        if on is not None and not on:
            continue
        keep.update(actuated_joints(full, tip_id, tip, on, mimic))
    if wanted is not None:
        off = wanted - {full.names[j] for j in keep} - set(full.names[1:])
        if off:
            raise RobotError(f"the URDF has no joint named {', '.join(sorted(off))}")
        unused = wanted - {full.names[j] for j in keep}
        if unused:
            raise RobotError(
                f"joint(s) {', '.join(sorted(unused))} are not between the base and {', '.join(tips)}"
            )
    if not keep:
        raise RobotError(f"no revolute, continuous or prismatic joint between the base and {', '.join(tips)}")
    return sorted(keep)


def reference_configuration(full: pin.Model, locked: Mapping[str, float] | None) -> np.ndarray:
    """Pinocchio's neutral configuration of ``full`` with the ``locked`` joints at their values.

    Raises:
        RobotError: a joint unknown, or not a 1-DoF joint (a floating base stays at neutral).
    """
    q_ref = pin.neutral(full)
    for jname, value in (locked or {}).items():
        if not full.existJointName(jname):
            raise RobotError(f"cannot lock {jname!r}: the URDF has no such joint")
        j = full.getJointId(jname)
        joint = full.joints[j]
        if joint.nv != 1:
            kind = _kind(full, j)
            raise RobotError(f"cannot lock {jname!r} at a value: it is a {kind} joint, held at neutral")
        if joint.nq == 2:  # continuous: (cos, sin)
            q_ref[joint.idx_q : joint.idx_q + 2] = (math.cos(value), math.sin(value))
        else:
            q_ref[joint.idx_q] = value
    return q_ref


def joint_limits(model: pin.Model) -> tuple[tuple[bool, ...], np.ndarray, np.ndarray]:
    """Which joints of a reduced model are prismatic, and their lower and upper limits [rad or m]
    (±inf for a continuous joint, whose (cos, sin) has none)."""
    n = model.njoints - 1
    prismatic = tuple(model.joints[j].shortname().startswith("JointModelP") for j in range(1, model.njoints))
    lower, upper = np.full(n, -np.inf), np.full(n, np.inf)
    for k in range(n):
        joint = model.joints[k + 1]
        if joint.nq != 2:
            lower[k], upper[k] = model.lowerPositionLimit[joint.idx_q], model.upperPositionLimit[joint.idx_q]
    return prismatic, lower, upper
