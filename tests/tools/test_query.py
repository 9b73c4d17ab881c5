"""One query core: the sweep summary, ``ds.ftsweep.optimum()``, ``select``
and ``export`` agree on every cube, also one with infeasible and over-capacity cases."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import xarray as xr

import ftsweep  # noqa: F401  (registers ds.ftsweep)
from ftsweep.store import cube
from ftsweep.sweeps.run import run_sweep
from ftsweep.tools import query
from ftsweep.tools.query import best_per_point_count
from ftsweep.tools.select import check_exportable, choose, open_cube

SPEC = """
surface: small_sine
layout: ring
machine: {machine}
axes: {{points: [8000, 20000, 60000], aspect: [1.0, 4.0, 16.0]}}
"""


@pytest.fixture(scope="module")
def mixed_cube(tmp_path_factory, module_catalog_dir):
    """A cube whose 60,000-point row is over the controller's capacity (30,000) and in which
    the lowest-P-V case of the 20,000-point row is infeasible for the machine's acceleration
    limit, while other cases of that row stay feasible."""
    folder = tmp_path_factory.mktemp("query")
    catalogs = folder / "catalogs"
    shutil.copytree(module_catalog_dir, catalogs)
    probe_spec = folder / "probe.yaml"
    probe_spec.write_text(SPEC.format(machine="tiny-fts"))
    probe = folder / "probe.zarr"
    run_sweep(str(probe_spec), probe, scheduler="synchronous", catalog_folder=catalogs)
    ds = open_cube(probe)
    row = ds.isel(points=1)
    best = int(np.nanargmin(row["pv_nm"].values))
    accel = row["w_accel_peak_m_s2"].values
    limit = float(0.999 * accel[best])
    assert np.any(accel < limit), "no case of the row would stay feasible: choose another row"
    with (catalogs / "machines.yaml").open("a") as fh:
        fh.write(
            f"""
picky-fts:
  description: tiny-fts with a peak acceleration limit between the cases (for tests).
  capacity_points: 30000
  command_rate_hz: 20000.0
  travel_um: 5000.0
  peak_accel_m_s2: {limit!r}
  continuous_accel_m_s2: 1000.0
  bandwidth_hz: 440.0
  bandwidth_amplitude_um: 100.0
"""
        )
    spec = folder / "mixed.yaml"
    spec.write_text(SPEC.format(machine="picky-fts"))
    out = folder / "mixed.zarr"
    run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalogs)
    return out


def test_the_cube_holds_infeasible_and_over_capacity_cases(mixed_cube):
    ds = open_cube(mixed_cube)
    # over the controller's capacity: refused before they were sent, saying why
    assert np.all(ds["status"].values[2] == cube.REFUSED)
    assert all("capacity" in str(m) for m in ds["message"].values[2])
    row = ds.isel(points=1)
    raw_best = int(np.nanargmin(row["pv_nm"].values))
    assert int(row["feasible"].values[raw_best]) == 0  # the lowest P-V is infeasible
    assert np.any(row["feasible"].values == 1)


def test_summary_optimum_and_select_agree(mixed_cube):
    ds = open_cube(mixed_cube)
    summary = best_per_point_count(mixed_cube)
    optimum = ds.ftsweep.optimum()
    # an aspect ratio: the coordinate's units (it carried the P-V's "nm")
    assert optimum.name == "aspect" and optimum.attrs == ds["aspect"].attrs
    assert optimum.attrs["units"] != "nm"
    for i, row in enumerate(summary):
        sub = ds.isel(points=[i])
        if row["index"] is None:
            assert np.isnan(optimum.values[i])
            with pytest.raises(ValueError, match="no computed, feasible case"):
                choose(sub, tolerance_nm=1e9)
            continue
        # the summary's case is exportable, and it is the accessor's and select's best
        check_exportable(ds, row["index"])
        assert optimum.values[i] == row["aspect"]
        chosen = choose(sub, tolerance_nm=1e-9)  # nothing meets it: the best of the row
        assert chosen["pv_nm"] == row["pv_nm"] and chosen["aspect_target"] == row["aspect"]
        assert ds.ftsweep.pv().isel(points=i).min().item() == row["pv_nm"]
    # the overall best under the largest budget is the best of the summary's rows
    found = [r for r in summary if r["index"] is not None]
    best = choose(ds, budget_points=int(np.nanmax(ds["n_points"].values)))
    assert best["pv_nm"] == min(r["pv_nm"] for r in found)
    assert ds.ftsweep.best(budget_points=10**6).attrs["index"] == best["index"]


def test_summary_never_names_a_case_select_refuses(mixed_cube):
    ds = open_cube(mixed_cube)
    ok = query.eligible(ds).values.ravel()
    for row in best_per_point_count(mixed_cube):
        if row["index"] is not None:
            assert ok[row["index"]]
    raw = xr.open_zarr(mixed_cube)["pv_nm"].isel(points=1)
    assert best_per_point_count(mixed_cube)[1]["pv_nm"] > float(
        raw.min()
    )  # the infeasible one is passed over


def test_a_count_axis_is_an_integer_coordinate(mixed_cube):
    """Target point counts read as the integers they are (950000, not 9.5e+05), with their units."""
    ds = xr.open_zarr(mixed_cube)
    assert ds["points"].dtype.kind == "i" and ds["points"].values.tolist() == [8000, 20000, 60000]
    assert ds["points"].attrs["units"] == "1" and ds["aspect"].dtype.kind == "f"


def test_the_optimum_of_a_lazily_opened_cube_is_computed(mixed_cube):
    """A notebook's ``xr.open_zarr`` cube is dask-backed: the accessor's optimum is still an
    answer (numpy values), not a lazy graph."""
    lazy = cube.open_dataset(mixed_cube)
    assert lazy["pv_nm"].chunks is not None  # the cube as a notebook opens it
    optimum = lazy.ftsweep.optimum()
    assert isinstance(optimum.data, np.ndarray)
    np.testing.assert_array_equal(optimum.values, open_cube(mixed_cube).ftsweep.optimum().values)


def test_a_budget_below_every_case_names_the_smallest_count(mixed_cube):
    ds = open_cube(mixed_cube)
    counts = ds["n_points"].where(ds["feasible"] == 1).values
    smallest = int(np.nanmin(counts))
    with pytest.raises(
        ValueError, match=rf"its smallest has {smallest:,} points \(--budget-points {smallest}\)"
    ):
        choose(ds, budget_points=10)


def test_an_unknown_sweep_name_gets_a_did_you_mean():
    from ftsweep.inputs.catalogs import CatalogError
    from ftsweep.sweeps.spec import load_sweep

    with pytest.raises(
        CatalogError, match=r"unknown sweep 'sinewave-rng' \(did you mean 'sinewave-ring'\?\)"
    ):
        load_sweep("sinewave-rng")


def test_a_missing_cube_names_the_cubes_beside_it(tmp_path, monkeypatch):
    from click.testing import CliRunner

    from ftsweep.cli.main import main

    for name in ("sinewave-ring.zarr", "lens-array-mesh.zarr"):
        (tmp_path / "outputs" / name).mkdir(parents=True)
    monkeypatch.chdir(tmp_path)
    r = CliRunner().invoke(main, ["status", "outputs/sinewave-rng.zarr"])
    assert r.exit_code == 2
    flat = " ".join(r.output.split())
    assert "no cube of that name (did you mean 'sinewave-ring.zarr'?)" in flat
    assert "cubes in outputs: outputs/lens-array-mesh.zarr, outputs/sinewave-ring.zarr" in flat
    # a folder with no cube: how to make one
    r = CliRunner().invoke(main, ["status", str(tmp_path / "none" / "sinewave-ring.zarr")])
    assert "run `ftsweep sweep sinewave-ring --out" in " ".join(r.output.split())
