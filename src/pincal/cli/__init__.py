"""The ``pincal`` command line: :func:`main` and one module per command.

Exit codes: 0 success; 2 unusable input, with one ``pincal: error: ...`` line on stderr; 1 a bug.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

from ..errors import PincalError
from . import calibrate, compensate, demo, diagnose, plan, tcp, twists
from .parser import attach_vectors, build_parser

_COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {
    "calibrate": calibrate.run,
    "diagnose": diagnose.run,
    "tcp": tcp.run,
    "twists": twists.run,
    "compensate": compensate.run,
    "plan": plan.run,
    "demo": demo.run,
}

#: The parser (under its former private name, for tests that build it).
_build_parser = build_parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``pincal`` command."""
    try:
        args = build_parser().parse_args(attach_vectors(sys.argv[1:] if argv is None else argv))
        return _COMMANDS[args.command](args)
    except PincalError as exc:
        message = " ".join(str(exc).split())
        print(f"pincal: error: {message}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
