"""The allocator settings: applied on glibc, and results never depend on them."""

from __future__ import annotations

import ctypes.util
import os
import platform
import subprocess
import sys

import pytest

from ftsweep.engine import allocator
from ftsweep.engine.case import Case, program_request
from ftsweep.simulate import run_case


@pytest.mark.skipif(platform.system() != "Linux" or not ctypes.util.find_library("c"), reason="glibc only")
def test_tune_applies_on_glibc():
    libc_name, _ = platform.libc_ver()
    if libc_name != "glibc":
        pytest.skip("not glibc")
    assert allocator.tune() is True


def test_results_do_not_depend_on_the_allocator():
    case = Case(surface="sinewave2d", layout=program_request(kind="ring", pitch=(20.0, 5.0)))
    before = run_case(case)
    allocator.tune()
    after = run_case(case)
    for key in ("pv_nm", "rms_nm", "pv_interp_nm", "error_min_nm", "error_max_nm"):
        assert before[key] == after[key], key


def _advice_in_fresh_process(numpy_first: bool, env: dict[str, str]) -> str:
    """numpy's huge-page advice in a fresh interpreter after ``allocator.no_hugepage_advice()``:
    in that process where numpy was imported after it (the command line), or in a process it
    starts that imports numpy itself (a local cluster's worker, which imports numpy before its
    warm-up tunes it)."""
    show = "import numpy; print(numpy._core.multiarray._get_madvise_hugepage())"
    code = "\n".join(
        [
            "import subprocess, sys",
            "from ftsweep.engine import allocator",
            "allocator.no_hugepage_advice()",
            f"subprocess.run([sys.executable, '-c', {show!r}], check=True)" if numpy_first else show,
        ]
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


@pytest.mark.parametrize("numpy_first", [True, False])
def test_tune_stops_numpys_hugepage_advice(numpy_first):
    # see allocator.HUGEPAGE_ENV: first touch of fresh arrays ~5x slower with the advice here
    env = {k: v for k, v in os.environ.items() if k != allocator.HUGEPAGE_ENV}
    assert _advice_in_fresh_process(numpy_first, env) == "False"


@pytest.mark.parametrize("numpy_first", [True, False])
def test_a_users_hugepage_setting_wins(numpy_first):
    env = dict(os.environ, **{allocator.HUGEPAGE_ENV: "1"})
    assert _advice_in_fresh_process(numpy_first, env) == "True"
