"""Code quality gates that CI runs with the tests: ruff (lint, import order, complexity ≤ 10
in pipeline/) over the project and mypy with every function of pipeline/ typed."""

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


def test_mypy_every_pipeline_function_typed():
    out = subprocess.run(
        [_tool("mypy"), "--disallow-untyped-defs", "--no-error-summary", "pipeline"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stdout + out.stderr
