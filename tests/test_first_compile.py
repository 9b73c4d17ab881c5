"""A first run's compile shared between a local cluster's workers: the kernels a case calls are
found without compiling them (each kernel run as the Python it is written in, on one line of
the case), and processes that share a claims folder compile them each once between them,
loading the others' from numba's cache (:mod:`ftsweep.engine.startup`). Its time is measured by
docs/performance.md's commands, never asserted here."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ftsweep.engine import startup
from ftsweep.engine.case import Case, Resolution
from ftsweep.registry import kind

BIN = Path(sys.executable).parent

# in a fresh interpreter: the kernels found without compiling any, then compiled for the types
# found, after which the whole warm-up case calls no kernel for types not compiled already
PROBE = """
import json, sys
from numba.core.registry import CPUDispatcher
from ftsweep.engine import startup
from ftsweep.engine.case import Case, Resolution
from ftsweep.registry import kind
from ftsweep.simulate import run_case

def signatures():
    found = {}
    for name, module in list(sys.modules.items()):
        if name.startswith("ftsweep."):
            for value in list(vars(module).values()):
                if isinstance(value, CPUDispatcher):
                    found[value.py_func.__qualname__] = sorted(map(str, value.signatures))
    return found

case = Case(surface=sys.argv[1], layout=kind(sys.argv[2]).warm_request())
line = case.model_copy(update={"resolution": Resolution(n_theta=2)})
calls = startup.kernel_calls(lambda: run_case(line), 60.0)
untouched = signatures()
startup.compile_shared(calls, sys.argv[3], 1.0)
compiled = signatures()
run_case(case)
print(json.dumps({"found": sorted(k.py_func.__qualname__ for k, _ in calls), "untouched": untouched,
                  "compiled": compiled, "after": signatures()}))
"""


@pytest.mark.parametrize(("surface", "layout"), [("sinewave2d", "ring"), ("lens_array", "mesh")])
def test_the_kernels_a_case_calls_are_found_without_compiling_and_are_all_it_calls(tmp_path, surface, layout):
    claims = tmp_path / "claims"
    out = subprocess.run(
        [sys.executable, "-c", PROBE, surface, layout, str(claims)],
        capture_output=True,
        text=True,
        check=True,
        timeout=600,
    )
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert {"envelope_lines", "interp_extrema_lines", "accumulate"} <= set(got["found"])
    # found by running them as Python: no kernel was compiled (nor loaded) for it
    assert not any(got["untouched"].values())
    assert all(got["compiled"][name] for name in got["found"])
    # the warm-up case then called nothing that was not compiled for the types found
    assert got["after"] == got["compiled"]
    assert not claims.exists()  # its last process removes the claims folder


def test_a_kernel_another_process_claims_is_waited_for_then_compiled_here(tmp_path):
    from ftsweep.simulate import run_case

    case = Case(surface="sinewave2d", layout=kind("ring").warm_request(), resolution=Resolution(n_theta=2))
    calls = startup.kernel_calls(lambda: run_case(case), 60.0)
    assert calls
    claims = tmp_path / "claims"
    claims.mkdir()
    held = startup._claim_of(calls[0], claims)
    held.touch()  # a process that claimed the first kernel and died
    t = time.perf_counter()
    startup.compile_shared(calls[:1], str(claims), wait_s=0.3)
    assert time.perf_counter() - t >= 0.3  # it waited for the claim, then went on
    kernel, types = calls[0]
    assert types in kernel.overloads  # compiled (or loaded) here all the same
    assert held.exists() and claims.exists()  # another's claim is not its to remove


def test_the_python_run_stops_when_its_time_is_spent():
    from ftsweep.simulate import run_case

    case = Case(surface="sinewave2d", layout=kind("ring").warm_request(), resolution=Resolution(n_theta=2))
    t = time.perf_counter()
    calls = startup.kernel_calls(lambda: run_case(case), 0.0)
    assert time.perf_counter() - t < 1.0
    assert calls == []
    assert run_case(case)["pv_nm"] > 0  # the kernels run compiled again


@pytest.mark.integration  # a local cluster's first run, numba's cache empty
def test_a_first_sweep_on_two_workers_compiles_between_them_and_leaves_no_claims(tmp_path):
    spec = tmp_path / "two.yaml"
    spec.write_text("surface: sinewave2d\naxes: {points: [20000, 40000], aspect: [8.0]}\n")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"), TMPDIR=str(tmp))
    out = subprocess.run(
        [str(BIN / "ftsweep"), "sweep", str(spec), "--out", str(tmp_path / "two.zarr"), "--workers", "2"],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert out.returncode == 0, out.stderr
    assert "compiling" in out.stderr  # the first run on this cache says so
    assert "[2/2] 0 failed, 0 refused, 0 pending" in out.stderr
    assert not list(tmp.glob("ftsweep-compiling-*"))
    assert list((tmp_path / "numba").rglob("arcs.*.nbi"))  # the kernels are in the cache


@pytest.mark.integration  # a first predict, numba's cache empty
def test_a_first_predict_compiles_with_a_helper_process_and_leaves_nothing_behind(tmp_path):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    args = ["predict", "--surface", "sinewave2d", "--layout", "ring", "--points", "20000", "--aspect", "8"]
    first = subprocess.run(
        [str(BIN / "ftsweep"), *args, "--json"],
        capture_output=True,
        text=True,
        env=dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"), TMPDIR=str(tmp)),
        timeout=600,
    )
    assert first.returncode == 0, first.stderr
    # nothing measured in this cache yet: the notice gives no figure, then the run records one
    assert "compiling    numba's kernels: a first run of this install (not yet measured here)" in first.stderr
    from ftsweep.caches import recorded_compile_s

    assert recorded_compile_s(tmp_path / "numba") > 0
    assert not list(tmp.iterdir())  # the helper's claims folder is gone
    # and so is the helper (its command line names the folder, in this test's own TMPDIR)
    helpers = subprocess.run(
        ["pgrep", "-f", f"ftsweep.engine.compiling {tmp}"], capture_output=True, text=True
    )
    assert not helpers.stdout.strip()
    # the record is the one a run with every kernel cached gives
    again = subprocess.run(
        [str(BIN / "ftsweep"), *args, "--json"],
        capture_output=True,
        text=True,
        env=dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba")),
        timeout=600,
        check=True,
    )
    assert json.loads(first.stdout)["pv_nm"] == json.loads(again.stdout)["pv_nm"]
    assert "compiling" not in again.stderr  # cached: nothing to say


# ----------------------------------------------------------------------------- where the cache is
def test_numbas_cache_is_the_user_cache_directory_unless_the_user_names_one(tmp_path):
    """A fresh process: with NUMBA_CACHE_DIR unset, importing ftsweep points numba at
    $XDG_CACHE_HOME/ftsweep/numba, also where numba was imported first; a user's own setting
    stands."""
    code = "import sys, numba\nimport ftsweep\nfrom numba.core import config\nprint(config.CACHE_DIR)\n"
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["XDG_CACHE_HOME"] = str(tmp_path / "xdg")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == str(tmp_path / "xdg" / "ftsweep" / "numba")
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "mine")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert out.stdout.strip() == str(tmp_path / "mine")


def test_a_first_compile_record_is_read_bounded_and_checked(tmp_path):
    from ftsweep.caches import COMPILE_RECORD, recorded_compile_s

    assert recorded_compile_s(tmp_path) is None  # nothing measured here
    record = tmp_path / COMPILE_RECORD
    for text in ('{"seconds": "9"}', '{"seconds": NaN}', '{"seconds": -1}', '{"seconds": true}', "[]", "{"):
        record.write_text(text)
        assert recorded_compile_s(tmp_path) is None, text
    record.write_text('{"seconds": 1' + "0" * 5000 + "}")
    assert recorded_compile_s(tmp_path) is None  # past the record's bound: not read
    record.write_text('{"seconds": 9.25, "measured": "2026-12-06T21:00:00+0000"}')
    assert recorded_compile_s(tmp_path) == 9.25
