"""Flange poses read from a CSV for the tool calibration: ``x,y,z,a,b,c`` (degrees), ``x,y,z`` with a
quaternion, or joint columns turned into flange poses by a robot's forward kinematics."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin

from pincal.data.checks import bounded_spread
from pincal.data.csv_table import unit_quaternions
from pincal.data.dataset import UNITS, csv_columns, read_table
from pincal.errors import DataError
from pincal.robot.robots import Robot
from pincal.tool.tcp import euler_zyx
from pincal.units import joints_from_file

#: The columns a flange-pose CSV is read by (``rename`` maps them to the file's).
POSE_COLUMNS = ("x", "y", "z", "a", "b", "c", "qw", "qx", "qy", "qz")


def _check_rename(path: str | Path, rename: dict[str, str] | None, robot: Robot | None) -> None:
    """Refuse a ``rename`` entry that would do nothing: a name the poses are not read by, or a
    file column the file does not have (it used to pass in silence, the column read by its own name).

    Raises:
        DataError: naming the entry, and what the file and the reader have.
    """
    if not rename:
        return
    known = robot.joint_names if robot is not None else POSE_COLUMNS
    unknown = [f"{name}={column}" for name, column in rename.items() if name not in known]
    if unknown:
        raise DataError(
            f"rename={','.join(unknown)}: the poses are read by the columns {', '.join(known)}: "
            "name one of them before each '='"
        )
    header = csv_columns(path)
    absent = [f"{name}={column}" for name, column in rename.items() if column not in header]
    if absent:
        raise DataError(
            f"rename={','.join(absent)}: {path} has no such column (it has {', '.join(header)}): "
            "name a column of the file after each '='"
        )


def read_flange_poses(
    path: str | Path,
    units: str = "m",
    rename: dict[str, str] | None = None,
    robot: Robot | None = None,
    degrees: bool = False,
    quaternion_order: str = "wxyz",
) -> tuple[np.ndarray, np.ndarray]:
    """Flange poses from a CSV: ``x,y,z,a,b,c`` (degrees, R = Rz(a) Ry(b) Rx(c)), ``x,y,z,qw,qx,qy,qz``,
    or, with ``robot``, joint columns turned into flange poses by its forward kinematics.

    Args:
        path: the CSV.
        units: unit of ``x,y,z`` and of the results (``m`` or ``mm``).
        rename: map from the contract's column names to the file's (``{"x": "X_mm", ...}``).
        robot: compute the flange poses from joint columns with this robot's tip frame.
        degrees: with ``robot``, revolute joint values are in degrees.
        quaternion_order: ``wxyz``: ``qw,qx,qy,qz`` hold what their names say; ``xyzw``: the four
            quaternion columns, left to right, hold x, y, z, w.

    Returns:
        Rotations (n, 3, 3) and positions (n, 3) in ``units``.
    """
    if units not in UNITS:
        raise DataError(f"unknown unit {units!r}: use m or mm")
    _check_rename(path, rename, robot)
    if robot is not None:
        q = read_table(path, robot.joint_names, f"the joints {', '.join(robot.joint_names)}", rename)
        q = joints_from_file(q, degrees, units, robot.prismatic)
        poses = [robot.frame_placement(qi) for qi in q]
        return np.array([m.rotation for m in poses]), np.array([m.translation for m in poses]) / UNITS[units]
    columns = csv_columns(path)
    header = set(columns)
    names = {(rename or {}).get(c, c) for c in ("qw", "qx", "qy", "qz")}
    if names & header and not names <= header:
        raise DataError(
            f"{path}: the header has {', '.join(sorted(names & header))} but not "
            f"{', '.join(sorted(names - header))}: a quaternion needs all four columns qw,qx,qy,qz"
        )
    if names <= header:
        quat = ["qw", "qx", "qy", "qz"]
        if quaternion_order == "xyzw":  # the four columns left to right are x, y, z, w
            mine = {(rename or {}).get(c, c): c for c in quat}
            ordered = [mine[c] for c in columns if c in mine]
            quat = [ordered[3], *ordered[:3]]
        values = read_table(path, ["x", "y", "z", *quat], "x,y,z,qw,qx,qy,qz", rename)
        quats = unit_quaternions(path, values[:, 3:])
        rotations = np.array([pin.Quaternion(*qt).toRotationMatrix() for qt in quats])
        bounded_spread(values[:, :3] * UNITS[units], "flange positions x,y,z")
        return rotations, values[:, :3]
    values = read_table(
        path, ["x", "y", "z", "a", "b", "c"], "x,y,z and a,b,c [deg] (or qw,qx,qy,qz)", rename
    )
    bounded_spread(values[:, :3] * UNITS[units], "flange positions x,y,z")
    return euler_zyx(*np.deg2rad(values[:, 3:]).T), values[:, :3]
