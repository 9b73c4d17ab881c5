"""Stored expectations: a fresh sweep reproduces, value for value, the cube stored
in tests/data/expected_small_sweep.json, so refactoring the engine cannot move a result
unnoticed. Regenerate (only for an intended change of results, and say why in the commit):

    FTSWEEP_REGEN_EXPECTED=1 .venv/bin/python -m pytest tests/engine/test_expectations.py
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from support.places import DATA

from ftsweep.store import cube
from ftsweep.sweeps.run import run_sweep

EXPECTED = DATA / "expected_small_sweep.json"
SPECS = {
    "ring": """
surface: small_sine
layout: ring
axes: {points: [8000, 20000], aspect: [1.0, 4.0, 16.0]}
""",
    "mesh": """
surface: small_lens
layout: mesh
axes: {points: [10000], aspect: [0.5, 2.0]}
compensation: slope
""",
}
# the same code on the same platform gives identical bits; this bound only admits
# last-digit differences of libm or SIMD code paths between machines
RTOL = 1e-9


def _values(path: Path) -> dict[str, list]:
    ds = xr.open_zarr(path).drop_vars(list(cube.TIMING_VARS)).load()
    out: dict[str, list] = {}
    for name, var in ds.data_vars.items():
        values = var.values.ravel().tolist()
        out[str(name)] = [None if isinstance(v, float) and math.isnan(v) else v for v in values]
    return out


def test_fresh_sweeps_reproduce_the_stored_cubes(tmp_path, catalog_dir):
    fresh = {}
    for kind, text in SPECS.items():
        spec = tmp_path / f"{kind}.yaml"
        spec.write_text(text)
        out = tmp_path / f"{kind}.zarr"
        run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
        fresh[kind] = _values(out)
    if os.environ.get("FTSWEEP_REGEN_EXPECTED"):
        EXPECTED.parent.mkdir(exist_ok=True)
        EXPECTED.write_text(json.dumps(fresh, indent=1, sort_keys=True) + "\n")
    stored = json.loads(EXPECTED.read_text())
    assert set(stored) == set(fresh)
    for kind in stored:
        assert set(stored[kind]) == set(fresh[kind]), kind
        for name, want in stored[kind].items():
            got = fresh[kind][name]
            if any(isinstance(v, str) for v in want):
                assert got == want, (kind, name)
                continue
            w = np.array([np.nan if v is None else v for v in want], dtype=float)
            g = np.array([np.nan if v is None else v for v in got], dtype=float)
            np.testing.assert_allclose(g, w, rtol=RTOL, atol=0.0, equal_nan=True, err_msg=f"{kind}.{name}")
    assert any(v is not None for v in stored["ring"]["pv_nm"])  # the file holds real results


@pytest.mark.parametrize("kind", list(SPECS))
def test_stored_expectations_cover_every_case(kind):
    stored = json.loads(EXPECTED.read_text())[kind]
    status = stored["status"]
    assert status and all(s == cube.DONE for s in status)
    assert all(v is not None and v > 0 for v in stored["pv_nm"])
