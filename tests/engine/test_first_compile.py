"""A machine's first compile: numba's cache is the user's cache directory, a first run says it
compiles and records how long it took, and two workers that find the cache empty both finish
with the kernels in it (:mod:`ftsweep.engine.compiling`, :mod:`ftsweep.caches`). Its time is
measured by docs/performance.md's commands, never asserted here."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

BIN = Path(sys.executable).parent


@pytest.mark.integration  # a local cluster's first run, numba's cache empty
def test_a_first_sweep_on_two_workers_compiles_and_leaves_the_kernels_cached(tmp_path):
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
    assert not list(tmp.iterdir())  # nothing left in the temporary directory
    assert list((tmp_path / "numba").rglob("arcs.*.nbi"))  # the kernels are in the cache


@pytest.mark.integration  # a first predict, numba's cache empty
def test_a_first_predict_says_it_compiles_records_the_time_and_leaves_nothing_behind(tmp_path):
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
    assert not list(tmp.iterdir())  # nothing left in the temporary directory
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
