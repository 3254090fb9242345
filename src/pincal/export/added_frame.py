"""A frame added to the corrected URDF at the calibrated tool (``--add-frame NAME``)."""

from __future__ import annotations

import re

import pinocchio as pin
from lxml import etree

from pincal.errors import DataError
from pincal.export.origins import write_origin


def check_frame_name(name: str | None) -> None:
    """Refuse an ``--add-frame`` name that is not a plain XML name."""
    if name is not None and not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_.-]*", name):
        raise DataError(f"add_frame={name!r}: use letters, digits, '_', '-' or '.', starting with a letter")


def add_tool_frame(root: etree._Element, tip: str, name: str, tool: pin.SE3, ball: bool) -> None:
    """A fixed joint ``<name>_joint`` and link ``name`` at ``tool`` on the tip link ``tip`` (at the
    tip itself when the tip link is a ball's calibrated centre, ``ball``)."""
    links = {link.get("name") for link in root.findall("link")}
    if tip not in links:
        raise DataError(f"add_frame= needs the tip {tip!r} to be a link of the URDF")
    if name in links or f"{name}_joint" in {j.get("name") for j in root.findall("joint")}:
        raise DataError(f"add_frame={name!r}: the URDF already has a link or joint of that name")
    indent = "\n  "
    if len(root):
        root[-1].tail = indent
    joint = etree.SubElement(root, "joint", name=f"{name}_joint", type="fixed")
    joint.text = indent + "  "
    etree.SubElement(joint, "parent", link=tip).tail = indent + "  "
    etree.SubElement(joint, "child", link=name).tail = indent + "  "
    origin = etree.SubElement(joint, "origin")
    origin.tail = indent
    write_origin(joint, pin.SE3.Identity() if ball else tool)
    joint.tail = indent
    etree.SubElement(root, "link", name=name).tail = "\n"
