"""The Markdown a benchmark writes for the documentation's results pages (``--markdown PATH``).

A results page (``docs/results/NAME.md``, written by hand: what was measured and why) includes
the file a benchmark writes (``docs/results/generated/NAME.md``: the figures, and the command that
produced them), so that running the command again refreshes the figures and nothing else.
"""

from __future__ import annotations

import datetime
import io
import json
import os
import sys
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import pincal
from pincal.files import atomic_write


def command_line(script: str, argv: Sequence[str], names: dict[str, str]) -> str:
    """The command as a reader runs it from the repository root: each argument in ``names``
    written as its name (the datasets folder as ``DATASETS_DIR``: no path of this machine), the
    ``--json FILE`` that only saves a copy left out, every other argument as given."""
    args: list[str] = []
    for arg in argv:
        if args and args[-1] == "--json":
            args.pop()
            continue
        args.append(names.get(arg.rstrip("/"), arg))
    return " ".join(["python", f"benchmarks/{script}", *args])


def write_page(path: Path, command: str, sections: Sequence[str]) -> None:
    """Write ``sections`` (Markdown) under a line naming the command, pincal's version, the date
    and the machine's cores; atomically."""
    when = datetime.date.today().isoformat()
    head = [
        "<!-- Written by a benchmark script: edit the script, then run the command below again. -->",
        "",
        f"Produced by `{command}` (pincal {pincal.__version__}, {when}, {os.cpu_count()} cores, "
        "one BLAS thread).",
        "",
    ]
    atomic_write(path, "\n".join([*head, *sections]).rstrip() + "\n")


def table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)


class Tee(io.StringIO):
    """Standard output kept as well as printed (``contextlib.redirect_stdout(Tee(sys.stdout))``):
    a benchmark's page is then what it printed."""

    def __init__(self, out: Any) -> None:
        super().__init__()
        self.out = out

    def write(self, text: str) -> int:
        self.out.write(text)
        return super().write(text)


def text_block(text: str) -> str:
    """Text printed by the script, shown as it is."""
    return "```text\n" + text.rstrip() + "\n```"


def publish(
    script: str,
    argv: Sequence[str] | None,
    text: str,
    sessions: Sequence[Any],
    json_path: Path | None,
    md_path: Path | None,
) -> None:
    """Print a sessions benchmark's table ``text``, save its sessions (dataclasses) as JSON when
    asked, and write its page when asked, naming the command as it was run (``argv`` None: this
    process's own arguments)."""
    print(text)
    if json_path:
        json_path.write_text(json.dumps([asdict(s) for s in sessions], indent=1))
    if md_path:
        given = sys.argv[1:] if argv is None else argv
        write_page(md_path, command_line(script, given, {}), [text])
