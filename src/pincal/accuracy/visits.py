"""Repeated visits of commanded poses, as ISO 9283 measures them: which pose each row visits, what
was commanded there, and what was attained, all in the robot's base frame.

A CSV names the pose in its ``pose`` column; its optional ``x_cmd,y_cmd,z_cmd`` columns are the
programmed Cartesian position (the data's units, base frame). A recording's static poses are
grouped: poses whose joint values all agree within a tolerance are visits of one pose, named
P1, P2, ... in the order of their first visit.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from pincal.data.dataset import Dataset, read_rows, read_table
from pincal.errors import DataError
from pincal.export.calibrated_robot import CalibratedRobot
from pincal.options import UNITS
from pincal.robot.robots import Robot

#: The programmed position's columns.
PROGRAMMED = ("x_cmd", "y_cmd", "z_cmd")


@dataclass(frozen=True)
class Commanded:
    """Commanded tool positions (N, 3) [m] and rotations (N, 3, 3) or None, base frame."""

    positions: np.ndarray
    rotations: np.ndarray | None = None


def pose_labels(path: str | Path) -> list[str]:
    """The ``pose`` column of a CSV, one label per data row.

    Raises:
        DataError: no ``pose`` column, or an empty cell.
    """
    header, rows = read_rows(Path(path))
    if "pose" not in header:
        raise DataError(f"{path}: no pose column: ISO 9283 figures need the commanded pose each row visits")
    k = header.index("pose")
    labels = [row[k].strip() if k < len(row) else "" for row in rows]
    empty = [i + 1 for i, label in enumerate(labels) if not label]
    if empty:
        raise DataError(f"{path}: data row {empty[0]} names no pose")
    return labels


def programmed(path: str | Path, units: str) -> np.ndarray | None:
    """The programmed positions (N, 3) [m] of a CSV's ``x_cmd,y_cmd,z_cmd``, or None without them."""
    table = read_rows(Path(path))
    present = [c in table[0] for c in PROGRAMMED]
    if not any(present):
        return None
    what = "all three of x_cmd,y_cmd,z_cmd (the programmed position)"
    return read_table(path, PROGRAMMED, what, table=table) * UNITS[units]


def group_visits(q: np.ndarray, tolerance: float) -> list[str]:
    """Pose names P1, P2, ... for joint values (N, n): a row within ``tolerance`` (every joint) of
    a named pose's first visit visits that pose, else it is a new one."""
    firsts: list[np.ndarray] = []
    labels = []
    for row in q:
        match = next((k for k, first in enumerate(firsts) if np.all(np.abs(row - first) <= tolerance)), None)
        if match is None:
            firsts.append(row)
            match = len(firsts) - 1
        labels.append(f"P{match + 1}")
    return labels


def by_model(robot: Robot | CalibratedRobot, q: np.ndarray, tool: pin.SE3) -> Commanded:
    """The commanded tool poses as a model's forward kinematics of the commanded joints ``q``.

    Args:
        robot: the nominal chain, or a calibrated robot (its extension, tool and geometry).
        q: (N, n) commanded joint values [rad or m].
        tool: ``tip_T_tool`` for the nominal chain (a calibrated robot has its own).
    """
    if isinstance(robot, CalibratedRobot):
        poses = robot.tool_poses(q)  # in the order visited: lost motion reads it
    else:
        poses = [robot.frame_placement(row) * tool for row in q]
    return Commanded(np.array([p.translation for p in poses]), np.array([p.rotation for p in poses]))


def attained_in_base(
    data: Dataset, instrument_T_base: pin.SE3 | None
) -> tuple[np.ndarray, np.ndarray | None]:
    """Attained positions (N, 3) [m] and rotations (N, 3, 3) or None, in the base frame.

    Args:
        data: the measurements, in the instrument frame.
        instrument_T_base: the instrument's registration, or None when the data is in the base frame.
    """
    rotations = data.rotations() if data.has_orientation else None
    if instrument_T_base is None:
        return data.points, rotations
    base_T_instrument = instrument_T_base.inverse()
    points = data.points @ base_T_instrument.rotation.T + base_T_instrument.translation
    if rotations is not None:
        rotations = base_T_instrument.rotation @ rotations
    return points, rotations
