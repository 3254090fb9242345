"""No import circle among pincal's modules (issue 32): the layers point only down.

The graph is grimp's, imports inside functions and under ``if TYPE_CHECKING:`` included: no
annotation points up either (a calibration's records live in :mod:`pincal.identify.records` below it;
the kinds, the fixed points and the blocks of large data take a problem as the protocol of
:mod:`pincal.identify.rows`). A cycle is a strongly connected component of more than one module. The
layer order itself is the import-linter contract of pyproject.toml (``lint-imports``), which
ignores no import.
"""

from __future__ import annotations

from pathlib import Path

import pytest

grimp = pytest.importorskip("grimp")

ROOT = Path(__file__).resolve().parents[1]


def cycles(graph: grimp.ImportGraph) -> list[list[str]]:
    """The strongly connected components of more than one module, each sorted (Tarjan's, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    for root in sorted(graph.modules):
        if root in index:
            continue
        work = [(root, iter(sorted(graph.find_modules_directly_imported_by(root))))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.find_modules_directly_imported_by(child)))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def _edges(graph: grimp.ImportGraph, component: list[str]) -> list[str]:
    inside, out = set(component), []
    for a in component:
        for b in sorted(graph.find_modules_directly_imported_by(a) & inside):
            lines = ", ".join(str(d["line_number"]) for d in graph.get_import_details(importer=a, imported=b))
            out.append(f"{a} -> {b} (line {lines})")
    return out


def test_no_import_cycle() -> None:
    """grimp's graph of pincal, function-level and type-checking imports included, has no cycle."""
    graph = grimp.build_graph("pincal", cache_dir=None)
    found = cycles(graph)
    assert not found, "\n".join(
        f"cycle of {len(c)} modules:\n  " + "\n  ".join(_edges(graph, c)) for c in found
    )


def test_the_contract_ignores_no_import() -> None:
    """pyproject.toml's import-linter contract makes no exception."""
    tomllib = pytest.importorskip("tomllib")  # Python 3.11
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    assert not [s for c in config["contracts"] for s in c.get("ignore_imports", ())]


def test_the_contract_passes() -> None:
    """``lint-imports`` (as CI runs it) keeps every module in its layer."""
    cli = pytest.importorskip("importlinter.cli")
    code = cli.lint_imports(config_filename=str(ROOT / "pyproject.toml"), no_cache=True, no_logo=True)
    assert code == 0


def test_no_self_import() -> None:
    """No module imports itself (``from . import this_module`` inside a function)."""
    graph = grimp.build_graph("pincal", cache_dir=None)
    selfish = [m for m in sorted(graph.modules) if m in graph.find_modules_directly_imported_by(m)]
    assert not selfish, selfish
