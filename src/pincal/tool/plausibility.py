"""Plausibility of a TCP calibration (``pincal tcp``, :func:`pincal.tool.tcp.calibrate_tool`): the
poses touch one point, so their TCP points must nearly coincide; if they do not, angles given in
radians or quaternions in another order are tried."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace

import numpy as np
import pinocchio as pin

from pincal.errors import PincalError
from pincal.plausibility.readings import IMPROVEMENT
from pincal.plausibility.verdict import TOOL, Check, Verdict, robot_size
from pincal.robot.robots import Robot
from pincal.tool.tcp import ToolCalibration, euler_zyx, tcp_position
from pincal.units import MAX_TOOL_M

#: TCP points' scatter / the flange positions' spread (the poses touch one point).
TCP_FIT = 0.05
#: Rows turned less than this from the row before them carry nothing about the TCP [rad].
_SAME_TURN = np.deg2rad(0.5)


def judge_tool(
    tool: ToolCalibration,
    rotations: np.ndarray,
    positions: np.ndarray,
    orientation: str = "default",
    robot: Robot | None = None,
    scale: float = 1.0,
    unit: str = "m",
) -> Verdict:
    """Whether a TCP calibration (:func:`pincal.tool.tcp.calibrate_tool`) is plausible.

    Checks ``fit``: the TCP points ``R_i t + p_i`` of the TCP rows that turn the tool (rows
    turned less than half a degree from the row before them carry nothing about the TCP, as
    the moves of ``--orientation z|zx``) scatter by at most :data:`TCP_FIT` of the flange
    positions' spread, since they all touch one point; and, with ``robot``, ``tool``: the TCP is
    within :data:`~pincal.plausibility.verdict.TOOL` times the robot's size. When ``fit`` fails without a
    robot, other readings are tried: Euler angles a,b,c given in radians, x,y,z,w quaternions.

    Args:
        tool: the TCP calibration.
        rotations, positions: the flange poses as read (n, 3, 3), (n, 3) in the data's unit.
        orientation: the ``--orientation`` method (which rows are TCP rows).
        robot: the robot the poses came from (``--robot``), if any.
        scale, unit: data units per metre, and their name.
    """
    n_tcp = _tcp_rows(len(rotations), orientation)
    ratio, scatter = _tcp_scatter(tool.tcp, rotations[:n_tcp], positions[:n_tcp])
    text = (
        f"the TCP points of the poses scatter by {scatter:.4g} {unit} RMS, {100 * ratio:.2g} % of the "
        "flange positions' spread, though every TCP pose touches one point"
    )
    checks = [Check("fit", ratio, TCP_FIT, "ratio", text)]
    length = float(np.linalg.norm(tool.tcp)) / scale  # [m] (issue 33: the unit layer's bound)
    text = f"the TCP is {length:.4g} m from the flange, more than any tool an arm carries ({MAX_TOOL_M:g} m)"
    checks.append(Check("tool_size", length, MAX_TOOL_M, "m", text))
    size = robot_size(robot) if robot is not None else 0.0
    if robot is not None:
        reach = float(np.linalg.norm(tool.tcp)) / scale
        text = f"the TCP is {reach:.4g} m from the flange, {reach / size:.2g} times the robot's size"
        checks.append(Check("tool", reach / size, TOOL, "ratio", f"{text} ({size:.3g} m)"))
    verdict = Verdict(tuple(checks), size, what="TCP")
    if verdict.plausible:
        return verdict
    first = verdict.failed[0]
    for cause, fix, alt in _tool_readings(rotations) if first.name == "fit" and robot is None else ():
        try:
            tcp, _, _ = tcp_position(alt[:n_tcp], positions[:n_tcp])
        except PincalError:
            continue
        other, _ = _tcp_scatter(tcp, alt[:n_tcp], positions[:n_tcp])
        if other <= TCP_FIT and other * IMPROVEMENT <= ratio:
            return replace(verdict, cause=cause, hint=f"{fix} ({first.text}; read so, {100 * other:.2g} %)")
    fixes = {
        "fit": "the poses do not touch one point as read: check the angle columns (a,b,c in degrees, "
        "R = Rz(a) Ry(b) Rx(c); or the quaternion's order: quaternion_order=), orientation=, and "
        "re-teach the poses flagged far from the others",
        "tool": "check the joint columns (units: degrees=True) and tip=",
        "tool_size": "the x,y,z columns look like millimetres: pass units=mm"
        if unit == "m" and length * 1e-3 <= MAX_TOOL_M
        else "check the unit of x,y,z (units=) and that every TCP pose touches one point",
    }
    return replace(verdict, cause=first.name, hint=f"{first.text}: {fixes[first.name]}")


def _tcp_rows(n: int, orientation: str) -> int:
    n_orient = {"default": 0, "z": 2, "zx": 3}.get(orientation, 0)
    return n - n_orient + 1 if n_orient else n


def _tcp_scatter(tcp: np.ndarray, rotations: np.ndarray, positions: np.ndarray) -> tuple[float, float]:
    """Scatter (RMS from their mean) of the TCP points of the rows that turn, and its share of the
    flange positions' spread."""
    keep = [0]
    turned = _turns(rotations[:-1], rotations[1:]) > _SAME_TURN  # each row from the row before it
    for i in range(1, len(rotations)):
        if keep[-1] == i - 1:  # the row before was kept: its turn is known
            if turned[i - 1]:
                keep.append(i)
        elif _turns(rotations[keep[-1]], rotations[i]) > _SAME_TURN:
            keep.append(i)
    rot, pos = rotations[keep], positions[keep]
    points = rot @ tcp + pos
    scatter = float(np.sqrt(np.mean(np.sum((points - points.mean(axis=0)) ** 2, axis=1))))
    flange = float(np.sqrt(np.mean(np.sum((pos - pos.mean(axis=0)) ** 2, axis=1))))
    return (scatter / flange if flange > 0 else 0.0), scatter


def _turns(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """The angle [rad] between rotations ``first`` and ``second`` (..., 3, 3), row by row."""
    trace = np.einsum("...ij,...ij->...", first, second)  # tr(firstᵀ second)
    return np.arccos(np.clip((trace - 1) / 2, -1.0, 1.0))


def _tool_readings(rotations: np.ndarray) -> Iterator[tuple[str, str, np.ndarray]]:
    """Other readings of flange orientations: Euler angles in radians, x,y,z,w quaternions."""
    from pincal.identify.registration import quaternions

    # R = Rz(a) Ry(b) Rx(c): b = -asin(R20), a = atan2(R10, R00), c = atan2(R21, R22)
    b = -np.arcsin(np.clip(rotations[:, 2, 0], -1.0, 1.0))
    a = np.arctan2(rotations[:, 1, 0], rotations[:, 0, 0])
    c = np.arctan2(rotations[:, 2, 1], rotations[:, 2, 2])
    angles = np.stack([a, b, c], axis=1)
    if np.abs(angles).max() <= np.deg2rad(2 * np.pi + 1e-6):  # every value within 2π as written
        fix = "the angles a,b,c look like radians, and pincal tcp reads degrees: convert them to degrees"
        yield "radians", fix, euler_zyx(*np.rad2deg(angles).T)
    quats = quaternions(rotations)  # (w, x, y, z) as read: the file's columns in that order
    alt = quats[:, [3, 0, 1, 2]]
    matrices = np.array([pin.Quaternion(*q).normalized().toRotationMatrix() for q in alt])
    yield "quaternion_xyzw", "quaternion looks like x,y,z,w: pass quaternion_order=xyzw", matrices
