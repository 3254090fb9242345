"""The code stays lint- and type-clean: ``ruff check`` and ``mypy`` (configured in pyproject.toml)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    "command",
    [[sys.executable, "-m", "ruff", "check", "."], [sys.executable, "-m", "mypy"]],
    ids=["ruff", "mypy"],
)
def test_clean(command: list[str]) -> None:
    """Each checker exits 0 on the whole project."""
    result = subprocess.run(command, capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 0, result.stdout + result.stderr


#: Most lines a module of src/ may have, and a function (its ``def`` line to its last line).
MAX_MODULE_LINES, MAX_FUNCTION_LINES = 350, 80


def test_modules_and_functions_stay_small() -> None:
    """One concept per module and functions a reader can hold: no module over 350 lines, no
    function over 80."""
    import ast

    too_long = []
    for path in sorted((ROOT / "src" / "pincal").rglob("*.py")):
        text = path.read_text()
        if len(text.splitlines()) > MAX_MODULE_LINES:
            too_long.append(f"{path.name}: {len(text.splitlines())} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                size = (node.end_lineno or node.lineno) - node.lineno + 1
                if size > MAX_FUNCTION_LINES:
                    too_long.append(f"{path.name}: {node.name} {size} lines")
    assert not too_long, too_long
