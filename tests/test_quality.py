"""Code quality gates that CI runs with the tests, the same for pipeline/ and stages/: ruff
(lint, import order, complexity ≤ 10), mypy with every function typed, the size of modules
and functions, and an import graph without a circle."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
BIN = Path(sys.executable).parent


def _tool(name: str) -> str:
    exe = BIN / name
    if not exe.exists():
        pytest.fail(f"{name} is not installed beside the test interpreter; install the [test] extra")
    return str(exe)


def test_ruff_lint_and_complexity():
    out = subprocess.run(
        [_tool("ruff"), "check", "pipeline", "stages", "tests"], cwd=REPO, capture_output=True, text=True
    )
    assert out.returncode == 0, out.stdout + out.stderr


@pytest.mark.integration  # mypy over the package
def test_mypy_every_function_typed():
    out = subprocess.run(
        [_tool("mypy"), "--disallow-untyped-defs", "--no-error-summary", "pipeline", "stages"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stdout + out.stderr


MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 60


def test_modules_and_functions_stay_small():
    """Modules by responsibility: no module of pipeline/ or stages/ over 600 lines, no
    function over 60 (its ``def`` line to its last, docstring included)."""
    import ast

    too_long = []
    for path in sorted([*(REPO / "pipeline").rglob("*.py"), *(REPO / "stages").rglob("*.py")]):
        text = path.read_text(encoding="utf-8")
        if len(text.splitlines()) > MAX_MODULE_LINES:
            too_long.append(f"{path.name}: {len(text.splitlines())} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = (node.end_lineno or node.lineno) - node.lineno + 1
                if length > MAX_FUNCTION_LINES:
                    too_long.append(f"{path.name}:{node.lineno} {node.name}: {length} lines")
    assert not too_long, too_long


def _module_names() -> dict[str, Path]:
    """Every module of the package by its import name (``pipeline/`` is ``ftsweep``,
    ``stages/`` is ``ftsweep.stages``)."""
    names = {}
    for root, base in (("pipeline", "ftsweep"), ("stages", "ftsweep.stages")):
        for path in (REPO / root).rglob("*.py"):
            parts = list(path.relative_to(REPO / root).with_suffix("").parts)
            names[".".join([base, *(parts[:-1] if parts[-1] == "__init__" else parts)])] = path
    return names


def _imports(name: str, path: Path, known: dict[str, Path]) -> set[str]:
    """The package's modules ``name`` imports anywhere in its text (inside functions too,
    where a lazy import would hide a circle from a run-time check)."""
    import ast

    package = name.split(".") if path.stem == "__init__" else name.split(".")[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package[: len(package) - node.level + 1] + ([base] if base else []))
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]
        else:
            continue
        for target in targets:
            while target and target not in known:
                target = target.rpartition(".")[0]
            if target and target != name:
                found.add(target)
    return found


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
            low[v] = min(low[v], low[w] if w in stack or w not in index else low[v])
        if low[v] == index[v]:
            component = stack[stack.index(v) :]
            del stack[stack.index(v) :]
            if len(component) > 1:
                circles.append(sorted(component))

    for name in graph:
        if name not in index:
            visit(name)
    return circles


def test_no_circle_of_imports():
    """The import graph of ftsweep's modules has no circle, counting the imports inside
    functions; the registry reaches the kinds through entry points, which are not imports."""
    known = _module_names()
    graph = {name: _imports(name, path, known) for name, path in known.items()}
    assert len(graph) > 50 and sum(map(len, graph.values())) > 200  # the walk did find the imports
    assert not _circles(graph)


def test_the_circle_finder_finds_a_circle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert _circles(graph) == [["a", "b", "c"]]
    assert _circles({"a": {"b"}, "b": set()}) == []


def test_the_engine_names_no_kind():
    """The engine and the generic layers import no kind's module: a kind is handed to the
    engine, and found by the registry for the layers above it."""
    known = _module_names()
    generic = ("ftsweep.engine", "ftsweep.store", "ftsweep.sweeps", "ftsweep.registry", "ftsweep.simulate")
    offenders = {
        name: sorted(t for t in _imports(name, path, known) if t.startswith("ftsweep.kinds"))
        for name, path in known.items()
        if name.startswith(generic)
    }
    assert not {k: v for k, v in offenders.items() if v}
