"""The ``pincal`` command line: :func:`main` and one module per command.

Exit codes: 0 success, its output printed and its warnings (``pincal: warning: ...``) said at
the end; 2 unusable input, with one ``pincal: error: ...`` line on stderr and nothing else (not
the tables of a result then refused, on stdout); 130 interrupted
(Ctrl-C), with one such line and no partial output; 141 standard output closed early
(``| head``), quietly; 1 a bug.
"""

from __future__ import annotations

import contextlib
import importlib
import io
import os
import signal
import sys
from collections.abc import Sequence

from ..errors import PincalError
from ..files import forget_inputs
from .parser import attach_vectors, build_parser

#: The parser (under its former private name, for tests that build it).
_build_parser = build_parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``pincal`` command."""
    try:
        args = build_parser().parse_args(attach_vectors(sys.argv[1:] if argv is None else argv))
        from ..threads import blas_threads

        command = importlib.import_module(f"{__name__}.{args.command}")  # one module per command
        printed = io.StringIO()  # said when the run ends well: a refused result prints nothing
        with blas_threads(args.threads), contextlib.redirect_stdout(printed):
            code = int(command.run(args))
        sys.stdout.write(printed.getvalue())
        sys.stdout.flush()
        for warning in getattr(args, "warnings", []):  # kept till now: a failing run says one line
            print(f"pincal: warning: {warning}", file=sys.stderr)
        return code
    except PincalError as exc:
        return _error(str(exc), 2)
    except KeyboardInterrupt:
        return _error("interrupted (Ctrl-C): no output was left half-written", 130)
    except MemoryError:
        return _error("out of memory: give fewer poses, candidates or parameters", 2)
    except BrokenPipeError:  # the reader of stdout went away (| head): end quietly, as cat does
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no error at exit's flush
        return 141
    finally:
        if argv is None:  # the process ends now: a late Ctrl-C must not kill it with the signal
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        forget_inputs()


def _error(message: str, code: int) -> int:
    """Print the one ``pincal: error:`` line and return ``code`` (on a terminal, over any progress line)."""
    sys.stdout.flush()
    clear = "\r\033[K" if sys.stderr.isatty() else ""
    message = " ".join(message.split())
    print(f"{clear}pincal: error: {message}", file=sys.stderr)
    return code


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
