"""The reference sweep sinewave-ring end to end, as the README's main command runs it:
a LocalCluster sweep, then the selection at a 950,000-point budget and the
export/verify round trip of that layout. Takes about five minutes on two cores."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import xarray as xr

from ftsweep.store import cube
from ftsweep.tools.export import export, verify
from ftsweep.tools.select import choose, open_cube

# the reference sweep on a local cluster
pytestmark = pytest.mark.integration

BUDGET = 950_000


@pytest.fixture(scope="module")
def ring_cube(reference_sweep, tmp_path_factory):
    """The run's reference sweep (tests/conftest.py), copied: export writes the cube's ledger."""
    out = tmp_path_factory.mktemp("reference") / reference_sweep.name
    shutil.copytree(reference_sweep, out)
    ds = xr.open_zarr(out)
    assert ds["status"].size == 84 and np.all(ds["status"].values == cube.DONE)
    return out


def test_select_at_950k_beats_every_other_aspect_ratio(ring_cube):
    ds = open_cube(ring_cube)
    chosen = choose(ds, budget_points=BUDGET)
    assert chosen["n_points"] <= BUDGET
    pv = ds["pv_nm"].values
    eligible = (
        (ds["n_points"].values <= BUDGET) & (ds["status"].values == cube.DONE) & (ds["feasible"].values == 1)
    )
    others = pv[eligible & (pv != chosen["pv_nm"])]
    assert others.size == eligible.sum() - 1
    assert np.all(chosen["pv_nm"] < others)
    # in particular at the budget's own row, against every other aspect ratio
    row = ds["pv_nm"].sel(points=BUDGET)
    assert chosen["points_target"] == BUDGET
    assert np.all(chosen["pv_nm"] < np.delete(row.values, int(np.argmin(row.values))))
    # an interior optimum: neither end of the aspect-ratio axis
    best_aspect = float(ds["aspect"].values[int(np.argmin(row.values))])
    assert ds["aspect"].values.min() < best_aspect < ds["aspect"].values.max()


def test_export_and_verify_the_selected_layout(ring_cube, tmp_path):
    header = tmp_path / "sinewave_ring.h"
    meta = export(ring_cube, header, budget_points=BUDGET)
    record = verify(header)
    assert abs(record["pv_nm"] - meta["pv_nm"]) <= max(1.0, 0.02 * meta["pv_nm"])


def test_cube_has_units_and_provenance(ring_cube):
    ds = xr.open_zarr(ring_cube)
    # numbers carry units; flags (status) and text follow CF and carry none
    for v in ds.variables:
        numeric = ds[v].dtype.kind in "fiu" and "flag_values" not in ds[v].attrs
        assert ("units" in ds[v].attrs) == numeric, v
    assert ds.attrs["sweep_name"] == "sinewave-ring"


def test_estimate_agrees_with_the_simulated_reference_sweep(ring_cube):
    """The first-order estimate against the 84 simulated cases."""
    from ftsweep.kinds.table.sweep_estimate import estimate_sweep
    from ftsweep.sweeps.spec import coordinates, load_sweep
    from ftsweep.tools.query import agreement

    _, spec = load_sweep("sinewave-ring")
    found = agreement(estimate_sweep(spec, coordinates(spec)), open_cube(ring_cube))
    print("estimate vs simulation, sinewave-ring:", found)  # the measured agreement (pytest -s)
    assert found["cases"] == 84
    # the estimated aspect optimum of each point count within a factor 1.5 of the simulated one
    assert found["optimum_aspect_factor_max"] <= 1.5
    # and its P-V within a factor 2 over the swept plane
    assert 0.5 <= found["pv_ratio_min"] and found["pv_ratio_max"] <= 2.0
