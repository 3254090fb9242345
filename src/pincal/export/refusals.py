"""Why a row of a program was not compensated: out of reach, at a joint limit, near a
singularity, or held still where lost motion forbids the reversal it needs."""

from __future__ import annotations

import numpy as np

from pincal.data.directions import STILL
from pincal.export.calibrated_robot import CalibratedRobot
from pincal.export.inverse_kinematics import Found
from pincal.robot.robots import Robot


def in_play(cal: CalibratedRobot, rows: np.ndarray) -> str:
    """Why a refused row of commands (the last of ``rows``) may need a move lost motion forbids: the
    joints with lost motion the program holds still (on their flank: no reversal under ``2|v|``)."""
    if len(rows) < 2:  # the first row: it comes from no row
        return ""
    names, slide, moved = cal.robot.joint_names, cal.robot.prismatic, np.abs(rows[1] - rows[0])
    lost = {names.index(j): (j, v) for j, v in cal.lost_motion().items()}
    held = [
        f"{j} ({2e3 * abs(v):.3f} {'mm' if slide[k] else 'mrad'})"
        for k, (j, v) in lost.items()
        if moved[k] <= STILL
    ]
    if not held:
        return ""
    return (
        f"; the program holds {', '.join(held)} still: a reversal smaller than its lost motion (in "
        "brackets) cannot be made: move the joint in the program"
    )


def unreached(robot: Robot, found: Found, task: str, limits: tuple[float, float] | None) -> tuple[str, str]:
    """Status and message of a row not compensated.

    A row of commands is ``singular`` when its correction needs more than ``max_change`` (found,
    or foreseen by the first Gauss-Newton step) or its Jacobian's σmin/σmax is under
    ``singular_rcond``; else ``unreachable`` (beyond the calibrated arm's reach or a joint limit).

    Args:
        robot: the calibrated chain.
        found: the closest search.
        task: ``pose`` or ``position``.
        limits: for a row of commands, ``(singular_rcond, max_change)``; None for a Cartesian row.
    """
    change = float(np.abs(found.q - found.start).max())
    if found.converged:
        return "singular", f"near a singularity: needs a joint change of {change:.3f} rad"
    off = f"{found.position * 1e3:.3f} mm" + (f", {found.rotation * 1e3:.3f} mrad" if task == "pose" else "")
    closest = f"the closest pose found is {off} off"
    at_limit = beyond(robot, found.q, strict=False)
    if limits is not None and not at_limit:
        singular_rcond, max_change = limits
        near = f"near a singularity (σmin/σmax {found.ratio:.1e})"
        if found.first_step > max_change:
            needs = f"the correction needs a joint change of about {found.first_step:.2f} rad"
            return "singular", f"{near}: {needs}; {closest}"
        if found.ratio < singular_rcond:
            return "singular", f"{near}: {closest}"
    why = f"; {at_limit} at a joint limit" if at_limit else ""
    return "unreachable", f"out of reach: {closest}{why}"


def beyond(robot: Robot, q: np.ndarray, strict: bool) -> str:
    """Joints beyond their limits (``strict``) or at them, comma separated."""
    out = [
        j
        for j, v, a, b in zip(robot.joint_names, q, robot.lower, robot.upper)
        if (v < a or v > b) or (not strict and (v <= a or v >= b))
    ]
    return ", ".join(out)
