"""Figures, the HTML report and the xarray accessor."""

from __future__ import annotations

import struct

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

import ftsweep  # noqa: F401  (registers ds.ftsweep)
from ftsweep.cli.main import main
from ftsweep.sweeps.run import run_sweep
from ftsweep.tools.report import FIGURES

SPEC = """
surface: small_sine
layout: ring
resolution: {error_map_bins: 24}
axes: {points: [8000, 16000], aspect: [1.0, 4.0, 16.0]}
"""


@pytest.fixture()
def small_cube(tmp_path, catalog_dir, monkeypatch):
    monkeypatch.setenv("FTSWEEP_CATALOGS", str(catalog_dir))
    spec = tmp_path / "rep.yaml"
    spec.write_text(SPEC)
    out = tmp_path / "rep.zarr"
    run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    return out


def png_size(path):
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    assert data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def test_report_writes_every_figure_and_an_html_page(small_cube, tmp_path):
    out = tmp_path / "report"
    r = CliRunner().invoke(main, ["report", str(small_cube), "--out", str(out), "--map-bins", "40"])
    assert r.exit_code == 0, r.output
    page = (out / "index.html").read_text()
    for name in FIGURES:
        png = out / f"{name}.png"
        width, height = png_size(png)
        assert 400 <= width <= 2000 and 300 <= height <= 2000, (name, width, height)
        assert png.stat().st_size > 10_000  # a real picture, not an empty canvas
        assert f'src="{name}.png"' in page
    assert "small_sine" in page and "Chosen case" in page
    assert not list(out.glob(".*"))  # no temporary files left


def test_report_maps_the_case_export_chooses_with_the_same_budget(small_cube, tmp_path):
    """``report --budget-points N`` shows the case ``select``/``export --budget-points N``
    choose, not the best at the largest budget; two criteria at once are refused."""
    import json

    picked = json.loads(
        CliRunner().invoke(main, ["select", str(small_cube), "--budget-points", "9000", "--json"]).stdout
    )
    out = tmp_path / "budget"
    args = ["report", str(small_cube), "--out", str(out), "--map-bins", "16", "--budget-points", "9000"]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0, r.output
    page = (out / "index.html").read_text()
    assert f"<th>index</th><td>{picked['index']}</td>" in page and "at or under 9,000 points" in page
    largest = json.loads(
        CliRunner().invoke(main, ["select", str(small_cube), "--budget-points", "16000", "--json"]).stdout
    )
    assert largest["index"] != picked["index"]  # the default would have mapped another case
    both = CliRunner().invoke(main, ["report", str(small_cube), "--budget-points", "9000", "--case", "0"])
    assert both.exit_code == 2 and "at most one of --budget-points, --tolerance-nm and --case" in both.output


def test_report_maps_the_case_last_exported_by_default(small_cube, tmp_path):
    """With no rule the error map shows the case the cube's last export wrote (its ledger
    records it), not the best at the largest budget; a cube never exported keeps that best."""
    import json
    import shutil

    cube = tmp_path / "copy.zarr"
    shutil.copytree(small_cube, cube)
    picked = json.loads(
        CliRunner().invoke(main, ["select", str(cube), "--budget-points", "9000", "--json"]).stdout
    )
    r = CliRunner().invoke(
        main, ["export", str(cube), "--budget-points", "9000", "-o", str(tmp_path / "p.h")]
    )
    assert r.exit_code == 0, r.output
    out = tmp_path / "default"
    r = CliRunner().invoke(main, ["report", str(cube), "--out", str(out), "--map-bins", "16"])
    assert r.exit_code == 0, r.output
    page = (out / "index.html").read_text()
    assert f"<th>name</th><td>{picked['name']}</td>" in page
    assert "the case last exported from the cube (p.h)" in page


def test_accessor_best_optimum_and_plots(small_cube):
    ds = xr.open_zarr(small_cube)
    best = ds.ftsweep.best(budget_points=16000)
    assert best["pv_nm"].item() == pytest.approx(float(ds["pv_nm"].where(ds["n_points"] <= 16000).min()))
    optimum = ds.ftsweep.optimum()
    assert set(optimum.values) <= set(ds["aspect"].values)
    for plot in (
        ds.ftsweep.plot_pv,
        ds.ftsweep.plot_aspect,
        ds.ftsweep.plot_heatmap,
        ds.ftsweep.plot_error_map,
    ):
        ax = plot()
        assert ax.get_xlabel() and ax.get_ylabel()  # units on every axis, in words where a count
        for label in (ax.get_xlabel(), ax.get_ylabel()):
            assert "[" in label or "(count)" in label or "(dimensionless)" in label, label
            assert "[1]" not in label, label


def test_stored_error_maps_match_the_case_pv(small_cube):
    ds = xr.open_zarr(small_cube)
    peak = ds["error_map_peak_nm"].values
    assert peak.shape == (2, 3, 24, 24)
    # the map's signed peaks are node errors, so they stay within each case's error range
    assert np.all(np.nanmax(peak, axis=(2, 3)) <= ds["error_max_nm"].values + 1e-9)
    assert np.all(np.nanmin(peak, axis=(2, 3)) >= ds["error_min_nm"].values - 1e-9)
    assert ds["map_x"].attrs["units"] == "um"


def test_error_map_without_stored_maps_says_what_to_do(tmp_path, catalog_dir):
    spec = tmp_path / "nomap.yaml"
    spec.write_text(SPEC.replace("resolution: {error_map_bins: 24}\n", ""))
    out = tmp_path / "nomap.zarr"
    run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    with pytest.raises(ValueError, match="error_map_bins"):
        xr.open_zarr(out).ftsweep.plot_error_map()
