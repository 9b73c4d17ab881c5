"""The tolerance loop (ftsweep optimize)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr

from ftsweep.store import cube
from ftsweep.store.cube import CubeError
from ftsweep.tools.optimize import optimize


@pytest.mark.slow  # 7-15 s on 2 cores: the full command runs it, the quick one leaves it out
def test_finds_the_smallest_layout_meeting_the_tolerance(tmp_path, catalog_dir):
    out = tmp_path / "opt.zarr"
    result = optimize("small_sine", "ring", 40.0, out, start_points=5000, catalog_folder=catalog_dir)
    assert result["met"]
    ans = result["answer"]
    assert ans["pv_nm"] <= 40.0 and ans["feasible"]
    ds = xr.open_zarr(out)
    # every evaluation recorded, through the sweeps' store protocol: flags, provenance
    assert int((ds["status"] != cube.PENDING).sum()) == result["evaluations"] >= 10
    assert ds["pv_nm"].attrs["units"] == "nm" and ds.attrs["tolerance_nm"] == 40.0
    assert "small_sine" in json.loads(ds.attrs["catalog_entries"])["surface"]
    done = ds["status"].values == cube.DONE
    # each evaluation records its realised table and pitches, as sweep cubes do
    np.testing.assert_array_equal(
        (ds["table_rows"] * ds["table_cols"]).values[done], ds["n_points"].values[done]
    )
    assert np.all(np.isfinite(ds["drho_um"].values[done])) and np.all(ds["aspect_actual"].values[done] > 0)
    assert ds["dtheta_deg"].attrs["units"] == "deg" and ds["aspect_target"].attrs["units"] == "um/deg"
    meets = (ds["pv_nm"].values <= 40.0) & done
    # the answer is the smallest evaluated layout that meets it
    assert ans["n_points"] == ds["n_points"].values[meets].min()
    # and the loop bracketed it: a layout at most 5 % smaller was tried and failed
    smaller = ds["n_points"].values < ans["n_points"]
    assert np.any(smaller & ~meets & (ds["n_points"].values >= 0.9 * ans["n_points"]))


def test_capacity_reached_without_meeting_reports_the_best(tmp_path, catalog_dir):
    result = optimize(
        "small_sine",
        "ring",
        0.5,
        tmp_path / "o.zarr",
        start_points=5000,
        machine="tiny-fts",
        catalog_folder=catalog_dir,
    )
    assert not result["met"]
    assert result["answer"]["pv_nm"] > 0.5
    assert result["answer"]["n_points"] <= 30000


@pytest.mark.slow  # 7-15 s on 2 cores: the full command runs it, the quick one leaves it out
def test_same_search_resumes_and_another_needs_restart(tmp_path, catalog_dir):
    out = tmp_path / "o.zarr"
    args = ("small_sine", "ring", 200.0, out)
    first = optimize(*args, start_points=3000, catalog_folder=catalog_dir, max_rounds=1)
    ids = xr.open_zarr(out)["run_id"].values.copy()
    again = optimize(*args, start_points=3000, catalog_folder=catalog_dir, max_rounds=1)
    # nothing recomputed: every evaluation came from the cube, with the first run's ids
    assert again["reused"] == first["evaluations"] == again["evaluations"]
    assert again["answer"]["n_points"] == first["answer"]["n_points"]
    np.testing.assert_array_equal(xr.open_zarr(out)["run_id"].values, ids)
    with pytest.raises(CubeError, match="changed: tolerance_nm.*--restart"):
        optimize(
            "small_sine", "ring", 150.0, out, start_points=3000, catalog_folder=catalog_dir, max_rounds=1
        )
    redone = optimize(
        "small_sine",
        "ring",
        150.0,
        out,
        start_points=3000,
        catalog_folder=catalog_dir,
        max_rounds=1,
        restart=True,
    )
    assert redone["reused"] == 0 and redone["evaluations"] > 0
    plain = tmp_path / "plain"
    plain.mkdir()
    with pytest.raises(CubeError, match="not an ftsweep evaluation cube"):
        optimize("small_sine", "ring", 150.0, plain, catalog_folder=catalog_dir, restart=True)
    assert plain.exists()  # --restart never deletes what is not an evaluation cube
    with pytest.raises(ValueError, match="positive"):
        optimize("small_sine", "ring", -1.0, tmp_path / "p.zarr", catalog_folder=catalog_dir)


@pytest.mark.slow  # 7-15 s on 2 cores: the full command runs it, the quick one leaves it out
def test_a_search_seeded_by_the_estimate_needs_fewer_evaluations(tmp_path, catalog_dir):
    # the estimate seeds the aspect optimum and the point count
    args = ("small_sine", "ring", 40.0)
    scan = optimize(*args, tmp_path / "scan.zarr", start_points=5000, catalog_folder=catalog_dir)
    seeded = optimize(*args, tmp_path / "seeded.zarr", catalog_folder=catalog_dir, seed="estimate")
    assert scan["met"] and seeded["met"]
    assert seeded["answer"]["pv_nm"] <= 40.0
    print("evaluations: scan", scan["evaluations"], "estimate-seeded", seeded["evaluations"])
    assert seeded["evaluations"] < scan["evaluations"]
    # both end at about the same smallest layout (each brackets it within ~5 %)
    assert seeded["answer"]["n_points"] == pytest.approx(scan["answer"]["n_points"], rel=0.15)
    with pytest.raises(ValueError, match="unknown seed"):
        optimize(*args, tmp_path / "x.zarr", catalog_folder=catalog_dir, seed="guess")


@pytest.mark.parametrize("kind", ["spiral", "dpath", "fresnel"])
def test_a_path_program_is_refused_saying_why_before_anything_is_written(kind, tmp_path, catalog_dir):
    out = tmp_path / "search.zarr"
    with pytest.raises(ValueError, match=f"aspect ratios of tables .*a {kind} program has none"):
        optimize("small_sine", kind, 20.0, out, catalog_folder=catalog_dir)
    assert not out.exists()
