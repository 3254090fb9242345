"""Masses lent by another URDF: gravity torques, and with them compliance and backlash, need the
links' ``<inertial>`` that some URDFs leave out."""

from __future__ import annotations

from pincal.errors import RobotError


def borrow_inertias(text: str, donor_text: str, donor: str) -> str:
    """``text`` with the ``<inertial>`` of ``donor_text``'s links of the same names added to its
    links that have none (a URDF without masses, as MUKCa's Panda and iiwa14: gravity torques,
    and with them compliance and backlash, need masses). Kinematics are left as they are.

    Args:
        text, donor_text: the URDF and the one that lends its masses.
        donor: the donor's name or path, for the error.

    Raises:
        RobotError: no link without masses has a namesake with masses in the donor.
    """
    import xml.etree.ElementTree as ET

    root, source = ET.fromstring(text), ET.fromstring(donor_text)
    lent = {link.get("name"): link.find("inertial") for link in source.iter("link")}
    moved = 0
    for link in root.iter("link"):
        found = lent.get(link.get("name"))
        if found is not None and link.find("inertial") is None:
            link.append(found)
            moved += 1
    if not moved:
        raise RobotError(
            f"inertias={donor}: none of its links with masses shares a name with a link of the "
            "URDF that has none: give the URDF of the same robot with its <inertial> elements"
        )
    return ET.tostring(root, encoding="unicode")
