"""A dataset written as the measurement CSV :func:`pincal.data.dataset.read_csv` reads back."""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pincal.data.dataset import Dataset
from pincal.data.markers import write_marker_csv
from pincal.errors import DataError
from pincal.files import atomic_write
from pincal.options import UNITS

_QUAT = ("qw", "qx", "qy", "qz")


def pose_table(data: Dataset) -> tuple[np.ndarray, np.ndarray]:
    """Several markers per pose, one row per pose: joint values (P, n) and points (P, K, 3) [m]
    (NaN where the marker was not seen), poses in the order of their row numbers."""
    assert data.marker is not None
    poses, first, at = np.unique(data.row_numbers, return_index=True, return_inverse=True)
    points = np.full((len(poses), len(data.marker_names), 3), np.nan)
    points[at, data.marker] = data.points
    return data.q[first], points


def write_csv(
    path: str | Path,
    data: Dataset,
    units: str = "m",
    degrees: bool = False,
    prismatic: Sequence[bool] | None = None,
) -> None:
    """Write a dataset in the CSV format :func:`read_csv` reads, with the same arguments: reading
    the file back with them gives the dataset.

    Args:
        path: the CSV to write (atomically).
        data: the poses (radians and metres, as a dataset holds them).
        units: unit of ``x,y,z`` and of prismatic joint values (``m`` or ``mm``).
        degrees: write revolute joint values in degrees (else radians).
        prismatic: which joints are prismatic (written in ``units``, never in degrees); None:
            every joint is revolute.

    Raises:
        DataError: an unknown unit, or ``prismatic`` not one flag per joint.
    """
    from pincal.units import joints_to_file

    if units not in UNITS:
        raise DataError(f"unknown unit {units!r}: use m or mm")
    n = len(data.joint_names)
    if prismatic is not None and len(prismatic) != n:
        raise DataError(f"prismatic= has {len(prismatic)} flags for {n} joints: give one per joint")
    if data.marker is not None:  # several markers: a pose's markers on its row, xK,yK,zK
        poses, points = pose_table(data)
        q_file = joints_to_file(poses, degrees, units, prismatic)
        write_marker_csv(path, data.joint_names, q_file, data.marker_names, points, units)
        return
    q = joints_to_file(data.q, degrees, units, prismatic)
    scale = 1.0 / UNITS[units]
    fixed = data.labels is not None
    header = [*data.joint_names, *(("point",) if fixed else ("x", "y", "z"))]
    header += _QUAT if data.has_orientation else ()
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    for i in range(len(data)):
        row = [repr(float(v)) for v in q[i]]
        if data.labels is not None:
            row.append(data.point_names[data.labels[i]])
        else:
            row += [repr(float(v)) for v in data.points[i] * scale]
        if data.quaternions is not None:
            row += [repr(float(v)) for v in data.quaternions[i]]
        writer.writerow(row)
    atomic_write(path, buffer.getvalue())
