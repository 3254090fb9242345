"""Running ``pincal`` in-process in tests: its exit code and what it printed."""

from __future__ import annotations

from pathlib import Path

import pytest

from pincal.cli import main


def run(capsys: pytest.CaptureFixture[str], *args: str | Path) -> tuple[int, str, str]:
    """Run the command line on ``args``: exit code, stdout, stderr."""
    capsys.readouterr()
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def one_error_line(capsys: pytest.CaptureFixture[str], *args: str | Path) -> str:
    """Run the command; expect exit 2 and exactly one ``pincal: error:`` line; return it."""
    code, _, err = run(capsys, *args)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pincal: error: "), err
    return lines[0]
