"""Input and output files: inputs read once, outputs written whole or not at all.

Inputs (:func:`read_input_text`): ``-`` is standard input; standard input, a named pipe or
``/dev/stdin`` can be read only once, so their text is kept and every later read of the same
name in the process gets it (a CSV's header is read before its table). Anything larger than
:data:`MAX_INPUT_BYTES` is refused (``/dev/zero`` would never end).

Outputs (:func:`atomic_write`, :func:`atomic_write_many`): only regular files are written. A
symlink is written through (its target is replaced, the link stays); a folder, a device, a named
pipe or a socket is refused, and so is a file the run reads (:mod:`pincal.inputs`: the data,
the URDF and its xacro includes, a ``@FILE`` list, a sidecar, ``--force`` or not). Each text
goes to an unnamed file in its target's folder (``O_TMPFILE``; where the file system has none,
a ``.pincal-*.tmp`` file removed on every way out), and only when every one is complete are they
named over their targets (Ctrl-C and SIGTERM held back during the renames), so a full disk, a
folder that refuses the file, Ctrl-C or a kill leave the old files (or none) and no partial or
temporary one, nor a new file beside an old one. The temporary name is short, so a target may
have the longest name the file system allows. A new file gets the usual permissions (0666 less
the process umask), a replaced one keeps its own.
"""

from __future__ import annotations

import errno
import os
import signal
import stat
import sys
import tempfile
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from pincal.errors import DataError, OutputError
from pincal.inputs import forget_run_inputs, input_named, note_input, note_standard_input, read_bytes

#: Largest input file read [bytes] (a measurement CSV of a million poses is about 100 MB).
MAX_INPUT_BYTES = 500_000_000
#: The name of standard input.
STDIN = "-"

_read_once: dict[str, str] = {}


def read_input_text(path: str | Path, what: str = "data file") -> str:
    """The text of an input (UTF-8, a byte-order mark dropped); ``-`` is standard input.

    Args:
        path: the file, ``-``, ``/dev/stdin`` or a named pipe.
        what: how to name the input in messages.

    Raises:
        DataError: missing, unreadable, not UTF-8, too large, a device, a pipe nobody writes
            to, or a terminal as standard input.
    """
    name = str(path)
    if name in _read_once:
        return _read_once[name]
    if name == STDIN:
        data, once = _read_stdin(what), True
    else:
        once = not os.path.isfile(name)  # a pipe is read once: its text is kept
        data = read_bytes(name, what, MAX_INPUT_BYTES, pipes=True)
    if len(data) > MAX_INPUT_BYTES:
        raise DataError(f"{what} {path} is larger than {MAX_INPUT_BYTES // 1_000_000} MB: is it a CSV?")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DataError(
            f"cannot read {what} {path}: not UTF-8 text ({exc.reason} at byte {exc.start})"
        ) from None
    if once:
        _read_once[name] = text
    return text


#: Longest line :func:`first_line` reads from a regular file before reading the file whole [chars].
MAX_HEADER_CHARS = 1_000_000


def is_content(line: str) -> bool:
    """True for a line of a data file that is neither blank nor a ``#`` comment."""
    return bool(line.strip()) and not line.lstrip().startswith("#")


def first_line(path: str | Path, what: str = "data file") -> str | None:
    """The first line that is neither blank nor a ``#`` comment, or None when there is none.

    A regular file is read only up to that line (a header is read before the table, and a
    100 MB CSV is not read whole for it); standard input, a pipe, or a file that is not UTF-8
    text or has a very long line is read whole by :func:`read_input_text` (kept for the next
    read, and refused with its message).
    """
    name = str(path)
    regular = name != STDIN and name not in _read_once and os.path.isfile(name)
    if regular and stat.S_ISREG(os.stat(name).st_mode):
        note_input(name, what)
        try:
            with open(name, encoding="utf-8-sig") as fh:
                while line := fh.readline(MAX_HEADER_CHARS):
                    if len(line) >= MAX_HEADER_CHARS:
                        break
                    for part in line.splitlines():  # the separators str.splitlines knows
                        if is_content(part):
                            return part
                else:
                    return None
        except (OSError, UnicodeDecodeError):
            pass  # read whole below, for the one message of every input
    return next(filter(is_content, read_input_text(path, what).splitlines()), None)


def _read_stdin(what: str) -> bytes:
    stream = sys.stdin
    if stream is None:
        raise DataError(f"the {what} is '-' but there is no standard input")
    if stream.isatty():
        raise DataError(
            f"the {what} is '-' (standard input), a terminal: pipe the CSV in, e.g. '- < data.csv'"
        )
    note_standard_input(what)
    buffer = getattr(stream, "buffer", None)
    if buffer is not None:
        return bytes(buffer.read(MAX_INPUT_BYTES + 1))
    return stream.read(MAX_INPUT_BYTES + 1).encode("utf-8")


def kept_inputs() -> frozenset[str]:
    """The names of the inputs read once whose text is kept (standard input, pipes)."""
    return frozenset(_read_once)


def forget_inputs() -> None:
    """Drop the kept texts of inputs read once (the command line does it when a command ends)."""
    _read_once.clear()
    forget_run_inputs()


def output_target(path: str | Path) -> Path:
    """The regular file an output path writes: symlinks followed, anything else refused.

    Raises:
        OutputError: ``-``, a folder, or a device, named pipe or socket.
    """
    if str(path) == STDIN:
        raise OutputError("'-' as an output: give a file name (pincal writes outputs to files, not stdout)")
    target = Path(os.path.realpath(path))
    try:
        mode = target.stat().st_mode
    except FileNotFoundError:
        return target
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(mode):
        raise OutputError(f"{path} is a folder: give a file name for the output")
    if not stat.S_ISREG(mode):
        raise OutputError(
            f"{path} is not a regular file (a device, a named pipe or a socket): pincal writes outputs "
            "only to regular files, give a file name"
        )
    return target


def atomic_write(path: str | Path, text: str | bytes) -> None:
    """Write ``text`` (UTF-8) or bytes to ``path`` atomically (see the module docstring).

    Raises:
        OutputError: not a regular file, or the file cannot be written (permissions, full disk).
    """
    atomic_write_many([(path, text)])


def atomic_write_many(files: Sequence[tuple[str | Path, str | bytes]]) -> None:
    """Write several files, all or none: each to an unnamed file in its folder, then every one
    given its name at once (see the module docstring).

    Raises:
        OutputError: an output that is an input of the run, is not a regular file, or cannot be
            written.
    """
    staged: list[_Staged] = []
    current: str | Path = ""
    try:
        for current, text in files:
            target = output_target(current)
            source = input_named(target)
            if source is not None:
                raise OutputError(f"{current} is the {source} this run reads: write to another file")
            staged.append(_Staged(target))
            staged[-1].write(text.encode("utf-8") if isinstance(text, str) else text)
        with _interrupts_held():  # a Ctrl-C between two renames would leave old and new side by side
            for one in staged:
                one.commit()
    except OSError as exc:
        raise OutputError(f"cannot write {current}: {exc.strerror or exc}{_hint(exc)}") from None
    finally:
        for one in staged:
            one.discard()


class _Staged:
    """One output's bytes written, not yet named: an ``O_TMPFILE`` (no name in any folder until
    :meth:`commit`), or where the system has none a ``.pincal-*.tmp`` file beside the target,
    removed by :meth:`discard` on every way out."""

    def __init__(self, target: Path) -> None:
        self.target, self.name, self.data = target, "", b""
        try:
            self.fd = os.open(target.parent, os.O_TMPFILE | os.O_WRONLY | os.O_CLOEXEC, 0o600)
        except (AttributeError, OSError) as exc:
            if isinstance(exc, OSError) and exc.errno not in _NO_TMPFILE:
                raise
            self.fd, self.name = tempfile.mkstemp(dir=target.parent, prefix=".pincal-", suffix=".tmp")

    def write(self, data: bytes) -> None:
        """Write every byte, with the permissions the target will have."""
        self.data = data
        os.fchmod(self.fd, _mode(self.target))
        _write_all(self.fd, data)

    def commit(self) -> None:
        """Give the file its name (replacing the old file), through a short temporary name."""
        if not self.name:
            self.name = self._link()
        os.close(self.fd)
        self.fd = -1
        os.replace(self.name, self.target)
        self.name = ""

    def _link(self) -> str:
        folder = os.open(self.target.parent, os.O_RDONLY | os.O_DIRECTORY)
        try:
            for _ in range(100):
                name = self._free_name()
                try:  # linkat with AT_SYMLINK_FOLLOW (a dir_fd makes Python use linkat)
                    os.link(f"/proc/self/fd/{self.fd}", Path(name).name, src_dir_fd=folder, dst_dir_fd=folder)
                    return name
                except FileExistsError:
                    continue
                except OSError:  # no /proc, or a file system that cannot name an unnamed file
                    break
        finally:
            os.close(folder)
        os.close(self.fd)
        self.fd, name = tempfile.mkstemp(dir=self.target.parent, prefix=".pincal-", suffix=".tmp")
        self.name = name
        self.write(self.data)
        return name

    def _free_name(self) -> str:
        """A temporary name no file has, in the target's folder (taken by ``mkstemp``, then freed)."""
        fd, name = tempfile.mkstemp(dir=self.target.parent, prefix=".pincal-", suffix=".tmp")
        os.close(fd)
        os.unlink(name)
        return name

    def discard(self) -> None:
        """Close and remove what :meth:`commit` did not name."""
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1
        if self.name:
            Path(self.name).unlink(missing_ok=True)
            self.name = ""


#: ``errno`` of a folder whose file system has no ``O_TMPFILE``.
_NO_TMPFILE = (errno.EOPNOTSUPP, errno.EISDIR, errno.EINVAL, errno.ENOENT)


@contextmanager
def _interrupts_held() -> Iterator[None]:
    """Hold SIGINT and SIGTERM back for the block: one that arrives in it is raised again when it
    ends, with the handler it would have met (a signal mask would not do: the kernel gives a
    process's signal to any thread that does not block it, BLAS's own threads included)."""
    if threading.current_thread() is not threading.main_thread():
        yield  # handlers can only be set in the main thread, where the interruption would land
        return
    arrived: list[int] = []
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    handlers = {s: h for s, h in handlers.items() if h is not None}  # None: not Python's to set
    for number in handlers:
        signal.signal(number, lambda signum, _frame: arrived.append(signum))
    try:
        yield
    finally:
        for number, handler in handlers.items():
            signal.signal(number, handler)
        if arrived:
            signal.raise_signal(arrived[0])


def _write_all(fd: int, data: bytes) -> None:
    """Write every byte (``os.write`` may write fewer than asked)."""
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]


def _mode(target: Path) -> int:
    """Permissions of a replaced file, else 0666 less the umask."""
    try:
        return stat.S_IMODE(target.stat().st_mode)
    except OSError:
        mask = os.umask(0o022)  # the umask can only be read by setting it: set it back at once
        os.umask(mask)
        return 0o666 & ~mask


def _hint(exc: OSError) -> str:
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return ": free some space, or write to another disk"
    if exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        return ": write to a folder you can write to"
    return ""
