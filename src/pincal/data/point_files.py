"""Reading fixed-point data: MUKCa's folders of sockets (a CSV with a ``point`` column is
:func:`pincal.data.dataset.read_points_csv`'s).

Both give a :class:`~pincal.data.dataset.Dataset` whose ``labels`` index ``point_names`` (the point each
row held the tip at); its ``points`` are zero. MUKCa's layout (Franzese, Spahn et al. 2025) is a
folder per placement of the fixture holding ``hole_<name>.csv`` files without a header, one
column per chain joint [rad]; a folder of placements reads as one data set.
"""

from __future__ import annotations

import io
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pincal import files
from pincal.data.csv_table import other_separator
from pincal.data.dataset import Dataset
from pincal.errors import DataError
from pincal.inputs import read_bytes


def socket_files(folder: Path) -> list[Path]:
    """The ``hole_<name>.csv`` files of a folder, sorted; ``hole_<name>_pose.csv`` (MUKCa's
    recordings of the robot's own tip poses, x,y,z and a quaternion) are not joint values."""
    return sorted(p for p in folder.glob("hole_*.csv") if not p.stem.endswith("_pose"))


def read_socket_folder(
    folder: str | Path, joint_names: Sequence[str], prismatic: Sequence[bool] | None = None
) -> Dataset:
    """Fixed-point data in MUKCa's layout: a folder of ``hole_<name>.csv`` files without a
    header, one row per configuration, one column per chain joint in chain order [rad, m]; the
    point of a row is its file's ``<name>`` (``hole_<name>_pose.csv`` files are skipped). A
    folder of such folders (placements of the fixture, as MUKCa's ``data/<robot>/``) reads as one
    data set whose points are ``<placement>/<name>``:
    every placement's sockets are unknowns of their own, the robot is shared, and a known
    distance ``0,1=D`` holds in each placement (:func:`pincal.identify.fixed_points.placed_distances`).

    Raises:
        DataError: no such files, a row with the wrong number of values, a value not finite.
    """
    folder = Path(folder)
    files = socket_files(folder)
    if not files:
        places = sorted(p for p in folder.iterdir() if p.is_dir() and socket_files(p))
        if places:
            return _placements(folder, places, joint_names, prismatic)
        raise _not_sockets(folder)
    blocks, labels = [], []
    for k, path in enumerate(files):
        values = _socket_rows(path)
        if values.size == 0:
            raise DataError(f"{path} has no rows")
        if values.shape[1] != len(joint_names) or not np.all(np.isfinite(values)):
            raise DataError(
                f"{path}: each row needs {len(joint_names)} finite joint values "
                f"({', '.join(joint_names)}), it has {values.shape[1]}"
            )
        blocks.append(values)
        labels.append(np.full(len(values), k))
    q = np.vstack(blocks)
    names = tuple(path.stem.removeprefix("hole_") for path in files)
    prism = np.asarray(prismatic if prismatic is not None else [False] * q.shape[1], dtype=bool)
    if prism.any():
        raise DataError(f"{folder}: MUKCa's layout is for revolute arms; write a CSV with a point column")
    first = 1 + np.cumsum([0] + [len(b) for b in blocks[:-1]])
    return Dataset(
        tuple(joint_names),
        q,
        np.zeros((len(q), 3)),
        labels=np.concatenate(labels),
        point_names=names,
        point_rows=first,
    )


def _not_sockets(folder: Path) -> DataError:
    """The error for a folder given as data that holds no socket files, naming its CSV files."""
    csvs = sorted(p.name for p in folder.glob("*.csv"))
    held = f" (it holds {', '.join(csvs[:3])}{', ...' if len(csvs) > 3 else ''})" if csvs else ""
    return DataError(
        f"{folder} is a folder without hole_<name>.csv files (MUKCa's layout: one file per socket) "
        f"or folders of them (one per placement of the fixture): give the measurement CSV file{held}"
    )


def _socket_rows(path: Path) -> np.ndarray:
    """The rows of one socket file: a regular file of at most :data:`pincal.files.MAX_INPUT_BYTES`,
    read once (a link to ``/dev/zero`` or a named pipe is refused, issue 33)."""
    text = read_bytes(path, "socket file", files.MAX_INPUT_BYTES).decode("utf-8", "replace")
    try:
        with warnings.catch_warnings():  # an empty file is said below, not warned of by NumPy
            warnings.simplefilter("ignore", UserWarning)
            return np.loadtxt(io.StringIO(text), delimiter=",", ndmin=2, comments="#")
    except ValueError as exc:
        first = next((line for line in text.splitlines() if files.is_content(line)), "")
        named = other_separator(first)
        if named is not None:
            raise DataError(
                f"{path}: the rows are separated by {named}, not commas: a socket file is comma separated "
                "with a point as decimal mark: save it so"
            ) from None
        raise DataError(f"{path}: not a table of numbers ({' '.join(str(exc).split())})") from None


def _placements(
    folder: Path, places: list[Path], joint_names: Sequence[str], prismatic: Sequence[bool] | None
) -> Dataset:
    """The placements' data as one data set, their points named ``<placement>/<name>``."""
    parts = [read_socket_folder(place, joint_names, prismatic) for place in places]
    names = tuple(f"{place.name}/{name}" for place, part in zip(places, parts) for name in part.point_names)
    first = np.cumsum([0] + [len(part.point_names) for part in parts[:-1]])
    labels = np.concatenate([part.labels + k for part, k in zip(parts, first) if part.labels is not None])
    q = np.vstack([part.q for part in parts])
    starts = np.cumsum([0] + [len(part) for part in parts[:-1]])
    rows = np.concatenate(
        [part.point_rows + start for part, start in zip(parts, starts) if part.point_rows is not None]
    )
    return Dataset(
        tuple(joint_names), q, np.zeros((len(q), 3)), labels=labels, point_names=names, point_rows=rows
    )
