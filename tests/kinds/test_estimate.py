"""The first-order estimate: exact where its premise is exact, and its
agreement with the simulation measured (tests/sweeps/test_reference_sweep.py)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given
from hypothesis import strategies as st

from ftsweep.cli.main import main
from ftsweep.stages.interpolation.tables import bilinear
from ftsweep.stages.layouts import estimate as est
from ftsweep.stages.sampling.geometry import Aperture

SQUARE = Aperture("rectangle", width_um=200.0, height_um=100.0)


def quadratic(a, b):
    """f = ½(a·x² + b·y²): constant second derivatives a, b [1/µm]."""

    def surface(x, y):
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        return 0.5 * (a * x * x + b * y * y), a * x, b * y

    return surface


@given(st.floats(-0.05, 0.05), st.floats(-0.05, 0.05), st.floats(0.5, 20.0), st.floats(0.5, 20.0))
def test_span_is_exact_for_a_quadratic(a, b, dx, dy):
    # on a quadratic the bilinear error is exactly ½[t(1−t)Δx²a + u(1−u)Δy²b] in every cell
    d11, d22 = est.mesh_second_derivatives(quadratic(a, b), SQUARE, n=21)
    span = est.interp_span_nm(d11, d22, np.array([dx]), np.array([dy]))[0]
    top = (dx * dx * max(a, 0.0) + dy * dy * max(b, 0.0)) / 8.0
    bottom = (dx * dx * min(a, 0.0) + dy * dy * min(b, 0.0)) / 8.0
    assert math.isclose(span, (top - bottom) * 1e3, rel_tol=1e-6, abs_tol=1e-9)


def test_span_matches_a_brute_force_bilinear_table():
    # the estimate against interpolating an actual table of the quadratic
    a, b, dx, dy = 0.02, -0.01, 4.0, 2.0
    f = quadratic(a, b)
    xs, ys = np.arange(-20.0, 20.0 + dx, dx), np.arange(-10.0, 10.0 + dy, dy)
    table = f(xs[:, None], ys[None, :])[0]
    x, y = np.meshgrid(np.linspace(-19.9, 19.9, 401), np.linspace(-9.9, 9.9, 201), indexing="ij")
    err = bilinear(table, (x - xs[0]) / dx, (y - ys[0]) / dy, periodic=False) - f(x, y)[0]
    d11, d22 = est.mesh_second_derivatives(f, SQUARE, n=11)
    span = est.interp_span_nm(d11, d22, np.array([dx]), np.array([dy]))[0]
    assert math.isclose(span, (err.max() - err.min()) * 1e3, rel_tol=0.01)


def test_bilinear_functions_estimate_no_interpolation_error():
    def bilinear(x, y):
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        return 0.3 * x * y + 0.1 * x, 0.3 * y + 0.1, 0.3 * x

    d11, d22 = est.mesh_second_derivatives(bilinear, SQUARE, n=31)
    assert np.all(est.interp_span_nm(d11, d22, np.array([5.0, 50.0]), np.array([5.0, 1.0])) < 1e-6)


def test_ring_second_derivatives_of_a_paraboloid():
    # f = c·r²/2: ∂²f/∂ρ² = c and ∂²f/∂θ² = 0 (a surface of revolution)
    c = 0.004
    d_rr, d_tt = est.ring_second_derivatives(quadratic(c, c), Aperture("circle", radius_um=500.0), 50, 90)
    np.testing.assert_allclose(d_rr, c, rtol=1e-6)
    assert np.max(np.abs(d_tt)) < 1e-6


def test_cli_estimate_prints_the_optimum_per_point_count():
    r = CliRunner().invoke(main, ["estimate", "sinewave-ring", "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)
    assert out["layouts"] == 84 and len(out["best"]) == 7
    pvs = [row["pv_estimate_nm"] for row in out["best"]]
    assert pvs == sorted(pvs, reverse=True)  # more points, less error
    cusp = est.cusp_nm(1.0, 83.0)
    assert all(pv > cusp for pv in pvs)


@pytest.mark.slow
def test_estimate_agrees_with_the_simulated_lens_array_sweep(tmp_path):
    """The first-order estimate against the mesh reference sweep (about three minutes on two cores; the
    ring reference sweep is checked in the default suite, tests/sweeps/test_reference_sweep.py)."""
    from ftsweep.kinds.table.sweep_estimate import estimate_sweep
    from ftsweep.sweeps.run import run_sweep
    from ftsweep.sweeps.spec import coordinates, load_sweep
    from ftsweep.tools.query import agreement
    from ftsweep.tools.select import open_cube

    out = tmp_path / "lens-array-mesh.zarr"
    report = run_sweep("lens-array-mesh", out, workers=2)
    assert report.done == report.total == 84
    _, spec = load_sweep("lens-array-mesh")
    found = agreement(estimate_sweep(spec, coordinates(spec)), open_cube(out))
    print("estimate vs simulation, lens-array-mesh:", found)
    assert found["cases"] == 84
    assert found["optimum_aspect_factor_max"] <= 1.5
    assert 0.5 <= found["pv_ratio_min"] and found["pv_ratio_max"] <= 2.0


PRUNE_SPEC = """
surface: small_sine
layout: ring
axes: {points: [8000, 20000], aspect: [0.3, 2.0, 16.0, 128.0]}
"""


@pytest.mark.slow  # 5-7 s on 2 cores: the full command runs it, the quick one leaves it out
def test_prune_leaves_out_hopeless_cases_and_keeps_the_optimum(tmp_path, catalog_dir):
    """``sweep --prune FACTOR`` computes only cases the estimate does not
    rule out; a later run without it computes the rest, giving the full cube."""
    import xarray as xr

    from ftsweep.store import cube
    from ftsweep.sweeps.run import run_sweep
    from ftsweep.tools.query import best_per_point_count, describe
    from ftsweep.tools.select import SelectError, check_exportable

    spec = tmp_path / "p.yaml"
    spec.write_text(PRUNE_SPEC)
    kw = {"scheduler": "synchronous", "catalog_folder": catalog_dir}
    full = tmp_path / "full.zarr"
    run_sweep(str(spec), full, **kw)
    out = tmp_path / "pruned.zarr"
    report = run_sweep(str(spec), out, prune=2.0, **kw)
    status = cube.read_status(out)
    pruned = status == cube.PRUNED
    assert 0 < pruned.sum() < status.size and report.pruned == pruned.sum()
    assert report.done == int((status == cube.DONE).sum()) == status.size - pruned.sum()
    # the simulation agrees that every pruned case is worse than the best of its point count
    pv = xr.open_zarr(full)["pv_nm"].values
    row_best = pv.min(axis=1, keepdims=True)
    assert np.all(np.broadcast_to(row_best, pv.shape)[pruned] < pv[pruned])
    assert best_per_point_count(out) == best_per_point_count(full)
    ds = xr.open_zarr(out).load()
    flat = int(np.flatnonzero(pruned.ravel())[0])
    with pytest.raises(SelectError, match="pruned by the estimate"):
        check_exportable(ds, flat)
    assert describe(ds, flat)["status"] == "pruned"
    # without --prune, the pruned cases are computed and the cube equals the full one
    again = run_sweep(str(spec), out, **kw)
    assert again.done == pruned.sum()
    drop = [*cube.TIMING_VARS, "run_id"]
    xr.testing.assert_equal(
        xr.open_zarr(out).drop_vars(drop).load(), xr.open_zarr(full).drop_vars(drop).load()
    )


@given(st.integers(0, 2**32 - 1), st.integers(1, 3000))
def test_the_extreme_samples_give_the_span_of_all_samples_bit_for_bit(seed, n):
    rng = np.random.default_rng(seed)
    d11, d22 = rng.normal(0.0, 0.01, (2, n))
    d11[rng.random(n) < 0.1] = 0.0  # ties and zeros, as flat regions give
    p1, p2 = rng.uniform(0.1, 20.0, (2, 50))
    full = np.empty(50)
    est._span_kernel(d11, d22, p1, p2, full)
    np.testing.assert_array_equal(est.interp_span_nm(d11, d22, p1, p2), full * 1e3)
    assert est.extreme_samples(d11, d22)[0].size <= n


def test_a_sweep_whose_kind_has_no_estimate_is_refused_by_name():
    res = CliRunner().invoke(main, ["estimate", "sinewave-spiral"])
    assert res.exit_code == 1 and "a spiral sweep has none" in res.output
