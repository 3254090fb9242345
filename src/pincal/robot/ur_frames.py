"""A UR kinematics YAML read (:func:`read_ur_kinematics`) and put on a UR URDF: ``ur_description``'s
joint frames (the format: :mod:`pincal.export.ur_yaml`, which writes a calibration as such a YAML).

A URDF in ``ur_description``'s frames (its own xacro's output: ``base_link_inertia`` before the
first joint, every UR joint turning about its z) takes the YAML's six origins as they are. An
older URDF (ROS 1's ``ur_description``, example-robot-data's, whose joints turn about y) is
rewritten to those frames first: ``base_link_inertia`` inserted, turned by π about z from the
first joint's parent (which is ``ur_description``'s ``base_link``), and each UR link's inertia,
visuals and child joints re-expressed in its new frame where they were at zero joint angles;
tool0, and whatever hangs on the flange, stays on wrist_3_link as ``ur_description`` has it.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
from lxml import etree

from pincal.errors import DataError, RobotError
from pincal.inputs import read_bytes

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

# The YAML read (its writing, from a calibration, is pincal.export.ur_yaml's: that layer sits above the fit)
#: The YAML's segments, base to tip: the links the joints of :data:`JOINTS` move.
SEGMENTS = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
KEYS = ("x", "y", "z", "roll", "pitch", "yaw")
#: The unit tags xacro's YAML loader knows (``!degrees 90``), as factors to radians or metres.
_UNITS = {"!radians": 1.0, "!degrees": math.pi / 180, "!meters": 1.0, "!millimeters": 1e-3}
_MAX_BYTES = 1_000_000
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
