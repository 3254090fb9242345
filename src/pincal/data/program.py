"""A program to run on the robot: joint commands, or Cartesian targets of the tool, read from a CSV
(what ``pincal compensate`` and ``pincal plan`` read and write)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from pincal.data.csv_table import quaternion_columns, unit_quaternions
from pincal.data.dataset import csv_columns, joint_values, read_table
from pincal.errors import DataError
from pincal.options import UNITS
from pincal.robot.robots import Robot


@dataclass(frozen=True)
class Targets:
    """Cartesian targets of the tool in the base frame: positions (N, 3) [m], rotations (N, 3, 3) or None."""

    positions: np.ndarray
    rotations: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.positions)

    def __getitem__(self, i: int) -> pin.SE3:
        return pin.SE3(np.eye(3) if self.rotations is None else self.rotations[i], self.positions[i])


def read_joints(path: str | Path, robot: Robot, degrees: bool = False, units: str = "m") -> np.ndarray:
    """Joint values (N, n) [rad or m] from a CSV with a column per chain joint (revolute ones in
    radians, or degrees; prismatic ones in ``units``).

    Raises:
        DataError: missing file or columns, non-numeric cells.
    """
    values = read_table(path, robot.joint_names, f"every chain joint ({', '.join(robot.joint_names)})")
    return joint_values(values, degrees, units, robot.prismatic)


def read_program(
    path: str | Path, robot: Robot, degrees: bool = False, units: str = "m", quaternion_order: str = "wxyz"
) -> np.ndarray | Targets:
    """Read a program CSV: joint commands (N, n) [rad or m] from a column per chain joint, or else
    :class:`Targets` from ``x,y,z`` (in ``units``) and optional ``qw,qx,qy,qz`` (``quaternion_order``).
    With joint columns, ``x,y,z`` columns are ignored (they are measurements, not targets).

    Raises:
        DataError: missing file or columns, non-numeric cells, unknown unit.
    """
    if units not in UNITS:
        raise DataError(f"unknown unit {units!r}: use m or mm")
    header, names = set(csv_columns(path)), robot.joint_names
    if set(names) <= header:
        return read_joints(path, robot, degrees, units)
    if not {"x", "y", "z"} <= header:
        raise DataError(f"{path}: a program needs a column per joint ({', '.join(names)}) or targets x,y,z")
    quat = quaternion_columns(path, csv_columns(path), quaternion_order)  # all four or none, in file order
    values = read_table(path, ["x", "y", "z", *quat], "x,y,z (and optionally qw,qx,qy,qz)")
    quats = unit_quaternions(path, values[:, 3:]) if quat else None
    rot = None if quats is None else np.array([pin.Quaternion(*v).matrix() for v in quats])
    return Targets(values[:, :3] * UNITS[units], rot)
