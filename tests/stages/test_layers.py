"""Layered trajectories for parts deeper than the stroke ([3])."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given
from hypothesis import strategies as st

from ftsweep.cli.main import main
from ftsweep.engine.case import Case, program_request
from ftsweep.engine.lines import LinePlan, _line_data, _machined, _table_of
from ftsweep.engine.planning import layer_plan
from ftsweep.engine.record import Timer
from ftsweep.simulate import resolve_case, run_case
from ftsweep.stages.interpolation import tables as interpolation
from ftsweep.stages.kinematics import dynamics
from ftsweep.stages.paths import layers
from ftsweep.stages.sampling.surfaces import FAMILIES
from ftsweep.sweeps.run import run_sweep
from ftsweep.tools.export import export, verify

PRISM = dict(surface="microprism", machine="fts-5um", cutting="microprism")


def prism_case(**kw) -> Case:
    return Case(**PRISM, layout=program_request(kind="mesh", points=40_000, aspect=1.0), **kw)


def zone_members(plan: layers.LayerPlan, phi: np.ndarray, k: int) -> np.ndarray:
    """Which of the angles ``phi`` lie on a segment of layer ``k``."""
    a, b = plan.segments_of(k)
    idx = np.searchsorted(a, phi, side="right") - 1
    return (idx >= 0) & (phi <= b[np.maximum(idx, 0)])


# ----------------------------------------------------------------------------- the plan
@given(
    seed=st.integers(0, 2**31),
    travel=st.floats(0.3, 3.0),
    margin_frac=st.floats(0.0, 0.3),
    n=st.integers(2, 3000),
)
def test_every_command_is_cut_by_its_zone_and_no_segment_leaves_its_zone(seed, travel, margin_frac, n):
    rng = np.random.default_rng(seed)
    phi = np.cumsum(rng.uniform(1e-3, 0.1, n))
    w = np.cumsum(rng.normal(0.0, 0.3, n)) + 2.0 * np.sin(phi)
    margin = margin_frac * travel

    def chunks():
        # uneven chunks: the plan must not depend on where the stream is split
        cut = rng.integers(1, n + 1)
        return [(phi[:cut], w[:cut]), (phi[cut:], w[cut:])] if cut < n else [(phi, w)]

    plan = layers.plan_layers(chunks, travel, margin, float(phi[-1]))
    zone = travel - margin
    assert plan.zone_um == pytest.approx(zone)
    assert np.all(np.diff(plan.offsets_um) > 0)  # the Z axis only retracts
    for k in range(plan.n_layers):
        a, b = plan.segments_of(k)
        assert np.all(b > a) and np.all(a[1:] >= b[:-1])
        bottom, top = plan.bottoms_um[k], plan.bottoms_um[k] + zone
        on = zone_members(plan, phi, k)
        # every command of the zone is cut by the zone's layer ...
        inside = (w >= bottom) & (w <= top)
        assert on[inside].all()
        # ... and no segment runs where the part stands above the zone
        assert np.all(w[on] <= top + 1e-9)
        # the servo stays within its travel
        assert 0.0 <= plan.stroke_used_um[k] <= travel + 1e-12
        # the layer starts where the (linear) command first enters the zone: the outermost
        # point of its outline, the spiral running inwards
        assert a[0] == pytest.approx(first_entry(phi, w, bottom, top), abs=1e-9)


def first_entry(phi: np.ndarray, w: np.ndarray, bottom: float, top: float) -> float:
    """Angle where the piecewise-linear command w(φ) first lies in [bottom, top]."""
    if bottom <= w[0] <= top:
        return float(phi[0])
    for i in range(phi.size - 1):
        lo, hi = min(w[i], w[i + 1]), max(w[i], w[i + 1])
        if lo <= top and hi >= bottom:
            level = bottom if w[i] < bottom else top
            return float(phi[i] + (level - w[i]) / (w[i + 1] - w[i]) * (phi[i + 1] - phi[i]))
    raise AssertionError("the command never enters the zone")


def test_a_span_within_the_travel_needs_one_layer_and_layers_needed_counts_zones():
    assert layers.layers_needed(4.9, 5.0, 0.25) == 1
    assert layers.layers_needed(25.75, 5.0, 0.25) == 6
    assert layers.layers_needed(9.5, 5.0, 0.25) == 2
    with pytest.raises(ValueError, match="margin"):
        layers.plan_layers(lambda: [(np.arange(3.0), np.arange(3.0))], 1.0, 1.0, 2.0)


# ----------------------------------------------------------------------------- the microprism of [3]
@pytest.fixture(scope="module")
def prism_runs():
    return {mode: run_case(prism_case(layers=mode)) for mode in ("auto", "off")}


def test_microprism_on_a_5um_stroke_plans_six_layers_within_their_zones(prism_runs):
    record = prism_runs["auto"]
    lay = record["layers"]
    assert record["feasible"] and record["n_layers"] == lay["n_layers"] >= 6
    assert np.all(np.diff(lay["offset_um"]) > 0)
    assert max(lay["stroke_used_um"]) <= 5.0 - 0.25 + 1e-9
    assert lay["stroke_extension"] == pytest.approx(25.75 / 5.0, rel=0.01)
    # the layers are cut one after the other: their machining adds up, and costs more than
    # one uninterrupted spiral (stops, and the spiral traversed again in every layer)
    assert record["machining_s"] == pytest.approx(sum(lay["time_s"]))
    assert record["machining_s"] > record["single_pass_s"]

    # each layer, checked on the commands the controller executes
    rcase = resolve_case(prism_case())
    table, _ = _table_of(rcase, None, None)
    plan = layer_plan(rcase, table)
    assert plan is not None
    k = dynamics.commands_per_revolution(rcase.machine.command_rate_hz, rcase.cutting.spindle_rpm)
    phi, w = (
        np.concatenate(v)
        for v in zip(
            *layers.command_stream(rcase.layout, table, rcase.rho0_um, rcase.feed_um, k), strict=True
        )
    )
    rho = rcase.rho0_um - rcase.feed_um * phi / (2 * math.pi)
    for j in range(plan.n_layers):
        on = zone_members(plan, phi, j)
        bottom = plan.bottoms_um[j]
        stroke = np.clip(w[on] - plan.offsets_um[j], 0.0, None)
        assert np.all(stroke <= plan.travel_um - 0.5 * plan.margin_um + 1e-9)
        # the start radius is the outermost radius of the part's outline inside the zone
        inside = (w >= bottom) & (w <= bottom + plan.zone_um)
        step = rcase.feed_um / k
        assert lay["start_radius_um"][j] == pytest.approx(rho[inside].max(), abs=step + 1e-9)


def test_the_segment_change_time_is_the_machines_unless_the_case_overrides_it(prism_runs):
    record = prism_runs["auto"]
    segments = record["layer_segments"]
    assert record["layer_change_s"] == 3.0  # fts-5um's stated layer_change_s
    assert record["layer_change_share"] == pytest.approx(3.0 * segments / record["machining_s"])
    quick = run_case(prism_case(layer_change_s=0.5))
    # the spindle's part of the time is the same; only the changes' part moves
    assert quick["machining_s"] == pytest.approx(record["machining_s"] - 2.5 * segments)
    assert quick["layer_change_share"] == pytest.approx(0.5 * segments / quick["machining_s"])
    assert quick["pv_nm"] == record["pv_nm"]
    assert prism_runs["off"]["layer_change_share"] == 0.0
    # unset, the key of a case is the one it had before the option existed
    assert "layer_change_s" not in prism_case().model_dump()
    with pytest.raises(ValueError, match="layer_change_s"):
        prism_case(layer_change_s=-1.0)


def test_layers_off_is_infeasible_naming_the_stroke(prism_runs):
    record = prism_runs["off"]
    assert not record["feasible"]
    assert "stroke 25.75 µm > travel 5 µm" in record["infeasible_reason"]
    assert "6 layers" in record["infeasible_reason"]
    assert record["n_layers"] == 1 and record["layers"] is None


def test_layered_prediction_equals_the_single_pass_on_the_prism(prism_runs):
    auto, off = prism_runs["auto"], prism_runs["off"]
    for name in ("pv_nm", "rms_nm", "error_min_nm", "error_max_nm"):
        assert auto[name] == pytest.approx(off[name], abs=0.1)


def test_layered_prediction_equals_the_single_pass_on_a_sine_through_a_short_stroke(module_catalog_dir):
    def run(mode):
        case = Case(
            surface="small_sine",
            machine="short-fts",
            layout=program_request(kind="ring", points=20_000, aspect=4.0),
            layers=mode,
        )
        return run_case(case, module_catalog_dir)

    auto, off = run("auto"), run("off")
    assert off["stroke_um"] > 0.8 and not off["feasible"]
    assert auto["n_layers"] >= 3 and auto["layer_stroke_um"] <= 0.8
    for name in ("pv_nm", "rms_nm", "error_min_nm", "error_max_nm"):
        assert auto[name] == pytest.approx(off[name], abs=0.1)


def test_a_z_error_per_retraction_shows_as_steps_of_that_error():
    e = 0.05
    rcase = resolve_case(prism_case())
    table, _ = _table_of(rcase, None, None)
    plan = layer_plan(rcase, table)
    lp = LinePlan.of(rcase, 400_000, 1e9)
    data = _line_data(rcase, lp, lp.batch(0), Timer())
    grid = data.grid
    w = interpolation.pass_commands(rcase.layout, table, grid)
    z = [
        _machined(grid, layers.layered_pass_commands(plan, grid.ray_theta, grid.n_passes, w, err), lp, 50.0)[
            0
        ]
        for err in (0.0, e)
    ]
    ok = np.isfinite(z[0]) & np.isfinite(z[1])
    diff = (z[1] - z[0])[ok]
    # never more than the retractions before the last layer, and never the other way
    assert diff.max() <= 1e-9 and diff.min() >= -(plan.n_layers - 1) * e - 1e-9
    steps = np.rint(-diff / e)
    on_step = np.abs(diff + steps * e) <= 1e-9
    assert on_step.mean() >= 0.8  # off a step only where two layers' passes meet
    assert len(np.unique(steps[on_step])) >= 4

    # the P-V of the whole part moves by at most those steps
    base = run_case(prism_case())
    shifted = run_case(prism_case(z_error_um=e))
    assert shifted["z_error_um"] == e and shifted["layers"]["z_shift_um"][-1] == pytest.approx(-5 * e)
    assert 0.0 < shifted["pv_nm"] - base["pv_nm"] <= (plan.n_layers - 1) * e * 1e3 + 0.1


# ----------------------------------------------------------------------------- export and CLI
def test_a_layered_header_round_trips_through_verify(tmp_path):
    spec = tmp_path / "prism.yaml"
    spec.write_text(
        "surface: microprism\nlayout: mesh\nmachine: fts-5um\ncutting: microprism\n"
        "axes: {points: [40000], aspect: [1.0]}\n"
    )
    cube_path = tmp_path / "prism.zarr"
    run_sweep(str(spec), cube_path, scheduler="synchronous")
    header = tmp_path / "prism.h"
    meta = export(cube_path, header, index=0)
    schedule = meta["layers"]
    assert schedule["n_layers"] >= 6 and len(schedule["segment_phi_deg"]) == len(schedule["segment_layer"])
    text = header.read_text()
    assert "#define PRISM_N_LAYERS" in text and "#define PRISM_LAYER_OFFSETS_UM {" in text
    record = verify(header)
    assert record["n_layers"] == schedule["n_layers"]
    assert abs(record["pv_nm"] - record["predicted_pv_nm"]) <= record["pv_tolerance_nm"]
    # an edited schedule is refused: tests/exports/test_verified_is_executed.py (layer offsets forged)


def test_predict_cli_reports_the_layers_and_refuses_them_off():
    args = [
        "predict",
        *sum(([f"--{k}", v] for k, v in PRISM.items()), []),
        "--points",
        "40000",
        "--aspect",
        "1",
    ]
    r = CliRunner().invoke(main, [*args, "--json"])
    assert r.exit_code == 0, r.output
    record = json.loads(r.output)
    lay = record["layers"]
    for key in ("offset_um", "start_radius_um", "stroke_used_um", "spiral_length_um", "time_s"):
        assert len(lay[key]) == lay["n_layers"]
    assert lay["total_time_s"] == pytest.approx(record["machining_s"])
    r = CliRunner().invoke(main, [*args, "--layers", "off", "--json"])
    assert r.exit_code == 0, r.output
    off = json.loads(r.output)
    assert off["feasible"] is False and "stroke" in off["infeasible_reason"] and off["layers"] is None
    r = CliRunner().invoke(main, args)
    assert "layers       6 zones of 4.75 µm" in r.output


# ----------------------------------------------------------------------------- the surface
@given(x=st.floats(-300, 300), y=st.floats(-300, 300), faces=st.integers(3, 8))
def test_microprism_is_a_pyramid_of_planar_faces(x, y, faces):
    fam = FAMILIES["microprism"]
    params = dict(height_um=25.75, base_um=400.0, faces=faces)
    f, fx, fy = fam.evaluate(np.array([x, 0.0]), np.array([y, 0.0]), **params)
    assert f[1] == pytest.approx(25.75)  # apex on the axis
    # the lowest of the face planes, cut off by the base plane
    angles = 2 * math.pi * np.arange(faces) / faces
    proj = np.sort(x * np.cos(angles) + y * np.sin(angles))
    assert f[0] == pytest.approx(max(0.0, 25.75 * (1 - proj[-1] / 200.0)), abs=1e-12)
    slope = math.hypot(fx[0], fy[0])
    assert slope == pytest.approx(0.0 if f[0] == 0.0 else 2 * 25.75 / 400.0)
    assert slope <= fam.gradient_bound(height_um=25.75, base_um=400.0) + 1e-12
    # away from the ridges and the base edge, the gradient is the face's (finite difference)
    d = 1e-4
    if proj[-1] - proj[-2] > 10 * d and f[0] > 1.0:
        fp, *_ = fam.evaluate(np.array([x + d, x]), np.array([y, y + d]), **params)
        assert (fp[0] - f[0]) / d == pytest.approx(fx[0], abs=1e-6)
        assert (fp[1] - f[0]) / d == pytest.approx(fy[0], abs=1e-6)


def test_microprism_faces_are_checked():
    with pytest.raises(ValueError, match="3 to 64 faces"):
        FAMILIES["microprism"].evaluate(np.zeros(1), np.zeros(1), height_um=1.0, base_um=1.0, faces=2)


def test_catalog_entries_of_the_layered_example():
    from ftsweep.inputs.catalogs import entry

    machine = entry("machines", "fts-5um")
    assert machine.travel_um == 5.0 and 0.0 < machine.layer_margin_um < machine.travel_um
    surface = entry("surfaces", "microprism")
    assert surface.params.height_um == 25.75


def test_a_layered_spiral_program_round_trips_through_verify(tmp_path, catalog_dir, monkeypatch):
    monkeypatch.setenv("FTSWEEP_CATALOGS", str(catalog_dir))
    spec = tmp_path / "sine.yaml"
    spec.write_text(
        "surface: small_sine\nlayout: spiral\nmachine: short-fts\naxes: {points_per_rev: [120]}\n"
    )
    cube_path = tmp_path / "sine.zarr"
    run_sweep(str(spec), cube_path, scheduler="synchronous", catalog_folder=catalog_dir)
    out = tmp_path / "sine.txt"
    meta = export(cube_path, out, index=0)
    assert meta["layers"]["n_layers"] >= 3
    text = out.read_text()
    assert "# layers: " in text and text.count("# segment: layer ") == len(meta["layers"]["segment_layer"])
    record = verify(out)
    assert record["n_layers"] == meta["layers"]["n_layers"]
    assert abs(record["pv_nm"] - record["predicted_pv_nm"]) <= record["pv_tolerance_nm"]
