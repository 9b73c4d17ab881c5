"""Code quality gates that CI runs with the tests: ruff (lint, import order, complexity ≤ 10
in pipeline/) over the project, mypy with every function of pipeline/ typed, and the size of
pipeline/'s modules and functions."""

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
def test_mypy_every_pipeline_function_typed():
    out = subprocess.run(
        [_tool("mypy"), "--disallow-untyped-defs", "--no-error-summary", "pipeline"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stdout + out.stderr


MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 60


def test_pipeline_modules_and_functions_stay_small():
    """Modules by responsibility: no module of pipeline/ over 600 lines, no function
    over 60 (its ``def`` line to its last, docstring included)."""
    import ast

    too_long = []
    for path in sorted((REPO / "pipeline").rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        if len(text.splitlines()) > MAX_MODULE_LINES:
            too_long.append(f"{path.name}: {len(text.splitlines())} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = (node.end_lineno or node.lineno) - node.lineno + 1
                if length > MAX_FUNCTION_LINES:
                    too_long.append(f"{path.name}:{node.lineno} {node.name}: {length} lines")
    assert not too_long, too_long
