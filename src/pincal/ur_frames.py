"""A UR kinematics YAML put on a UR URDF: ``ur_description``'s joint frames (see :mod:`pincal.ur_yaml`).

A URDF in ``ur_description``'s frames (its own xacro's output: ``base_link_inertia`` before the
first joint, every UR joint turning about its z) takes the YAML's six origins as they are. An
older URDF (ROS 1's ``ur_description``, example-robot-data's, whose joints turn about y) is
rewritten to those frames first: ``base_link_inertia`` inserted, turned by π about z from the
first joint's parent (which is ``ur_description``'s ``base_link``), and each UR link's inertia,
visuals and child joints re-expressed in its new frame where they were at zero joint angles;
tool0, and whatever hangs on the flange, stays on wrist_3_link as ``ur_description`` has it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin
from lxml import etree

from .errors import RobotError

if TYPE_CHECKING:
    from .ur_yaml import URKinematics

#: The UR joints, base to tip (a URDF's may carry a prefix, as ``tf_prefix`` gives).
JOINTS = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)
#: ``base_link`` -> ``base_link_inertia`` in ``ur_description``.
BASE_INERTIA = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, math.pi), np.zeros(3))
PARSER = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, remove_comments=False)
_AXIS_TOLERANCE = 0.05  # [rad] a YAML's axis against the URDF's: a calibration is mrad off
_TOOL_TOLERANCE = 0.02  # [m] tool0 at zero angles, YAML against URDF: more is another type


def _origin(element: Any) -> pin.SE3:
    """SE3 of a URDF ``<origin>`` (missing: identity)."""
    if element is None:
        return pin.SE3.Identity()
    xyz = [float(v) for v in (element.get("xyz") or "0 0 0").split()]
    rpy = [float(v) for v in (element.get("rpy") or "0 0 0").split()]
    return pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.array(xyz))


def _set_origin(element: Any, placement: pin.SE3) -> None:
    origin = element.find("origin")
    origin = etree.SubElement(element, "origin") if origin is None else origin
    origin.set("xyz", " ".join(repr(float(v) + 0.0) for v in placement.translation))
    origin.set("rpy", " ".join(repr(float(v) + 0.0) for v in pin.rpy.matrixToRpy(placement.rotation)))


@dataclass(frozen=True, eq=False)
class URChain:
    """The six UR joints of a URDF tree and what they connect."""

    root: Any
    joints: tuple[Any, ...]
    links: tuple[str, ...]  # the first joint's parent, then each joint's child
    prefix: str

    @classmethod
    def find(cls, root: Any) -> URChain:
        """The chain in ``root`` (joint names may carry a prefix, as ``tf_prefix`` gives)."""
        named = {j.get("name", ""): j for j in root.findall("joint")}
        first = [n for n in named if n.endswith(JOINTS[0])]
        if len(first) != 1:
            raise RobotError(
                "a UR kinematics YAML needs a UR robot: the URDF has no single shoulder_pan_joint"
            )
        prefix = first[0][: -len(JOINTS[0])]
        missing = [prefix + j for j in JOINTS if prefix + j not in named]
        if missing:
            raise RobotError(f"a UR kinematics YAML needs a UR robot: the URDF has no joint {missing[0]}")
        joints = tuple(named[prefix + j] for j in JOINTS)
        links = [joints[0].find("parent").get("link")] + [j.find("child").get("link") for j in joints]
        for joint, parent in zip(joints[1:], links[1:-1]):
            if joint.find("parent").get("link") != parent:
                raise RobotError(
                    f"{joint.get('name')} is not on {parent}: the UR joints must follow each other"
                )
        return cls(root, joints, tuple(links), prefix)

    def axis(self, k: int) -> np.ndarray:
        element = self.joints[k].find("axis")
        axis = np.array([float(v) for v in (element.get("xyz") if element is not None else "1 0 0").split()])
        return axis / np.linalg.norm(axis)

    def in_ur_frames(self) -> bool:
        """True for ``ur_description``'s own frames: base_link_inertia first, every axis z."""
        first = self.links[0] == self.prefix + "base_link_inertia"
        return first and all(np.allclose(self.axis(k), (0, 0, 1), atol=1e-12) for k in range(6))

    def placements(self) -> dict[str, pin.SE3]:
        """Every link's placement in the root link at zero joint values."""
        parent = {j.find("child").get("link"): j for j in self.root.findall("joint")}
        out: dict[str, pin.SE3] = {}

        def place(link: str) -> pin.SE3:
            if link not in out:
                joint = parent.get(link)
                out[link] = (
                    pin.SE3.Identity()
                    if joint is None
                    else (place(joint.find("parent").get("link")) * _origin(joint.find("origin")))
                )
            return out[link]

        for link in [*parent, *(e.get("name") for e in self.root.findall("link"))]:
            place(link)
        return out


def apply_ur_kinematics(urdf_text: str, kinematics: URKinematics) -> str:
    """The URDF with the YAML's six joint origins, as ``ur_description`` would build it.

    Raises:
        RobotError: not a UR URDF, or a YAML of another type (axes or tool0 far apart).
    """
    try:
        root = etree.fromstring(urdf_text.encode("utf-8"), PARSER)
        return _apply(root, URChain.find(root), kinematics)
    except (etree.XMLSyntaxError, AttributeError, TypeError, ValueError, RecursionError) as exc:
        raise RobotError(f"cannot put the kinematics YAML on this URDF: {exc}: fix the URDF") from None


def _apply(root: Any, chain: URChain, kinematics: URKinematics) -> str:
    at_zero = chain.placements()
    ur_frames = [at_zero[chain.links[0]] * (pin.SE3.Identity() if chain.in_ur_frames() else BASE_INERTIA)]
    for origin in kinematics.origins:
        ur_frames.append(ur_frames[-1] * origin)
    tool = chain.prefix + "tool0"
    gap = np.linalg.norm(ur_frames[6].translation - at_zero.get(tool, at_zero[chain.links[6]]).translation)
    if gap > _TOOL_TOLERANCE:
        raise RobotError(
            f"the kinematics YAML puts tool0 {gap * 1000:.0f} mm away from the URDF's at zero angles: "
            "give the URDF of the same UR type as the YAML"
        )
    if not chain.in_ur_frames():
        _to_ur_frames(chain, ur_frames, at_zero)
    for joint, origin in zip(chain.joints, kinematics.origins):
        _set_origin(joint, origin)
    return etree.tostring(root, encoding="unicode")


def _to_ur_frames(chain: URChain, ur_frames: list[pin.SE3], at_zero: dict[str, pin.SE3]) -> None:
    """Rewrite an older UR URDF to ``ur_description``'s link frames: each link's contents and
    child joints re-expressed in its new frame, base_link_inertia inserted."""
    tool = chain.prefix + "tool0"
    for k in range(1, 7):
        turn = ur_frames[k].rotation[:, 2] @ (at_zero[chain.links[k]].rotation @ chain.axis(k - 1))
        if turn < math.cos(_AXIS_TOLERANCE):
            raise RobotError(
                f"joint {chain.joints[k - 1].get('name')} turns about another axis in the kinematics YAML "
                "than in the URDF: give the URDF of the same UR type as the YAML"
            )
    links = {e.get("name"): e for e in chain.root.findall("link")}
    for k in range(1, 7):
        link = chain.links[k]
        move = ur_frames[k].actInv(at_zero[link])  # the old link frame in the new one
        if k == 6 and tool in at_zero:  # tool0 stays wrist_3_link's frame, as ur_description has it
            move = at_zero[link].actInv(at_zero[tool]).inverse()
        for element in links.get(link, ()):
            if element.tag in ("inertial", "visual", "collision"):
                _set_origin(element, move * _origin(element.find("origin")))
        leaving = chain.joints[k] if k < 6 else None  # the next UR joint takes the YAML's origin
        for joint in chain.root.findall("joint"):
            if joint.find("parent").get("link") == link and joint is not leaving:
                _set_origin(joint, move * _origin(joint.find("origin")))
    for joint in chain.joints:
        axis = joint.find("axis")
        (etree.SubElement(joint, "axis") if axis is None else axis).set("xyz", "0 0 1")
    _insert_base_inertia(chain)


def _insert_base_inertia(chain: URChain) -> None:
    """``base_link_inertia`` between the first joint and its parent, turned by π about z."""
    name = chain.prefix + "base_link_inertia"
    first = chain.joints[0]
    index = list(chain.root).index(first)
    link = etree.Element("link", name=name)
    joint = etree.Element("joint", name=f"{chain.links[0]}-base_link_inertia", type="fixed")
    etree.SubElement(joint, "parent", link=chain.links[0])
    etree.SubElement(joint, "child", link=name)
    _set_origin(joint, BASE_INERTIA)
    chain.root.insert(index, joint)
    chain.root.insert(index, link)
    first.find("parent").set("link", name)
