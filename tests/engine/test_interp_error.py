"""The exact-command envelope only when asked: the same results without it,
pv_interp_nm NaN, and unchanged hashes for specs that keep the default."""

from __future__ import annotations

import json
import math

import numpy as np
import xarray as xr
from click.testing import CliRunner
from hypothesis import example, given, settings
from hypothesis import strategies as st

from ftsweep.cli.main import main
from ftsweep.engine.case import Case, Resolution, program_request
from ftsweep.simulate import run_case
from ftsweep.stages.envelope import arcs as envelope
from ftsweep.sweeps.run import run_sweep
from ftsweep.tools.export import export, verify

SMALL = """
surface: small_sine
layout: ring
axes: {points: [8000], aspect: [1.0, 4.0]}
"""


def test_without_the_exact_envelope_every_other_result_is_the_same():
    on = run_case(Case(surface="sinewave2d", layout=program_request(kind="ring", pitch=(20.0, 5.0))))
    off = run_case(
        Case(
            surface="sinewave2d",
            layout=program_request(kind="ring", pitch=(20.0, 5.0)),
            resolution=Resolution(interp_error=False),
        )
    )
    assert math.isfinite(on["pv_interp_nm"]) and math.isnan(off["pv_interp_nm"])
    for key, value in on.items():
        if key == "pv_interp_nm" or key.startswith("seconds"):
            continue
        assert off[key] == value, key


def test_the_default_keeps_hashes_and_round_trips():
    assert "interp_error" not in Resolution().model_dump()
    off = Resolution(interp_error=False)
    assert off.model_dump()["interp_error"] is False
    assert Resolution.model_validate_json(off.model_dump_json()) == off
    a = Case(surface="s", layout=program_request(kind="ring", pitch=(1.0, 1.0)))
    b = Case(surface="s", layout=program_request(kind="ring", pitch=(1.0, 1.0)), resolution=off)
    assert a.key() != b.key()


def test_a_sweep_can_leave_it_out(tmp_path, catalog_dir, monkeypatch):
    monkeypatch.setenv("FTSWEEP_CATALOGS", str(catalog_dir))  # verify compares the entries with it
    spec = tmp_path / "off.yaml"
    spec.write_text(SMALL + "resolution: {interp_error: false}\n")
    out = tmp_path / "off.zarr"
    report = run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    assert report.done == 2
    ds = xr.open_zarr(out).load()
    assert np.all(np.isnan(ds["pv_interp_nm"].values)) and np.all(np.isfinite(ds["pv_nm"].values))
    # such a cube's selection is still strict JSON: the metric not simulated is null
    r = CliRunner().invoke(main, ["select", str(out), "--budget-points", "8000", "--json"])
    assert r.exit_code == 0, r.output
    chosen = json.loads(r.stdout)
    assert chosen["pv_interp_nm"] is None and chosen["pv_nm"] > 0
    text = CliRunner().invoke(main, ["select", str(out), "--budget-points", "8000"])
    assert text.exit_code == 0, text.output
    assert "interpolation alone not simulated" in text.stdout and "nan" not in text.stdout
    # and its export writes strict JSON (the sidecar's selection names the metric null) that verifies
    header = tmp_path / "off.h"
    sidecar = export(out, header, budget_points=8000)
    assert sidecar["selection"]["pv_interp_nm"] != sidecar["selection"]["pv_interp_nm"]  # NaN in memory
    assert (
        json.loads(header.with_name(header.name + ".json").read_text())["selection"]["pv_interp_nm"] is None
    )
    assert verify(header)["pv_nm"] > 0


ARGS = ["predict", "--surface", "sinewave2d", "--drho-um", "20", "--dtheta-deg", "5", "--no-interp-error"]


def test_predict_json_names_the_skipped_metric_null():
    r = CliRunner().invoke(main, [*ARGS, "--json"])
    assert r.exit_code == 0, r.output
    record = json.loads(r.stdout)
    assert record["pv_interp_nm"] is None and record["pv_nm"] > 0
    text = CliRunner().invoke(main, ARGS)
    assert "interp. P-V  not simulated" in text.stdout


# --- the exact envelope evaluated only where the extremes can move (stages.envelope) ---------


def _lines(rng, n_lines, ppf, feed, rc, spread):
    """A batch of feed-plane lines: a path grid's node radii, passes on every ppf-th node, smooth
    exact commands and executed ones that differ by a line-dependent amount."""
    off, k = 3, int(rng.integers(20, 60))
    n_nodes = off + ppf * k + 8
    first = rng.uniform(0.5 * k * feed, k * feed, 2 * n_lines)
    node_r = first[:, None] - (np.arange(n_nodes)[None, :] - off) * (feed / ppf)
    # the passes stop before the axis, as the spiral's do (a path grid's n_passes)
    n_passes = np.minimum(rng.integers(k // 2, k + 1, 2 * n_lines), np.floor(first / feed).astype(int))
    pos = node_r[:, off : off + ppf * k : ppf]
    exact = 0.3 * np.sin(pos / 7.0) + 0.01 * pos
    scale = rng.uniform(0.0, spread, (2 * n_lines, 1))  # lines differ in how far they stray
    w = exact + scale * rng.normal(0.0, 0.02, exact.shape)
    return node_r, w, exact, n_passes, off


def _eager(z_exact, z, inside, ext):
    d = np.where(inside & ~np.isnan(z), z - z_exact, np.nan)
    if np.all(np.isnan(d)):
        return ext.copy()
    return np.array([min(ext[0], np.nanmin(d)), max(ext[1], np.nanmax(d))])


@settings(max_examples=60, deadline=None)
@given(
    st.integers(1, 12),
    st.sampled_from([2, 4]),
    st.floats(0.5, 3.0),
    st.floats(20.0, 150.0),
    st.floats(0.0, 1.0),
    st.integers(0, 2**32 - 1),
)
# passes far apart across the axis (short rays): the bound does not hold there, such lines are
# evaluated
@example(n_lines=8, ppf=2, feed=3.0, rc=20.0, prior=0.0, seed=21)
def test_skipping_lines_gives_the_extremes_of_every_line(n_lines, ppf, feed, rc, prior, seed):
    """The skipped lines provably lie within the extremes found: the result is bit for bit that
    of evaluating the exact envelope on every node, from any extremes found before."""
    rng = np.random.default_rng(seed)
    node_r, w, exact, n_passes, off = _lines(rng, n_lines, ppf, feed, rc, 1.0)
    start = off + ppf + 2
    z = envelope.machined_lines(node_r, w, n_passes, off, ppf, start, rc)[0]
    z_exact = envelope.machined_lines(node_r, exact, n_passes, off, ppf, start, rc)[0]
    inside = rng.uniform(size=z.shape) < 0.9
    # extremes of earlier batches: none, or a range the lines may or may not exceed
    ext = np.array([np.inf, -np.inf]) if prior < 0.3 else np.array([-0.02 * prior, 0.02 * prior])
    want = _eager(z_exact, z, inside, ext)
    got = ext.copy()
    envelope.interp_extrema_lines(node_r, w, exact, n_passes, off, ppf, start, rc, z, inside, got)
    assert np.array_equal(got, want)


def test_lines_within_the_extremes_are_skipped():
    rng = np.random.default_rng(7)
    node_r, w, exact, n_passes, off = _lines(rng, 40, 2, 1.0, 80.0, 1.0)
    w[:2] = exact[:2] + 0.05 * np.sign(rng.normal(size=exact[:2].shape))  # one line strays most
    z = envelope.machined_lines(node_r, w, n_passes, off, 2, off + 4, 80.0)[0]
    inside = np.ones(z.shape, dtype=bool)
    ext = np.array([np.inf, -np.inf])
    grid = (node_r, w, exact, n_passes, off, 2, off + 4, 80.0)
    evaluated = envelope.interp_extrema_lines(*grid, z, inside, ext)
    z_exact = envelope.machined_lines(node_r, exact, n_passes, off, 2, off + 4, 80.0)[0]
    assert np.array_equal(ext, _eager(z_exact, z, inside, np.array([np.inf, -np.inf])))
    assert 1 <= evaluated < 10  # of 40 lines


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 12), st.floats(20.0, 150.0), st.integers(0, 2**32 - 1))
def test_rows_skip_likewise(n_rows, rc, seed):
    rng = np.random.default_rng(seed)
    k = 40
    pos = np.sort(rng.uniform(0.0, 60.0, (n_rows, k)), axis=1)
    n_valid = rng.integers(0, k + 1, n_rows)
    exact = 0.2 * np.cos(pos / 5.0)
    w = exact + rng.uniform(0.0, 1.0, (n_rows, 1)) * rng.normal(0.0, 0.02, pos.shape)
    query = np.sort(rng.uniform(0.0, 60.0, (n_rows, 100)), axis=1)
    query[rng.uniform(size=query.shape) < 0.1] = np.nan
    z = envelope.machined_rows(pos, w, n_valid, rc, query)[0]
    z_exact = envelope.machined_rows(pos, exact, n_valid, rc, query)[0]
    inside = rng.uniform(size=z.shape) < 0.9
    want = _eager(z_exact, z, inside & ~np.isnan(query), np.array([np.inf, -np.inf]))
    got = np.array([np.inf, -np.inf])
    envelope.interp_extrema_rows(pos, w, exact, n_valid, rc, query, z, inside, got)
    assert np.array_equal(got, want)
