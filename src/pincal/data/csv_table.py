"""Reading a CSV's columns as numbers, streamed and bounded.

A file is read once and bounded (:func:`pincal.files.read_input_text`), then parsed by blocks of
lines, NumPy's C parser first: only the wanted columns are kept, as 8-byte floats (a million
poses are never a million lists of cells). Lines that are blank or start with ``#`` are
comments; the lines are those :meth:`str.splitlines` knows.

Bounds (stated in ``docs/reliability.md``): at most :data:`MAX_COLUMNS` columns in the header,
:data:`MAX_ROWS` data rows, :data:`~pincal.files.MAX_HEADER_CHARS` characters on a line and
:data:`~pincal.files.MAX_INPUT_BYTES` in the file; beyond them the file is refused in one line.
"""

from __future__ import annotations

import csv
import difflib
import itertools
import math
import re
from array import array
from collections import Counter
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from pincal import files
from pincal.errors import DataError
from pincal.options import QUATERNION_ORDERS
from pincal.workers import parallel_map

LOCK_TOLERANCE = 1e-3  # [rad or m]: a locked joint's column may move this much and count as still
_QUAT = ("qw", "qx", "qy", "qz")
#: Most columns a measurement CSV may have (a chain of 100 joints and its measurements has ~110).
MAX_COLUMNS = 10_000
#: Most data rows a measurement CSV may have.
MAX_ROWS = 20_000_000


def content_lines(path: str | Path, what: str = "data file") -> Iterator[str]:
    """The lines of an input that are neither blank nor ``#`` comments, streamed.

    Raises:
        DataError: unreadable, not UTF-8, a line longer than :data:`~pincal.files.MAX_HEADER_CHARS`,
            or too large a file (see :func:`pincal.files.read_input_text`).
    """
    for block in content_blocks(path, what):
        yield from block


def content_blocks(path: str | Path, what: str = "data file") -> Iterator[list[str]]:
    """:func:`content_lines` in lists of :data:`_BLOCK_LINES` lines. The file is read once, whole
    and bounded (:func:`pincal.files.read_input_text`: at most 500 MB, a regular file or a pipe);
    its lines are then parsed block by block (a million rows are never a million lists of cells)."""
    text = files.read_input_text(path, what)
    lines = [line for line in text.splitlines() if files.is_content(line)]
    del text
    longest = max(map(len, lines), default=0)
    if longest > files.MAX_HEADER_CHARS:
        raise DataError(f"{what} {path}: a line of {longest:,} characters: is it a CSV?")
    for start in range(0, len(lines), _BLOCK_LINES):
        yield lines[start : start + _BLOCK_LINES]


def parse_header(path: str | Path, line: str) -> list[str]:
    """The column names of a header line, refused when duplicated or more than :data:`MAX_COLUMNS`."""
    try:
        header = [h.strip() for h in next(csv.reader([line]))]
    except csv.Error as exc:
        raise DataError(f"{path}: malformed header line ({exc})") from None
    _check_separator(path, line, header)
    if len(header) > MAX_COLUMNS:
        raise DataError(
            f"{path}: the header has {len(header):,} columns, more than {MAX_COLUMNS:,}: is it a CSV?"
        )
    dupes = sorted(name for name, count in Counter(header).items() if name and count > 1)
    if dupes:
        raise DataError(f"{path}: duplicated column(s) {', '.join(dupes)}")
    return header


#: Separators of tables that are not comma separated, named for the message.
_OTHER_SEPARATORS = {";": "semicolons", "\t": "tabs", "|": "vertical bars", " ": "spaces"}


def _check_separator(path: str | Path, line: str, header: list[str]) -> None:
    """Refuse a header of one column that another separator splits into several: a table saved
    with semicolons (a spreadsheet in a locale whose decimal mark is a comma), tabs or spaces
    would otherwise be one column named after the whole line, and every joint "missing"."""
    if len(header) != 1:
        return
    for sep, name in _OTHER_SEPARATORS.items():
        names = [part.strip() for part in line.split(sep) if part.strip()]
        if len(names) > 1:
            raise DataError(
                f"{path}: the header line is separated by {name} ({', '.join(names[:4])}"
                f"{', ...' if len(names) > 4 else ''}), not commas: a measurement CSV is comma separated "
                "with a point as decimal mark: save it so (or replace each separator with a comma and "
                "each decimal comma with a point)"
            )


def other_separator(line: str) -> str | None:
    """The name of the separator other than a comma that splits ``line`` into several cells, when
    the line has no comma (``semicolons``, ``tabs``, ...), else None."""
    if "," in line:
        return None
    return next((name for sep, name in _OTHER_SEPARATORS.items() if len(line.strip().split(sep)) > 1), None)


def _separator_hint(line: str, n_fields: int) -> str:
    """``: ... separated by NAME`` when another separator splits a data row into the header's fields."""
    for sep, name in _OTHER_SEPARATORS.items():
        if len(line.split(sep)) == n_fields:
            return f": the row is separated by {name}, the header by commas: separate every line with commas"
    return ""


def read_columns(
    path: str | Path,
    columns: Sequence[str],
    what: str,
    rename: dict[str, str] | None = None,
    text_column: str | None = None,
) -> tuple[np.ndarray, list[str]]:
    """The named columns of a CSV as finite numbers (rows, columns), and one column as text.

    Args:
        path: the CSV file (``-`` is standard input).
        columns: the numeric columns wanted, in order.
        what: how to describe the required columns in an error message.
        rename: optional map from wanted name to the file's column name.
        text_column: a column kept as text (each row's value, stripped), or None.

    Raises:
        DataError: missing file, duplicated or missing columns, no rows, too many rows or columns,
            a row with another number of fields than the header, non-numeric or non-finite cells.
    """
    blocks = content_blocks(path)
    first = next(filter(None, blocks), [None])
    if first[0] is None:
        name = "standard input" if str(path) == files.STDIN else path
        raise DataError(f"{name} is empty: it needs a header line and one row per pose")
    header = parse_header(path, first[0])
    names = [(rename or {}).get(c, c) for c in columns]
    missing = [c for c in [*names, *([text_column] if text_column else [])] if c not in header]
    if missing:
        hints = misspelt(missing, [c for c in header if c not in names])
        raise DataError(f"{path}: missing column(s) {', '.join(missing)}; the header must name {what}{hints}")
    index = {name: k for k, name in enumerate(header)}
    cols = [index[c] for c in names]
    at = index[text_column] if text_column else -1
    rows = [block for block in itertools.chain([first[1:]], blocks) if block]
    if sum(map(len, rows)) > MAX_ROWS:
        raise DataError(f"{path} has more than {MAX_ROWS:,} data rows: split it")
    if not rows:
        raise DataError(f"{path} has a header but no data rows")
    fast = _fast_blocks(rows, len(header), cols) if at < 0 else [None] * len(rows)
    parsed: list[np.ndarray] = []
    texts: list[str] = []
    done = 0
    for block, values in zip(rows, fast):
        if values is None:
            values = _parse_block(path, block, len(header), cols, names, at, done, texts)
        parsed.append(values)
        done += len(block)
    return np.concatenate(parsed) if len(parsed) > 1 else parsed[0], texts


#: A unit written into a column's name after a separator or in brackets: ``x_mm``, ``X [mm]``,
#: ``y(m)``, ``a_deg`` (not the last letter of a word: ``bottom``, ``custom``).
_UNIT_SUFFIX = re.compile(r"(?:[\s_]+[(\[]?|[(\[])\s*(mm|m|deg|rad)\s*[)\]]?$", re.IGNORECASE)


def misspelt(wanted: Sequence[str], columns: Sequence[str]) -> str:
    """``; misspelt: 'X_mm' for x? ...`` for the wanted names that one of ``columns`` seems meant
    to be (the same name in other capitals or with a unit after it, or a close spelling), with a
    word on units when a column holds one in its name; empty when none is."""
    plain = {_UNIT_SUFFIX.sub("", c).strip().lower() or c.lower(): c for c in columns}
    matches = {}
    for name in wanted:
        close = difflib.get_close_matches(name, columns, n=1, cutoff=0.6)
        match = plain.get(name.lower()) or (close[0] if close else None)
        if match is not None:
            matches[name] = match
    if not matches:
        return ""
    text = "; misspelt: " + " ".join(f"'{column}' for {name}?" for name, column in matches.items())
    if any(_UNIT_SUFFIX.search(column) for column in matches.values()):
        text += " (a column's name holds no unit: give it with units=mm or degrees=True)"
    return text


#: Lines parsed at once.
_BLOCK_LINES = 65_536


def _fast_blocks(blocks: list[list[str]], n_fields: int, cols: list[int]) -> list[np.ndarray | None]:
    """:func:`_fast_block` of each block; the blocks of a large file (several) side by side in
    worker processes (:func:`pincal.workers.parallel_map`: the same numbers).

    A worker is handed its blocks as one text each (the lines hold no line break): reading the
    parent's line objects would write to each (its reference count), and copying those pages
    took as long as parsing them."""
    if len(blocks) == 1:
        return [_fast_block(blocks[0], n_fields, cols)]
    texts = ["\n".join(block) for block in blocks]
    return parallel_map(lambda k: _fast_block(texts[k].split("\n"), n_fields, cols), len(blocks))


def _fast_block(block: list[str], n_fields: int, cols: list[int]) -> np.ndarray | None:
    """The block's columns parsed by NumPy's C reader, or None when a line needs the careful
    reader (quotes, another number of fields, a cell that is not a finite number: it says which)."""
    if any('"' in line or line.count(",") != n_fields - 1 for line in block):
        return None
    try:
        values = np.loadtxt(block, delimiter=",", usecols=cols, ndmin=2, dtype=float, comments=None)
    except ValueError:
        return None
    return values if np.isfinite(values).all() else None


def _parse_block(
    path: str | Path,
    block: list[str],
    n_fields: int,
    cols: list[int],
    names: list[str],
    at: int,
    done: int,
    texts: list[str],
) -> np.ndarray:
    """The block's columns parsed row by row with :mod:`csv`, naming the first bad cell."""
    values = array("d")
    try:
        for r, row in enumerate(csv.reader(block), start=done + 1):
            if len(row) != n_fields:
                raise DataError(
                    f"{path}: data row {r} has {len(row)} fields, the header {n_fields}"
                    + _separator_hint(",".join(row), n_fields)
                )
            try:
                numbers = [float(row[c]) for c in cols]
            except ValueError:
                numbers = _not_a_number(path, r, row, cols, names)
            if not all(map(math.isfinite, numbers)):
                k = next(k for k, v in enumerate(numbers) if not math.isfinite(v))
                cell = f"column {names[k]}: {row[cols[k]]}"
                raise DataError(f"{path}: data row {r}, {cell} is not a finite number")
            values.extend(numbers)
            if at >= 0:
                texts.append(row[at].strip())
    except csv.Error as exc:
        raise DataError(f"{path}: malformed CSV ({exc})") from None
    return np.frombuffer(values, dtype=float).reshape(-1, len(cols)).copy()


def _not_a_number(path: str | Path, r: int, row: list[str], cols: list[int], names: list[str]) -> list[float]:
    """Raise the message naming the first cell of row ``r`` that is not a number."""
    for k, c in enumerate(cols):
        try:
            float(row[c])
        except ValueError:
            raise DataError(f"{path}: data row {r}, column {names[k]}: {row[c]!r} is not a number") from None
    return []


def quaternion_columns(path: str | Path, header: Sequence[str], order: str = "wxyz") -> list[str]:
    """The file's quaternion columns in the order w, x, y, z (none when it has none).

    ``wxyz`` reads each of ``qw,qx,qy,qz`` as its name says; ``xyzw`` reads the four, left to
    right as the header has them, as x, y, z, w.

    Raises:
        DataError: some but not all of the four columns (a partial quaternion).
    """
    if order not in QUATERNION_ORDERS:
        raise DataError(f"unknown quaternion order {order!r}: use {' or '.join(QUATERNION_ORDERS)}")
    present = [c for c in header if c in _QUAT]
    if not present:
        return []
    if len(present) < len(_QUAT):
        missing = ", ".join(c for c in _QUAT if c not in present)
        raise DataError(
            f"{path}: the header has {', '.join(present)} but not {missing}: an orientation needs all "
            "four quaternion columns qw,qx,qy,qz; add the missing one(s), or rename or remove the others "
            "for position data"
        )
    if order == "xyzw":
        return [present[3], present[0], present[1], present[2]]
    return list(_QUAT)


def check_locked(path: str | Path, names: Sequence[str], values: np.ndarray, degrees: bool = False) -> None:
    """Refuse a locked joint (``--lock``) whose column moves: it would be held at its neutral
    value while the robot moved it.

    Args:
        path: the data file (for the message).
        names: the locked joints that have a column.
        values: their columns as read (rows, len(names)).
        degrees: the values are degrees (prismatic joints are taken as revolute here).
    """
    for k, name in enumerate(names):
        col = values[:, k]
        span = float(col.max() - col.min()) if len(col) else 0.0
        if (np.deg2rad(span) if degrees else span) > LOCK_TOLERANCE:
            raise DataError(
                f"{path}: locked={name}, but its column moves (from {col.min():.6g} to {col.max():.6g}): "
                f"a locked joint is held at its neutral value, so drop locked={name} to calibrate "
                "with its values"
            )


def unit_quaternions(path: str | Path, quats: np.ndarray) -> np.ndarray:
    """Quaternions (N, 4) scaled to unit length; one of zero length is refused, naming its data row."""
    size = np.abs(quats).max(axis=1, keepdims=True)  # first: a norm overflows on entries of 1e308
    zero = np.flatnonzero(size[:, 0] < 1e-9)
    if zero.size:
        raise DataError(f"{path}: data row {zero[0] + 1}: the quaternion qw,qx,qy,qz is zero, not a rotation")
    scaled = quats / size
    return scaled / np.linalg.norm(scaled, axis=1, keepdims=True)
