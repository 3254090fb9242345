"""The inputs of a run: read bounded, from regular files only, and remembered for the output guard.

Every file a command reads passes through :func:`read_bytes`: the measurement CSVs, the URDF and
the files a xacro includes, the sidecar, a ``--kinematics`` YAML, a ``--params @FILE`` list and
MUKCa's socket files. It

- refuses a folder, a device (``/dev/zero``, a terminal) or a socket before reading a byte, and
  a named pipe unless the caller reads streams (a measurement CSV may come through a pipe), and
  then only one whose writer is there within :data:`PIPE_WAIT_SECONDS`;
- reads at most ``limit`` bytes, and refuses a larger file with one line;
- remembers the file (its resolved path and its inode) as an input of the run.

:func:`input_named` tells the output guard (:func:`pincal.files.atomic_write_many` and the
command line's early check) whether a path about to be written is one of the run's inputs: no
command ever replaces one of its inputs, ``--force`` or not. Files are remembered only within
:func:`run_scope` (the command line opens one for each command): a program that uses the library
may rewrite a file it read before.
"""

from __future__ import annotations

import os
import select
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from pincal.errors import DataError, PincalError

#: Longest wait for the writer of a named pipe given as an input [s].
PIPE_WAIT_SECONDS = 5.0
_READ_CHUNK = 1 << 20  # [bytes]

_inputs: dict[str, str] = {}  # resolved path -> what it is ("data file", ...)
_inodes: dict[tuple[int, int], str] = {}  # (device, inode) -> what it is
_scope: list[bool] = []  # non-empty within run_scope


@contextmanager
def run_scope() -> Iterator[None]:
    """The inputs read in the block are the run's: outputs written in it must not be one of them."""
    forget_run_inputs()
    _scope.append(True)
    try:
        yield
    finally:
        _scope.pop()
        forget_run_inputs()


def note_input(path: str | Path, what: str) -> None:
    """Remember ``path`` as an input of the run (a file that does not exist is not remembered)."""
    name = str(path)
    if name == "-" or not _scope:
        return
    try:
        info = os.stat(name)
    except OSError:
        return
    if stat.S_ISREG(info.st_mode):
        _inputs.setdefault(os.path.realpath(name), what)
        _inodes.setdefault((info.st_dev, info.st_ino), what)


def note_standard_input(what: str) -> None:
    """Remember the file standard input reads (``- < data.csv``) as an input of the run: an output
    named after it would replace the data being read. A pipe or a terminal is no file to protect."""
    if not _scope:
        return
    try:
        info = os.fstat(0)
    except OSError:
        return
    if stat.S_ISREG(info.st_mode):
        _inodes.setdefault((info.st_dev, info.st_ino), f"{what} (standard input)")


def input_named(path: str | Path) -> str | None:
    """What the run read from ``path`` ("data file", ...), or None when it is no input of the run
    (symlinks and hard links resolved)."""
    target = os.path.realpath(path)
    if target in _inputs:
        return _inputs[target]
    try:
        info = os.stat(target)
    except OSError:
        return None
    return _inodes.get((info.st_dev, info.st_ino))


def forget_run_inputs() -> None:
    """Forget the run's inputs (the command line does it when a command ends)."""
    _inputs.clear()
    _inodes.clear()


def read_bytes(
    path: str | Path,
    what: str,
    limit: int,
    *,
    pipes: bool = False,
    error: type[PincalError] = DataError,
) -> bytes:
    """The bytes of an input file, at most ``limit`` of them (see the module docstring).

    Args:
        path: the file.
        what: how to name it in messages ("data file", "sidecar", ...).
        limit: the largest size read [bytes].
        pipes: a named pipe is accepted (read once: the caller keeps the bytes).
        error: the exception raised.

    Raises:
        PincalError: ``error``: missing, a folder, a device or socket (a pipe without ``pipes``),
            a pipe without a writer, unreadable, or larger than ``limit``.
    """
    mode = _mode(path, what, error)
    fifo = stat.S_ISFIFO(mode)
    if not (stat.S_ISREG(mode) or (fifo and pipes)):
        raise error(
            f"{what} {path} is {_kind(mode)}, not a regular file: give a file (a device or a pipe "
            f"may be larger than {_size(limit)}, the most pincal reads, or never end)"
        )
    try:
        fd = os.open(str(path), os.O_RDONLY | (os.O_NONBLOCK if fifo else 0))
    except OSError as exc:
        raise error(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    try:
        if fifo:
            _wait_for_writer(fd, path, what, error)
        elif not stat.S_ISREG(os.fstat(fd).st_mode):  # replaced since the check
            raise error(f"{what} {path} is no longer a regular file: give a file")
        data = _read_at_most(fd, limit + 1)
    except OSError as exc:
        raise error(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    finally:
        os.close(fd)
    if len(data) > limit:
        raise error(f"{what} {path} is larger than {_size(limit)}: is it the right file?")
    note_input(path, what)
    return data


def _mode(path: str | Path, what: str, error: type[PincalError]) -> int:
    try:
        mode = os.stat(str(path)).st_mode
    except FileNotFoundError:
        raise error(f"{what} not found: {path}") from None
    except OSError as exc:
        raise error(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(mode):
        raise error(f"{what} {path} is a folder: give a file")
    return mode


def _kind(mode: int) -> str:
    if stat.S_ISFIFO(mode):
        return "a named pipe"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "a device"


def _size(limit: int) -> str:
    return f"{limit / 1e6:g} MB" if limit >= 1_000_000 else f"{limit} bytes"


def _wait_for_writer(fd: int, path: str | Path, what: str, error: type[PincalError]) -> None:
    """Wait for a pipe's first bytes (or its writer's end) at most :data:`PIPE_WAIT_SECONDS`, then
    read it blocking (a pipe nobody writes to would otherwise hang the run for ever)."""
    poll = select.poll()
    poll.register(fd, select.POLLIN | select.POLLHUP)
    if not poll.poll(PIPE_WAIT_SECONDS * 1000):
        raise error(
            f"{what} {path} is a named pipe nobody wrote to within {PIPE_WAIT_SECONDS:g} s: "
            "give a file, or start the writer first"
        )
    os.set_blocking(fd, True)


def _read_at_most(fd: int, size: int) -> bytes:
    """Up to ``size`` bytes (fewer at the end of the file)."""
    parts, left = [], size
    while left > 0:
        part = os.read(fd, min(left, _READ_CHUNK))
        if not part:
            break
        parts.append(part)
        left -= len(part)
    return b"".join(parts)
