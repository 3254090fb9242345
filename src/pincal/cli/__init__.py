"""The ``pincal`` command line: :func:`main` and one module per command.

Exit codes: 0 success; 2 unusable input, with one ``pincal: error: ...`` line on stderr; 1 a bug.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Sequence

from ..errors import PincalError
from .parser import attach_vectors, build_parser

#: The parser (under its former private name, for tests that build it).
_build_parser = build_parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``pincal`` command."""
    try:
        args = build_parser().parse_args(attach_vectors(sys.argv[1:] if argv is None else argv))
        from ..threads import blas_threads

        command = importlib.import_module(f"{__name__}.{args.command}")  # one module per command
        with blas_threads(args.threads):
            return int(command.run(args))
    except PincalError as exc:
        message = " ".join(str(exc).split())
        print(f"pincal: error: {message}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
