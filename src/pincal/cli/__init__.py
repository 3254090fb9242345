"""The ``pincal`` command line: :func:`main` and one module per command.

Exit codes: 0 success, its output printed and its warnings (``pincal: warning: ...``) said at
the end; 2 unusable input, with one ``pincal: error: ...`` line on stderr and nothing else (not
the tables of a result then refused, on stdout), and a standard output closed before the run
(``>&-``); 130 interrupted (Ctrl-C) and 143 terminated (SIGTERM), with one such line and no
partial output; 141 standard output closed early by its reader (``| head``), quietly; 1 a bug,
said in one ``pincal: bug: ...`` line (the traceback with ``PINCAL_TRACEBACK=1``). A closed
standard error never makes a run fail: its lines are dropped. Every output file is written whole
or not at all (:mod:`pincal.files`).
"""

from __future__ import annotations

import contextlib
import errno
import importlib
import io
import os
import signal
import sys
import traceback
from collections.abc import Iterator, Sequence
from types import FrameType

from pincal.cli import blas_start  # noqa: F401  (first: BLAS loads with the command's threads)
from pincal.cli.flags import as_flags
from pincal.cli.parser import build_parser
from pincal.cli.values import attach_vectors
from pincal.errors import PincalError
from pincal.files import forget_inputs
from pincal.inputs import run_scope
from pincal.memory import keep_freed_memory

#: The parser (under its former private name, for tests that build it).
_build_parser = build_parser


class Terminated(BaseException):
    """SIGTERM arrived: unwound like Ctrl-C, so that no temporary file stays behind."""


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``pincal`` command."""
    keep_freed_memory()
    closed = _reserve_closed_channels()
    if closed[1]:  # before the run: a broken pipe later is quiet, a channel closed on purpose is said
        return _error(
            "standard output is closed (>&-): pincal prints its results there; redirect it to a file, "
            "or to /dev/null to drop them (> /dev/null), instead of closing it",
            2,
        )
    with _terminate_unwinds():
        try:
            with run_scope():  # no output of the run may be one of its inputs
                return _run(argv, stdout_closed=closed[1])
        except PincalError as exc:
            return _error(as_flags(str(exc)), 2)
        except KeyboardInterrupt:
            return _error("interrupted (Ctrl-C): no output was left half-written", 130)
        except Terminated:
            return _error("terminated (SIGTERM): no output was left half-written", 143)
        except MemoryError:
            return _error("out of memory: give fewer poses, candidates or parameters", 2)
        except _StdoutGone:
            return _quiet_stdout()
        except OSError as exc:
            if exc.errno == errno.EPIPE:
                return _quiet_stdout()
            return _error(f"cannot write standard output: {exc.strerror or exc}", 2)
        except Exception as exc:  # noqa: BLE001 (a bug: one line that says so, not a traceback)
            return _bug(exc)
        finally:
            if argv is None:  # the process ends now: a late Ctrl-C must not kill it with the signal
                signal.signal(signal.SIGINT, signal.SIG_IGN)
            forget_inputs()


class _StdoutGone(Exception):
    """Standard output is closed (``>&-``) or its reader went away."""


def _reserve_closed_channels() -> dict[int, bool]:
    """Open the null device on file descriptors 1 and 2 when they are closed (``>&-``, ``2>&-``):
    else the next file opened (an output's temporary file) would get the number, and what C code
    prints would land in it. Returns which were closed."""
    closed = {}
    for fd, name in ((1, "stdout"), (2, "stderr")):
        try:
            os.fstat(fd)
            closed[fd] = getattr(sys, name) is None
        except OSError:
            closed[fd] = True
            null = os.open(os.devnull, os.O_WRONLY)
            if null != fd:
                os.dup2(null, fd)
                os.close(null)
        if closed[fd] and getattr(sys, name) is None:
            setattr(sys, name, open(fd, "w", encoding="utf-8", closefd=False))  # noqa: SIM115
    return closed


def _run(argv: Sequence[str] | None, stdout_closed: bool = False) -> int:
    """Parse, run the command with its printed text held back, then print it and the warnings."""
    args = build_parser().parse_args(attach_vectors(sys.argv[1:] if argv is None else argv))
    from pincal.threads import blas_threads
    from pincal.workers import kept_workers

    command = importlib.import_module(f"{__name__}.{args.command}")  # one module per command
    printed = io.StringIO()  # said when the run ends well: a refused result prints nothing
    with blas_threads(args.threads), kept_workers(), contextlib.redirect_stdout(printed):
        code = int(command.run(args))
    stdout = sys.stdout
    if stdout is None or stdout_closed:
        raise _StdoutGone
    try:
        stdout.write(printed.getvalue())
        stdout.flush()
    except (BrokenPipeError, ValueError):  # ValueError: the stream was closed
        raise _StdoutGone from None
    for warning in getattr(args, "warnings", []):  # kept till now: a failing run says one line
        _say(f"pincal: warning: {as_flags(warning)}")
    return code


def _quiet_stdout() -> int:
    """End quietly, as ``cat`` does when its reader goes away (no error at exit's flush)."""
    with contextlib.suppress(OSError, ValueError):
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 1)
        os.close(null)
    if sys.stdout is None or sys.stdout.closed:
        sys.stdout = open(os.devnull, "w", encoding="utf-8")  # noqa: SIM115 (lives till exit)
    return 141


def _error(message: str, code: int) -> int:
    """Print the one ``pincal: error:`` line and return ``code`` (on a terminal, over any progress line)."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        sys.stdout.flush()
    tty = sys.stderr is not None and not sys.stderr.closed and sys.stderr.isatty()
    message = " ".join(message.split())
    _say(f"{chr(13) + chr(27) + '[K' if tty else ''}pincal: error: {message}")
    return code


def _bug(exc: Exception) -> int:
    """One line saying that this is a bug (the traceback too, with ``PINCAL_TRACEBACK=1``)."""
    if os.environ.get("PINCAL_TRACEBACK"):
        _say("".join(traceback.format_exception(exc)).rstrip())
    frames = traceback.extract_tb(exc.__traceback__)
    at = f" at {os.path.basename(frames[-1].filename)}:{frames[-1].lineno}" if frames else ""
    what = " ".join(f"{type(exc).__name__}: {exc}".split())
    _say(f"pincal: bug: {what}{at} (an internal error, not your input: please report it with the command)")
    return 1


def _say(line: str) -> None:
    """Print a line on standard error; a closed or broken one drops it (never a second failure)."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        print(line, file=sys.stderr, flush=True)


@contextlib.contextmanager
def _terminate_unwinds() -> Iterator[None]:
    """SIGTERM raises :class:`Terminated` in the main thread for the block (Python's default
    would end the process at once, leaving a temporary file of a write in progress)."""
    if sys.modules["threading"].current_thread() is not sys.modules["threading"].main_thread():
        yield
        return

    def stop(_signum: int, _frame: FrameType | None) -> None:
        raise Terminated

    before = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, before)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
