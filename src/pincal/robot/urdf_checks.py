"""The structure of a URDF, checked before any URDF parser sees it.

urdfdom and Pinocchio's URDF parser trust the file: a link that is its own parent or a closed
loop of joints crashes the process (SIGSEGV), a joint axis ``0 0 0`` gives a model that is no
rotation at all, and a chain of a thousand joints exhausts the memory. :func:`check_urdf_structure`
reads the text with :mod:`xml.etree` (whose DOCTYPE :func:`pincal.robot.descriptions.read_urdf_text` has
already cleared) and refuses, with one line naming the joint or link:

- a root element that is not ``<robot>``, a link or joint without a name, or a name used twice;
- a joint whose parent or child link is missing or undefined, or is both its parent and child;
- a link that is the child of two joints, a closed loop, or more than one root link;
- more than :data:`MAX_JOINTS` movable joints, :data:`MAX_ALL_JOINTS` in all (fixed ones count
  apart: marker frames), or more than :data:`MAX_CHAIN` movable joints in a row;
- an origin, axis or limit that is not three (or one) finite numbers, an axis of zero length,
  limits with ``lower > upper``, or an origin or prismatic limit :data:`MAX_LENGTH` or more
  from zero (the kinematics overflow).

A nonzero axis that is not of unit length is accepted: Pinocchio, KDL and MoveIt all read it as
its direction (they normalise it), and so does every pincal model.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections import deque
from pathlib import Path

from pincal.errors import RobotError

#: Movable joints a URDF may hold (a humanoid with hands has about a hundred).
MAX_JOINTS = 1000
#: Joints a URDF may hold, fixed ones included (sensor and marker frames are fixed links).
MAX_ALL_JOINTS = 20_000
#: Movable joints on one path from the root (a serial arm has 5 to 10).
MAX_CHAIN = 100
#: Axis length under which an axis counts as zero.
MIN_AXIS = 1e-6
#: Length [m] an origin coordinate or a prismatic limit stays below (no arm is a thousand km).
MAX_LENGTH = 1e6
_MOVING = ("revolute", "continuous", "prismatic")


def check_urdf_structure(text: str, path: str | Path) -> None:
    """Refuse a URDF that is not a tree of well-formed joints (see the module docstring).

    Args:
        text: the URDF's text.
        path: the file, for the messages.

    Raises:
        RobotError: what is wrong, with the joint or link it is about.
    """
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise RobotError(f"URDF {path} is not well-formed XML ({exc}): fix the URDF") from None
    ns = _namespace(root.tag)
    if root.tag != f"{ns}robot":
        raise RobotError(f"URDF {path}: the root element is <{_local(root.tag)}>, not <robot>: is it a URDF?")
    links = listed_names(root.findall(f"{ns}link"), "link", path)
    known = set(links)
    joints = root.findall(f"{ns}joint")
    if not links:
        raise RobotError(f"URDF {path} has no <link>: a robot needs links joined by joints")
    moving = sum(joint.get("type", "") in _MOVING for joint in joints)
    if moving > MAX_JOINTS or len(joints) > MAX_ALL_JOINTS or (len(joints) > MAX_JOINTS and not moving):
        raise RobotError(  # fixed joints (marker frames) count apart from movable ones (issue 33)
            f"URDF {path} has {len(joints)} joints, {moving} of them movable: more than {MAX_JOINTS} "
            f"movable, {MAX_ALL_JOINTS} in all, or {MAX_JOINTS} and none movable: is it a robot arm's URDF?"
        )
    listed_names(joints, "joint", path)
    parent_of: dict[str, tuple[str, str, bool]] = {}  # child link -> (joint, parent link, movable)
    for joint in joints:
        name, kind = joint.get("name", ""), joint.get("type", "")
        parent, child = _link_of(joint, "parent", ns, path), _link_of(joint, "child", ns, path)
        for link in (parent, child):
            if link not in known:
                raise RobotError(f"URDF {path}: joint {name!r} names link {link!r}, which no <link> defines")
        if parent == child:
            raise RobotError(
                f"URDF {path}: joint {name!r} has link {child!r} as both parent and child: "
                "a link cannot be its own parent"
            )
        if child in parent_of:
            raise RobotError(
                f"URDF {path}: link {child!r} is the child of two joints ({parent_of[child][0]!r} and "
                f"{name!r}): a URDF is a tree, closed loops are not supported: remove one of them"
            )
        parent_of[child] = (name, parent, kind in _MOVING)
        _check_joint(joint, name, kind, ns, path)
    _check_tree(links, parent_of, path)


def without_default_namespace(text: str) -> str:
    """The URDF ``text`` with its elements out of a default XML namespace (``<robot xmlns="...">``),
    for the readers and writers that look elements up by their plain names (urdfdom ignores the
    namespace: the robot is the same). A text without one, or not well-formed, is returned as it is.
    """
    head = text[: text.find(">", text.find("<robot")) + 1] if "<robot" in text else ""
    if "xmlns" not in head:
        return text
    from lxml import etree  # here: the other texts need no second parse

    parser = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False)
    try:
        root = etree.fromstring(text.encode("utf-8"), parser)
    except etree.XMLSyntaxError:
        return text  # the structure check says what is wrong, naming the file
    namespace = root.nsmap.get(None)
    if namespace is None:
        return text
    for element in root.iter():
        if isinstance(element.tag, str) and element.tag.startswith(f"{{{namespace}}}"):
            element.tag = element.tag[len(namespace) + 2 :]
    etree.cleanup_namespaces(root)
    return str(etree.tostring(root.getroottree(), encoding="unicode"))


class _Prolog(Exception):
    """The parse reached the root element: the DOCTYPE, if any, is behind it."""


def declares_dtd(text: str) -> bool:
    """Whether the DOCTYPE names an external DTD (``SYSTEM``, ``PUBLIC``) or has an internal subset
    (entity declarations), as an XML parser reads it: the words elsewhere (a link named
    ``PUBLIC-display``, ``SYSTEM`` in a comment) do not count (issue 33). The parse stops at the
    root element; a text expat cannot read is left to the URDF checks' message."""
    import xml.parsers.expat

    found: list[bool] = []

    def doctype(_name: str, system: str | None, public: str | None, subset: int) -> None:
        found.append(bool(system or public or subset))
        raise _Prolog  # nothing past the DOCTYPE's opening is parsed (no entity is read)

    def start(*_: object) -> None:
        raise _Prolog

    parser = xml.parsers.expat.ParserCreate()
    parser.StartDoctypeDeclHandler, parser.StartElementHandler = doctype, start
    try:
        parser.Parse(text.encode("utf-8"), True)
    except _Prolog:
        pass
    except xml.parsers.expat.ExpatError:
        return "<!ENTITY" in text.upper()  # not XML: the structure check says so, unless it may expand
    return any(found)


def _check_tree(links: list[str], parent_of: dict[str, tuple[str, str, bool]], path: str | Path) -> None:
    """One root, every link reached from it, and no path of more than :data:`MAX_CHAIN` movable joints."""
    roots = [link for link in links if link not in parent_of]
    if not roots:
        raise RobotError(
            f"URDF {path} has no root link: every link is the child of a joint, the joints form a "
            "closed loop: remove the joint that closes it"
        )
    if len(roots) > 1:
        raise RobotError(
            f"URDF {path} has {len(roots)} root links ({', '.join(roots[:5])}): every link but the "
            "base must be the child of a joint"
        )
    children: dict[str, list[tuple[str, bool]]] = {}
    for child, (_, parent, movable) in parent_of.items():
        children.setdefault(parent, []).append((child, movable))
    depth = {roots[0]: 0}
    todo = deque(roots)
    while todo:
        link = todo.popleft()
        for child, movable in children.get(link, []):
            depth[child] = depth[link] + int(movable)
            todo.append(child)
    cut_off = [link for link in links if link not in depth]
    if cut_off:
        raise RobotError(
            f"URDF {path}: link(s) {', '.join(cut_off[:5])} form a closed loop of joints, not "
            f"connected to the root {roots[0]!r}: a URDF is a tree, remove the joint that closes it"
        )
    deepest = max(depth.values())
    if deepest > MAX_CHAIN:
        raise RobotError(
            f"URDF {path} has {deepest} movable joints in a row, more than {MAX_CHAIN}: "
            "is it a robot arm's URDF?"
        )


def _check_joint(joint: ET.Element, name: str, kind: str, ns: str, path: str | Path) -> None:
    """A joint's origin, axis and limits are finite numbers, the axis nonzero, lower ≤ upper."""
    origin = joint.find(f"{ns}origin")
    if origin is not None:
        _numbers(origin, "rpy", 3, f"joint {name!r} origin", path)
        xyz = _numbers(origin, "xyz", 3, f"joint {name!r} origin", path)
        _metres(xyz, f"joint {name!r} origin xyz", path)
    if kind not in _MOVING:
        return
    axis_element = joint.find(f"{ns}axis")
    if axis_element is not None:
        axis = _numbers(axis_element, "xyz", 3, f"joint {name!r} axis", path)
        if axis is not None and math.hypot(*axis) < MIN_AXIS:
            raise RobotError(
                f"URDF {path}: joint {name!r} has axis {axis_element.get('xyz')!r}, of length zero: "
                "give the direction it turns or slides about, for example '0 0 1'"
            )
    limit = joint.find(f"{ns}limit")
    if limit is None or kind == "continuous":
        return
    lower = _numbers(limit, "lower", 1, f"joint {name!r} limit", path)
    upper = _numbers(limit, "upper", 1, f"joint {name!r} limit", path)
    if kind == "prismatic":
        _metres([*(lower or []), *(upper or [])], f"prismatic joint {name!r} limit", path)
    if lower is not None and upper is not None and lower[0] > upper[0]:
        raise RobotError(
            f"URDF {path}: joint {name!r} has limit lower {lower[0]:g} above upper {upper[0]:g}: "
            "swap them (lower ≤ upper)"
        )


def _numbers(element: ET.Element, attr: str, count: int, what: str, path: str | Path) -> list[float] | None:
    """The attribute as ``count`` finite numbers (None when absent)."""
    text = element.get(attr)
    if text is None:
        return None
    try:
        values = [float(v) for v in text.split()]
    except ValueError:
        values = []
    if len(values) != count or not all(math.isfinite(v) for v in values):
        need = "a finite number" if count == 1 else f"{count} finite numbers"
        raise RobotError(f"URDF {path}: {what} {attr}={text!r} is not {need}: fix the URDF")
    return values


def _metres(values: list[float] | None, what: str, path: str | Path) -> None:
    """Refuse lengths [m] of :data:`MAX_LENGTH` or more."""
    if values and max(abs(v) for v in values) >= MAX_LENGTH:
        raise RobotError(
            f"URDF {path}: {what} holds {max(values, key=abs):g} m, {MAX_LENGTH:g} m or more: "
            "fix the URDF (its lengths are in metres)"
        )


def listed_names(elements: list[ET.Element], what: str, path: str | Path) -> list[str]:
    """The names of links or joints, refused when missing or repeated."""
    names: list[str] = []
    seen: set[str] = set()
    for element in elements:
        name = element.get("name")
        if not name:
            raise RobotError(f"URDF {path}: a <{what}> has no name: name every {what}")
        if name in seen:
            raise RobotError(f"URDF {path}: two <{what}> elements are named {name!r}: names must be unique")
        seen.add(name)
        names.append(name)
    return names


def _link_of(joint: ET.Element, role: str, ns: str, path: str | Path) -> str:
    """The link a joint's ``<parent>`` or ``<child>`` names."""
    element = joint.find(f"{ns}{role}")
    link = None if element is None else element.get("link")
    if not link:
        raise RobotError(
            f"URDF {path}: joint {joint.get('name')!r} has no <{role} link=...>: every joint joins a "
            "parent link to a child link"
        )
    return link


def _namespace(tag: str) -> str:
    return tag[: tag.index("}") + 1] if tag.startswith("{") else ""


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]
