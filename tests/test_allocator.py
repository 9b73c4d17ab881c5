"""The allocator settings (issue 10): applied on glibc, and results never depend on them."""

from __future__ import annotations

import ctypes.util
import platform

import pytest

from ftsweep import allocator
from ftsweep.case import run_case
from ftsweep.kinds.requests import program_request
from ftsweep.spec import Case


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
