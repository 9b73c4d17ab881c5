"""Work shared across cases: cases on the same lines reuse their surface
samples, exact commands and exact envelope, and give exactly what they give alone."""

from __future__ import annotations

import math

import numpy as np
import pytest
import xarray as xr
from hypothesis import given
from hypothesis import strategies as st

from ftsweep.engine.case import Case, Resolution, program_request
from ftsweep.engine.cost import ladder_rung
from ftsweep.engine.lines import LineCache
from ftsweep.simulate import run_case
from ftsweep.store.cube import TIMING_VARS
from ftsweep.sweeps.run import run_sweep
from ftsweep.sweeps.spec import case_lines, load_sweep, plan_tasks


def _same(a: dict, b: dict) -> list[str]:
    """Fields of two records that differ (timings aside; NaN equals NaN)."""

    def equal(x, y):
        if isinstance(x, np.ndarray):
            return np.array_equal(x, y, equal_nan=True)
        return x == y or (isinstance(x, float) and math.isnan(x) and math.isnan(y))

    return [k for k in a if not k.startswith("seconds") and not equal(a[k], b[k])]


def _case(pitch, n_theta=240, **kw):
    return Case(
        surface="small_sine",
        layout=program_request(kind="ring", pitch=pitch),
        resolution=Resolution(n_theta=n_theta, **kw),
    )


def test_cases_on_the_same_lines_reuse_them_and_give_what_they_give_alone(catalog_dir):
    cache = LineCache(2**30)
    first = run_case(_case((20.0, 6.0)), catalog_dir, lines=cache)
    misses = cache.misses
    assert cache.hits == 0 and misses > 0 and cache.nbytes > 0
    second = run_case(_case((10.0, 12.0)), catalog_dir, lines=cache)
    assert cache.hits == misses and cache.misses == misses  # every batch came from the cache
    assert second["seconds_sampling"] == 0.0  # nothing was sampled again
    alone = run_case(_case((10.0, 12.0)), catalog_dir)
    assert _same(second, alone) == []
    assert first["pv_nm"] != second["pv_nm"]  # the table's own work was done: another answer


def test_different_lines_or_methods_are_not_mixed_up(catalog_dir):
    cache = LineCache(2**30)
    run_case(_case((20.0, 6.0)), catalog_dir, lines=cache)
    for other in (
        _case((20.0, 6.0), n_theta=244),  # other angles
        Case(**{**_case((20.0, 6.0)).model_dump(), "feed_um": 4.0}),  # other spiral
        Case(**{**_case((20.0, 6.0)).model_dump(), "compensation": "slope"}),  # other exact commands
    ):
        hits = cache.hits
        record = run_case(other, catalog_dir, lines=cache)
        assert cache.hits == hits
        assert _same(record, run_case(other, catalog_dir)) == []


def test_a_small_budget_keeps_less_and_changes_nothing(catalog_dir):
    cache = LineCache(1.0)  # smaller than any batch: nothing kept
    a = run_case(_case((20.0, 6.0)), catalog_dir, lines=cache)
    assert cache.nbytes == 0 and cache.hits == 0
    assert _same(a, run_case(_case((20.0, 6.0)), catalog_dir)) == []
    full = LineCache(2**30)
    run_case(_case((20.0, 6.0)), catalog_dir, batch_nodes=20_000, lines=full)
    budget = full.nbytes // 2
    half = LineCache(budget)
    run_case(_case((20.0, 6.0)), catalog_dir, batch_nodes=20_000, lines=half)
    assert 0 < half.nbytes <= budget
    run_case(_case((10.0, 12.0)), catalog_dir, batch_nodes=20_000, lines=half)
    # the first batches stay (the lines being filled never evict their own), and the next case on
    # the same lines reuses them and recomputes the rest
    assert 0 < half.hits < full.misses
    # other lines make room by dropping the older lines' batches, staying within the budget
    run_case(_case((20.0, 6.0), n_theta=300), catalog_dir, batch_nodes=20_000, lines=half)
    assert 0 < half.nbytes <= budget
    hits = half.hits
    run_case(_case((10.0, 12.0)), catalog_dir, batch_nodes=20_000, lines=half)
    assert half.hits - hits < hits


@given(st.integers(2, 10**6), st.floats(1.01, 2.0))
def test_ladder_rungs_are_even_shared_and_within_the_ratio(n, ratio):
    rung = ladder_rung(n, ratio)
    assert rung >= n and rung % 2 == 0
    assert rung <= ratio * n + 2.0
    assert ladder_rung(rung, ratio) == rung  # a rung is its own rung: counts between rungs share it
    assert ladder_rung(max(2, n - 1), ratio) <= rung


def test_the_ladder_shares_samples_and_keeps_hashes(catalog_dir):
    assert "angular_ladder" not in Resolution().model_dump()
    spc = Resolution(angular_ladder=1.5)

    def run(aspect):
        layout = program_request(kind="ring", points=8000, aspect=aspect)
        return run_case(Case(surface="small_sine", layout=layout, resolution=spc), catalog_dir)

    ra, rb = run(1.0), run(1.2)
    assert ra["table_cols"] != rb["table_cols"]
    assert ra["n_theta"] == rb["n_theta"] == ladder_rung(3 * ra["table_cols"], 1.5)


SPEC = """
surface: small_sine
layout: ring
resolution: {angular_ladder: 1.5}
axes: {points: [4000, 8000], aspect: [0.5, 1.0, 2.0, 4.0]}
"""


def test_a_sweep_with_shared_lines_equals_the_sweep_case_by_case(tmp_path, catalog_dir):
    spec = tmp_path / "ladder.yaml"
    spec.write_text(SPEC)
    _, sweep = load_sweep(str(spec), catalog_dir)
    keys = [case_lines(sweep, i, catalog_dir)[1] for i in range(8)]
    assert len(set(keys)) < len(keys)  # the ladder makes some cases share lines
    tasks = plan_tasks(sweep, list(range(8)), workers=2, catalog_folder=catalog_dir)
    assert sorted(i for t in tasks for i in t) == list(range(8))
    for key in set(keys):
        sharing = {i for i in range(8) if keys[i] == key}
        assert any(sharing <= set(t) for t in tasks), "cases on the same lines are one task"
    kw = {"scheduler": "synchronous", "catalog_folder": catalog_dir}
    shared = run_sweep(str(spec), tmp_path / "shared.zarr", line_cache_mb=512, **kw)
    alone = run_sweep(str(spec), tmp_path / "alone.zarr", line_cache_mb=0, **kw)
    assert shared.done == alone.done == 8
    assert sum(r["reused_batches"] for r in shared.rows) > 0
    assert sum(r["reused_batches"] for r in alone.rows) == 0
    a, b = xr.open_zarr(tmp_path / "shared.zarr").load(), xr.open_zarr(tmp_path / "alone.zarr").load()
    compared = 0
    for name, var in a.data_vars.items():
        if name in TIMING_VARS:
            continue
        if var.dtype.kind == "f":
            assert np.array_equal(var.values, b[name].values, equal_nan=True), name
        else:
            assert np.array_equal(var.values, b[name].values), name
        compared += 1
    assert compared > 10


def test_a_task_keeps_only_lines_another_of_its_cases_reads(tmp_path, catalog_dir):
    """Kept lines cost fresh memory per batch: a case whose lines no other case of its task
    simulates runs without the cache (nothing kept), the sharing cases through it."""
    from ftsweep.sweeps.executor import _LINE_CACHES, TaskSpec, run_task
    from ftsweep.sweeps.run import prepare_cube

    spec = tmp_path / "ladder.yaml"
    spec.write_text(SPEC)
    name, sweep = load_sweep(str(spec), catalog_dir)
    keys = [case_lines(sweep, i, catalog_dir)[1] for i in range(8)]
    shared = next(k for k in keys if keys.count(k) > 1)
    pair = [i for i in range(8) if keys[i] == shared][:2]
    lone = [i for i in range(8) if keys.count(keys[i]) == 1]
    assert lone, "the spec should have a case sharing its lines with none"
    out = tmp_path / "c.zarr"
    prepare_cube(name, sweep, out, False, catalog_dir)
    task = TaskSpec(str(out), sweep.model_dump_json(), str(catalog_dir), "run-lone", 512.0)
    run_task(task, lone[:1])
    assert _LINE_CACHES["run-lone"].nbytes == 0 and _LINE_CACHES["run-lone"].misses == 0
    task = TaskSpec(str(out), sweep.model_dump_json(), str(catalog_dir), "run-pair", 512.0)
    rows = run_task(task, pair)
    assert _LINE_CACHES["run-pair"].nbytes > 0 and rows[1]["reused_batches"] > 0


@pytest.mark.parametrize(
    "case",
    [
        Case(surface="lens_array", layout=program_request(kind="mesh", pitch=(16.0, 16.0))),
        # layered (2 layers on a 5 µm stroke): column k of the passes is the spiral's pass k + k0
        pytest.param(  # 9 s on 2 cores: the full command runs it, the quick one leaves it out
            Case(
                surface="lens_array",
                machine="fts-5um",
                layout=program_request(kind="mesh", pitch=(16.0, 16.0)),
            ),
            marks=pytest.mark.slow,
        ),
        Case(surface="lens_array", layout=program_request(kind="spiral", points_per_rev=200)),
    ],
    ids=["mesh", "layered-mesh", "spiral"],
)
def test_passes_left_out_beyond_a_rectangle_change_nothing(case, catalog_dir, monkeypatch):
    """A rectangle's rays stop at its edge plus the arc's reach (``lines._reach_um``): the
    record equals the one simulated out to the circumscribed circle, value for value."""
    from ftsweep.engine import lines
    from ftsweep.stages.interpolation import tables as interpolation

    held = []
    grid = interpolation.path_grid

    def spy(*args, **kw):
        g = grid(*args, **kw)
        held.append(g.first_revolution)
        return g

    monkeypatch.setattr(interpolation, "path_grid", spy)
    trimmed = run_case(case, catalog_dir)
    assert max(held) > 0  # passes were left out
    monkeypatch.setattr(lines, "_reach_um", lambda *a: math.inf)
    held.clear()
    whole = run_case(case, catalog_dir)
    assert max(held) == 0
    assert _same(trimmed, whole) == []
    assert trimmed["seconds_envelope"] > 0 and trimmed["pv_nm"] > 0
    assert case.machine != "fts-5um" or trimmed["n_layers"] > 1


def test_layered_passes_of_a_grid_left_out_are_those_of_the_whole_grid(catalog_dir):
    from ftsweep.engine.planning import control_table, layer_plan
    from ftsweep.simulate import resolve_case
    from ftsweep.stages.interpolation import tables as interpolation
    from ftsweep.stages.paths import layers

    case = Case(
        surface="lens_array", machine="fts-5um", layout=program_request(kind="mesh", pitch=(16.0, 16.0))
    )
    rcase = resolve_case(case, catalog_dir)
    table, _ = control_table(case, rcase.layout, rcase.surface_spec, rcase.nose_radius_um, catalog_dir)
    plan = layer_plan(rcase, table)
    assert plan is not None and plan.n_layers > 1
    lines = interpolation.line_angles(64)[5:9]
    args = (lines, rcase.rho0_um, rcase.feed_um, 2, 30.0)
    whole, part = interpolation.path_grid(*args), interpolation.path_grid(*args, reach_um=0.6 * rcase.rho0_um)
    k0 = part.first_revolution
    assert k0 > 0
    w = np.random.default_rng(3).uniform(
        table.min(), table.max(), (whole.ray_theta.size, int(whole.n_passes.max()))
    )
    want = layers.layered_pass_commands(plan, whole.ray_theta, whole.n_passes, w)[:, k0:]
    got = layers.layered_pass_commands(plan, part.ray_theta, part.n_passes, w[:, k0:].copy(), 0.0, k0)
    held = np.arange(got.shape[1])[None, :] < part.n_passes[:, None]
    assert np.array_equal(got[held], want[:, : got.shape[1]][held])
    wrong = layers.layered_pass_commands(plan, part.ray_theta, part.n_passes, w[:, k0:].copy())
    assert not np.array_equal(wrong[held], want[:, : got.shape[1]][held])  # the test can tell
