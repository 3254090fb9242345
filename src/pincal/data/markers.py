"""Several markers per pose: the CSV columns ``xK,yK,zK`` of ``contracts.md``.

A file whose header has ``xK,yK,zK`` columns for labels K (digits or letters, compared as written)
holds labelled markers, in the order of their columns. Each marker is a point fixed on its frame,
all in one instrument frame. A row's three cells of a marker may all be empty: the marker was
not seen in that row, and the row's other markers still count.

Inside pincal such data is a :class:`~pincal.data.dataset.Dataset` of *observations*: one row per
marker seen in a pose, ``marker`` naming the marker (an index into ``marker_names``) and ``rows``
the pose's row number in the file (shared by the markers of one pose). Every measurement kind then
reads it as it reads one marker per pose: the rows of ``position`` are each observation's point,
the pairs of ``distance`` every pair of measured points (markers of one pose included).
"""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pincal.data.csv_table import content_lines, parse_header
from pincal.errors import DataError
from pincal.files import atomic_write
from pincal.options import UNITS

#: A marker label: digits or letters (``x1``, ``xA``, ``x01``).
_LABEL = re.compile(r"[A-Za-z0-9]+")


def marker_labels(header: Sequence[str]) -> list[str]:
    """The marker labels K of a header with ``xK,yK,zK`` columns, in the order of their ``xK``
    columns (none for a header of one marker ``x,y,z``)."""
    names = set(header)
    return [
        h[1:]
        for h in header
        if h.startswith("x") and _LABEL.fullmatch(h[1:]) and f"y{h[1:]}" in names and f"z{h[1:]}" in names
    ]


def _number(path: str | Path, r: int, name: str, cell: str) -> float:
    try:
        value = float(cell)
    except ValueError:
        raise DataError(f"{path}: data row {r}, column {name}: {cell!r} is not a number") from None
    if not np.isfinite(value):
        raise DataError(f"{path}: data row {r}, column {name}: {cell} is not a finite number")
    return value


def read_marker_table(
    path: str | Path, joint_names: Sequence[str], labels: Sequence[str]
) -> tuple[np.ndarray, np.ndarray]:
    """The joint columns (N, n) and the markers' points (N, K, 3) of a CSV, as written (NaN where
    a marker was not seen).

    Raises:
        DataError: missing columns, a row with another number of fields, a cell that is not a
            number, a marker with some but not all of its three cells empty, no rows.
    """
    lines = content_lines(path)
    first = next(lines, None)
    if first is None:
        raise DataError(f"{path} is empty: it needs a header line and one row per pose")
    header = parse_header(path, first)
    missing = [j for j in joint_names if j not in header]
    if missing:
        raise DataError(f"{path}: missing column(s) {', '.join(missing)}; the header must name every joint")
    at = {name: k for k, name in enumerate(header)}
    joints, points = [], []
    try:
        for r, row in enumerate(csv.reader(lines), start=1):
            if len(row) != len(header):
                raise DataError(f"{path}: data row {r} has {len(row)} fields, the header {len(header)}")
            joints.append([_number(path, r, j, row[at[j]]) for j in joint_names])
            points.append(
                [_marker(path, r, label, [row[at[f"{a}{label}"]] for a in "xyz"]) for label in labels]
            )
    except csv.Error as exc:
        raise DataError(f"{path}: malformed CSV ({exc})") from None
    if not joints:
        raise DataError(f"{path} has a header but no data rows")
    return np.array(joints, dtype=float), np.array(points, dtype=float).reshape(len(joints), len(labels), 3)


def _marker(path: str | Path, r: int, label: str, cells: list[str]) -> list[float]:
    """A marker's three cells as numbers, or NaN when all three are empty (not seen)."""
    empty = [not c.strip() for c in cells]
    if all(empty):
        return [np.nan] * 3
    if any(empty):
        raise DataError(
            f"{path}: data row {r}: marker {label} has some but not all of x{label},y{label},z{label} "
            "empty: leave all three empty when the marker was not seen"
        )
    return [_number(path, r, f"{a}{label}", c) for a, c in zip("xyz", cells)]


def observations(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The (pose, marker) index pairs of the markers seen, pose by pose, in the columns' order."""
    seen = ~np.isnan(points[:, :, 0])
    pose, marker = np.nonzero(seen)
    return pose, marker


def check_seen(path: str | Path, labels: Sequence[str], points: np.ndarray) -> None:
    """Refuse markers never seen (a row where none is seen measures nothing: it is left out,
    though its joint values still give the next row's directions of motion)."""
    seen = ~np.isnan(points[:, :, 0])
    never = [label for label, s in zip(labels, seen.T) if not s.any()]
    if never:
        raise DataError(
            f"{path}: marker(s) {', '.join(never)} have no row where they were seen: fill their cells, "
            "or drop their columns"
        )


def write_marker_csv(
    path: str | Path,
    joint_names: Sequence[str],
    q: np.ndarray,
    labels: Sequence[str],
    points: np.ndarray,
    units: str = "m",
) -> None:
    """Write a CSV of several markers (joint values [rad or m], points (N, K, 3) [m], NaN: not
    seen, written as empty cells) in ``units``."""
    scale = 1.0 / UNITS[units]
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow([*joint_names, *(f"{a}{k}" for k in labels for a in "xyz")])
    for qi, pi in zip(q, points):
        cells = ["" if np.isnan(v) else repr(float(v) * scale) for v in pi.reshape(-1)]
        writer.writerow([*(repr(float(v)) for v in qi), *cells])
    atomic_write(path, buffer.getvalue())
