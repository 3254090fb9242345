"""Measurement data: the :class:`Dataset` container and the CSV format of ``contracts.md``.

One row per pose: a column per actuated joint of the chain, named as the URDF joint (radians or
metres; degrees with ``degrees=True``), ``x,y,z`` the measured point in the instrument frame
(metres; millimetres with ``units="mm"``) and optionally ``qw,qx,qy,qz`` the measured
orientation of a target frame on the tip. Other columns are ignored. Lines starting with ``#``
are comments.

Fixed-point data (``--measure points``, :mod:`pincal.identify.fixed_points`) has a ``point`` column
instead of ``x,y,z``: the name of the physical point (a socket) the tip was held at.
"""

from __future__ import annotations

import csv
import functools
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from pincal.data import csv_table
from pincal.data.csv_table import check_locked, content_lines, parse_header, quaternion_columns, read_columns
from pincal.data.directions import move_directions
from pincal.data.markers import check_seen, marker_labels, observations, read_marker_table
from pincal.errors import DataError
from pincal.files import STDIN, first_line
from pincal.options import UNITS

_QUAT = ("qw", "qx", "qy", "qz")


@dataclass(frozen=True)
class Dataset:
    """Joint values and measurements of a set of poses. Internally metres and radians.

    Attributes:
        joint_names: the chain joints the columns of ``q`` belong to.
        q: (N, n) joint values [rad or m].
        points: (N, 3) measured point in the instrument frame [m].
        quaternions: (N, 4) measured orientation (w, x, y, z) in the instrument frame, or None.
        rows: (N,) the row number of each pose in its source, or None for 1..N.
        labels: (N,) for fixed-point data, the index in ``point_names`` of the point each pose
            held the tip at (``points`` is then zero), else None.
        point_names: the names of the fixed points, as the ``point`` column gives them.
        point_rows: for a folder of ``hole_<name>.csv`` files (one per point, read one after the
            other), the row number of each file's first row, so that a row is named by its file
            (:meth:`row_name`); else None.
        spread: (N,) for poses averaged over a static segment of a recording, the measurement's
            spread over it (RMS per axis of its standard deviation) [m], else None.
        directions: (N, n) each joint's direction of motion into each pose, read from the order
            of the whole source's rows (kept by :meth:`subset`), or None: from the order of ``q``
            (:meth:`moves`).
        marker: (N,) for several markers per pose (:mod:`pincal.data.markers`), the index in
            ``marker_names`` of the marker each row measured (a row is one marker seen in a pose;
            the markers of one pose share its row number), else None.
        marker_names: the markers' labels, in the order of their columns.
    """

    joint_names: tuple[str, ...]
    q: np.ndarray
    points: np.ndarray
    quaternions: np.ndarray | None = None
    rows: np.ndarray | None = None
    labels: np.ndarray | None = None
    point_names: tuple[str, ...] = ()
    point_rows: np.ndarray | None = None
    spread: np.ndarray | None = None
    directions: np.ndarray | None = None
    marker: np.ndarray | None = None
    marker_names: tuple[str, ...] = ()

    def moves(self) -> np.ndarray:
        """Each joint's direction of motion into each pose (N, n): +1 rising, -1 falling, 0 for
        the source's first row (:func:`pincal.data.directions.move_directions`)."""
        return self._moves

    @functools.cached_property
    def _moves(self) -> np.ndarray:
        """:meth:`moves`, worked out once (a subset of a large data set asks for them each time)."""
        return self.directions if self.directions is not None else move_directions(self.q)

    @property
    def row_numbers(self) -> np.ndarray:
        """Row number of each pose in its source (1 = first data row)."""
        return self.rows if self.rows is not None else np.arange(1, len(self.q) + 1)

    def row_name(self, row: int) -> str:
        """Where row number ``row`` is: ``row 7``, in socket files ``left/hole_1.csv row 7``."""
        if self.point_rows is None or row < self.point_rows[0]:
            return f"row {row}"
        k = int(np.searchsorted(self.point_rows, row, side="right")) - 1
        place, _, name = self.point_names[k].rpartition("/")
        return f"{place + '/' if place else ''}hole_{name}.csv row {row - int(self.point_rows[k]) + 1}"

    def __len__(self) -> int:
        return len(self.q)

    @property
    def measured(self) -> str:
        """What the columns measure: ``points``, ``pose`` or ``position`` (never ``distance``)."""
        return "points" if self.labels is not None else "pose" if self.has_orientation else "position"

    @property
    def has_orientation(self) -> bool:
        """Whether the data holds measured orientations (full-pose data)."""
        return self.quaternions is not None

    def rotations(self) -> np.ndarray:
        """Measured orientations as rotation matrices (N, 3, 3)."""
        return self._rotations

    @functools.cached_property
    def _rotations(self) -> np.ndarray:
        """:meth:`rotations`, worked out once (each problem on the same poses asks for them)."""
        if self.quaternions is None:
            raise DataError("the data has no orientation columns qw,qx,qy,qz")
        w, x, y, z = (self.quaternions / np.linalg.norm(self.quaternions, axis=1, keepdims=True)).T
        return np.stack(
            [
                np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
                np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
            ],
            axis=1,
        )

    def subset(self, index: Sequence[int] | np.ndarray | slice) -> Dataset:
        """The poses at ``index`` (row numbers are kept); a slice's subset holds views of these
        arrays, not copies."""
        idx = index if isinstance(index, slice) else np.asarray(index)
        per_pose = ("q", "points", "quaternions", "labels", "spread", "marker")
        chosen = {name: getattr(self, name)[idx] for name in per_pose if getattr(self, name) is not None}
        rows = np.array(self.row_numbers[idx])  # a copy: not a view of a temporary
        sub = replace(self, rows=rows, directions=self.moves()[idx], **chosen)
        if isinstance(idx, slice) and "_rotations" in self.__dict__:  # worked out already: a view
            sub.__dict__["_rotations"] = self._rotations[idx]
        return sub

    def split(self, fraction: float, seed: int = 0) -> tuple[Dataset, Dataset]:
        """Random (fit, held-out) split, ``fraction`` of the poses held out."""
        if not 0.0 < fraction < 1.0:
            raise DataError(f"fraction= must be a fraction between 0 and 1, got {fraction}")
        if seed < 0:
            raise DataError(f"seed= must be 0 or more, got {seed}")
        if self.marker is not None:  # the markers of a pose stay together
            return self._split_poses(fraction, seed)
        order = np.random.default_rng(seed).permutation(len(self))
        n_out = max(1, round(fraction * len(self)))
        if n_out >= len(self):
            raise DataError(
                f"fraction={fraction} of {len(self)} poses leaves none to fit: hold out a smaller fraction"
            )
        return self.subset(np.sort(order[n_out:])), self.subset(np.sort(order[:n_out]))

    @property
    def n_poses(self) -> int:
        """Number of poses (several markers: of distinct row numbers; else of rows)."""
        return len(self) if self.marker is None else len(np.unique(self.row_numbers))

    def _split_poses(self, fraction: float, seed: int) -> tuple[Dataset, Dataset]:
        """:meth:`split` of several markers per pose: whole poses (rows of one row number) held out."""
        poses = np.unique(self.row_numbers)
        order = np.random.default_rng(seed).permutation(len(poses))
        n_out = max(1, round(fraction * len(poses)))
        if n_out >= len(poses):
            raise DataError(
                f"fraction={fraction} of {len(poses)} poses leaves none to fit: hold out a smaller fraction"
            )
        out = np.isin(self.row_numbers, poses[order[:n_out]])
        return self.subset(np.flatnonzero(~out)), self.subset(np.flatnonzero(out))


def every_marker(data: Dataset, q: np.ndarray, quaternions: np.ndarray | None = None) -> Dataset:
    """Poses ``q`` (P, n) with nothing measured (points zero), shaped as ``data``: with several
    markers, one row per marker of each pose (all seen)."""
    if data.marker is None:
        return Dataset(data.joint_names, q, np.zeros((len(q), 3)), quaternions)
    k = len(data.marker_names)
    return Dataset(
        data.joint_names,
        np.repeat(q, k, axis=0),
        np.zeros((len(q) * k, 3)),
        rows=np.repeat(np.arange(1, len(q) + 1), k),
        marker=np.tile(np.arange(k), len(q)),
        marker_names=data.marker_names,
    )


def csv_columns(path: str | Path) -> list[str]:
    """The column names of a measurement CSV (its first non-comment line, read up to it)."""
    header = first_line(path)
    if header is None:
        name = "standard input" if str(path) == STDIN else path
        raise DataError(f"{name} is empty: it needs a header line and one row per pose")
    return parse_header(path, header)


Table = tuple[list[str], list[list[str]]]


def read_rows(path: Path) -> Table:
    """Header and data rows of a CSV as text (comments dropped), with duplicated columns refused."""
    lines = content_lines(path)
    first = next(lines, None)
    if first is None:
        raise DataError(f"{path} is empty: it needs a header line and one row per pose")
    header = parse_header(path, first)
    try:
        return header, list(csv.reader(lines))
    except csv.Error as exc:
        raise DataError(f"{path}: malformed CSV ({exc})") from None


def read_table(
    path: str | Path,
    columns: Sequence[str],
    what: str,
    rename: dict[str, str] | None = None,
    table: Table | None = None,
) -> np.ndarray:
    """The named columns of a CSV as finite numbers (rows, columns), streamed
    (:func:`pincal.data.csv_table.read_columns`; ``table``, the file's header and rows already read,
    is accepted for callers of old and read again from the file).

    Raises:
        DataError: missing file, duplicated or missing columns, no rows, non-numeric or non-finite cells.
    """
    return read_columns(path, columns, what, rename)[0]


def read_csv(
    path: str | Path,
    joint_names: Sequence[str],
    degrees: bool = False,
    units: str = "m",
    prismatic: Sequence[bool] | None = None,
    measure: str | None = None,
    quaternion_order: str = "wxyz",
    locked: Sequence[str] = (),
) -> Dataset:
    """Read a measurement CSV (see the module docstring).

    Args:
        path: the CSV file.
        joint_names: the chain's actuated joints; each must have a column.
        degrees: revolute joint values are in degrees.
        units: unit of ``x,y,z`` and of prismatic joint values (``m`` or ``mm``).
        prismatic: which joints are prismatic (their values take ``units``, not degrees).
        measure: ``points`` reads fixed-point data (a ``point`` column, no ``x,y,z``); the
            default reads it when the file has a ``point`` column and no ``x,y,z``.
        quaternion_order: ``wxyz``: the columns ``qw,qx,qy,qz`` hold what their names say;
            ``xyzw``: the four quaternion columns, left to right, hold x, y, z, w.
        locked: joints held at their neutral value (``--lock``): a column of theirs must not move.

    Raises:
        DataError: the file is missing or malformed, holds some but not all of the quaternion
            columns, or a locked joint's column moves.
    """
    if units not in UNITS:
        raise DataError(f"unknown unit {units!r}: use m or mm")
    header = csv_columns(path)
    quat_order = quaternion_columns(path, header, quaternion_order)
    if measure == "points" or (measure is None and "point" in header and "x" not in header):
        return read_points_csv(path, joint_names, degrees, units, prismatic)
    labels = marker_labels(header)
    if labels and "x" not in header:
        return read_markers_csv(path, joint_names, labels, degrees, units, prismatic)
    required = [*joint_names, "x", "y", "z"]
    still = [j for j in locked if j in header and j not in joint_names]
    wanted = [*required, *quat_order, *still]
    values = read_table(path, wanted, f"every chain joint ({', '.join(joint_names)}) and x,y,z")
    n = len(joint_names)
    q = joint_values(values[:, :n], degrees, units, prismatic)
    points = values[:, n : n + 3] * UNITS[units]
    quats = csv_table.unit_quaternions(path, values[:, n + 3 : n + 7]) if quat_order else None
    check_locked(path, still, values[:, n + 3 + len(quat_order) :], degrees)
    return Dataset(tuple(joint_names), q, points, quats)


def read_points_csv(
    path: str | Path,
    joint_names: Sequence[str],
    degrees: bool = False,
    units: str = "m",
    prismatic: Sequence[bool] | None = None,
) -> Dataset:
    """Fixed-point data as a CSV (read once): a column per chain joint, as
    :func:`pincal.data.dataset.read_csv`
    reads them, and a ``point`` column naming each row's point (names in order of first appearance).

    Raises:
        DataError: the file is missing or malformed, no ``point`` column, an empty point name.
    """
    if "point" not in csv_columns(path):
        raise DataError(f"{path}: no 'point' column; fixed-point data names each row's point there")
    what = f"every chain joint ({', '.join(joint_names)}) and point"
    values, points = read_columns(path, joint_names, what, text_column="point")  # streamed (issue 33)
    q = joint_values(values, degrees, units, prismatic)
    names: dict[str, int] = {}
    labels = np.empty(len(points), dtype=int)
    for r, name in enumerate(points):
        if not name:
            raise DataError(f"{path}: data row {r + 1} has no point name in column 'point'")
        labels[r] = names.setdefault(name, len(names))
    return Dataset(tuple(joint_names), q, np.zeros((len(q), 3)), labels=labels, point_names=tuple(names))


def read_markers_csv(
    path: str | Path,
    joint_names: Sequence[str],
    labels: Sequence[str],
    degrees: bool = False,
    units: str = "m",
    prismatic: Sequence[bool] | None = None,
) -> Dataset:
    """A CSV of several markers per pose (:mod:`pincal.data.markers`) as observations: one row per
    marker seen, ``marker`` its index in ``labels``, ``rows`` its pose's data row.

    Raises:
        DataError: the file is missing or malformed, a marker never seen (a row with none seen
            is left out).
    """
    values, points = read_marker_table(path, joint_names, labels)
    check_seen(path, labels, points)
    pose, marker = observations(points)
    q = joint_values(values, degrees, units, prismatic)
    return Dataset(
        tuple(joint_names),
        q[pose],
        points[pose, marker] * UNITS[units],
        rows=pose + 1,
        marker=marker,
        marker_names=tuple(labels),
        directions=move_directions(q)[pose],  # from the file's rows: one per pose
    )


def joint_values(
    values: np.ndarray, degrees: bool, units: str, prismatic: Sequence[bool] | None
) -> np.ndarray:
    """Joint columns as read -> radians and metres (:func:`pincal.units.joints_from_file`)."""
    from pincal.units import joints_from_file

    return joints_from_file(values, degrees, units, prismatic)
