"""D-shaped slow-tool-servo paths ([5] = seed 004): planner, junctions, X motion, form error
through the engine's envelope, Z motion against the spiral, export and verify, sweeps."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from ftsweep.engine.case import Case, CaseError, program_request
from ftsweep.exports.programs import read_program
from ftsweep.inputs.catalogs import CatalogError
from ftsweep.kinds.dpath import format as program
from ftsweep.kinds.dpath import study as dstudy
from ftsweep.simulate import run_case
from ftsweep.stages.interpolation import rays
from ftsweep.stages.kinematics import axes as kinematics
from ftsweep.stages.paths import dpath, dpath_motion
from ftsweep.tools.export import ExportError, verify

# [5]'s example: l = s = 20 mm, zone centre 30 mm from the C axis (outer edge 40 mm), 40 rpm
SEED = {"length_um": 20000.0, "width_um": 20000.0, "outer_um": 40000.0, "zones": 1}


def seed_path(transition: str, spacing_um: float = 100.0, ppc: int = 201) -> dpath.DPath:
    return dpath.plan(dpath.DGeometry(spacing_um=spacing_um, transition=transition, **SEED), ppc, 1.0)


def x_motion(path: dpath.DPath, rpm: float = 40.0) -> dict[str, np.ndarray]:
    z = np.zeros(path.n_points)
    return dpath_motion.axis_motion(
        dpath_motion.point_times(path.phi, path.rho, z, "spindle", rpm), path.phi, path.rho, z
    )


def test_seed_example_optimised_acceleration_is_a_fraction_of_the_traditional_and_on_the_cuts():
    trad, opt = seed_path("traditional"), seed_path("optimised")
    a_trad = np.abs(x_motion(trad)["x_accel_m_s2"])
    a_opt = np.abs(x_motion(opt)["x_accel_m_s2"])
    ratio = a_opt.max() / a_trad.max()
    # [5] reports 0.16; the traditional spike is the slope jump over the C step at the junction
    assert ratio <= 0.3
    on = opt.cut >= 0
    assert a_opt[on].max() >= a_opt[~on].max()
    # the spike (kinematics stage, [2] eq. 14): the X velocity jump ω·Δ(dρ/dθ) at the junction
    # over the mean of the two C steps either side, ω²·Δ(dρ/dθ)/(½(Δθ₁+Δθ₂)); it grows as the
    # step shrinks; within 10 %: the cut's own acceleration adds to it
    omega = 40.0 * 2.0 * math.pi / 60.0
    end = int(np.flatnonzero(trad.cut == 0)[-1])
    span = trad.phi[end + 1] - trad.phi[end - 1]
    jump = abs(dpath_motion.junctions(trad)["jump_d1"][0])
    expected = omega**2 * jump / (0.5 * span) * 1e-6
    assert abs(a_trad[end] - expected) <= 0.1 * expected
    # the cuts' analytic acceleration, ω²·d(sec tan² + sec³), bounds the optimised peak
    half = math.atan(10.0 / 40.0)
    sec = 1.0 / math.cos(half)
    cut_peak = omega**2 * 40000.0 * sec * (math.tan(half) ** 2 + sec**2) * 1e-6
    assert a_opt.max() <= cut_peak * 1.01


@settings(max_examples=30, deadline=None)
@given(
    a=st.floats(-50.0, 50.0),
    b=st.floats(-1e-2, 1e-2),
    c=st.floats(-1e-6, 1e-6),
    transition=st.sampled_from(dpath.TRANSITIONS),
    ppc=st.integers(3, 30),
)
def test_planned_z_is_exact_for_z_quadratic_along_the_cuts(a, b, c, transition, ppc):
    # Z = a + b·u + c·u² on every cut (u along it), linear in θ across the transitions ([5]
    # eq. 14): the planned path between the points is that quadratic and that line
    path = seed_path(transition, spacing_um=2000.0, ppc=ppc)
    on = path.cut >= 0
    i = path.cut[on]
    u = path.cut_d[i] * np.tan(path.phi[on] - path.cut_centre[i])
    z = dpath_motion.transition_z(path, a + b * u + c * u**2)
    phi = np.linspace(path.phi[0], path.phi[-1], 5001)
    rho, _, _, on_cut = dpath.evaluate(path, phi)
    got = dpath_motion.planned_z(path, z, phi)
    seg = np.clip(np.searchsorted(path.bounds, phi[on_cut], side="right") - 1, 0, path.bounds.size - 1)
    k = np.minimum(seg // 2, path.n_cuts - 1)
    uu = path.cut_d[k] * np.tan(phi[on_cut] - path.cut_centre[k])
    assert np.allclose(got[on_cut], a + b * uu + c * uu**2, rtol=0.0, atol=1e-9)
    assert np.allclose(got[~on_cut], np.interp(phi[~on_cut], path.phi, z), rtol=0.0, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(
    first=st.floats(-1e4, 1e4),
    length=st.floats(0.0, 1e4),
    n=st.integers(3, 5000),
    cut=st.integers(0, 5000),
)
def test_period_times_a_stretch_at_a_time_are_linspace_own(first, length, n, cut):
    # the controller-period grid taken in stretches: the same values as one linspace
    whole = np.linspace(first, first + length, n)
    cut = min(cut, n)
    parts = [
        dpath_motion.period_times(first, first + length, n, 0, cut),
        dpath_motion.period_times(first, first + length, n, cut, n),
    ]
    np.testing.assert_array_equal(np.concatenate(parts), whole)


@pytest.mark.parametrize("transition", ["traditional", "optimised"])
def test_motion_extremes_taken_a_stretch_at_a_time_are_those_of_the_samples(monkeypatch, transition):
    # the streamed extremes of the motion every controller period (stretches of 1,000 samples
    # with their neighbours) are those of the whole sampled arrays, first points included
    from ftsweep.kinds.dpath import program as dprog

    path = seed_path(transition, spacing_um=500.0, ppc=21)
    z = 1e-3 * (path.rho - path.rho.mean()) ** 2 / 1e4
    t = dpath_motion.point_times(path.phi, path.rho, z, "spindle", 40.0)
    s = dpath_motion.at_period(path, z, t, 1e-3)
    want = kinematics.extremes(dprog.axes_of(s), kinematics.steps_of(s.t), s.on_cut, 2)
    monkeypatch.setattr(dprog, "SAMPLE_BLOCK", 1000)
    samples, got, (x_min, x_max) = dprog.sampled_extremes(path, z, t, 1e-3)
    assert samples.n == s.t.size > 5000
    for name, value in want._asdict().items():
        np.testing.assert_array_equal(getattr(got, name), value, err_msg=name)
    assert (x_min, x_max) == (s.rho.min(), s.rho.max())
    for i in (0, 999, 1000, 4321, s.t.size - 1):
        assert samples.time(i) == s.t[i] and samples.line(i) == s.line(i)


def test_motion_at_the_controller_period_samples_the_planned_path():
    # at constant spindle speed the samples are a period apart in time and ω·T in C, on the
    # analytic path; smooth stretches read ω²·d²ρ/dθ², not the polyline's kinks
    path = seed_path("optimised", spacing_um=500.0, ppc=21)
    z = np.zeros(path.n_points)
    omega = 40.0 * 2.0 * math.pi / 60.0
    t = dpath_motion.point_times(path.phi, path.rho, z, "spindle", 40.0)
    s = dpath_motion.at_period(path, z, t, 1e-3)
    assert np.diff(s.t).max() <= 1e-3 + 1e-12
    assert np.allclose(np.diff(s.phi), omega * np.diff(s.t), rtol=1e-9)
    assert np.allclose(s.rho, dpath.evaluate(path, s.phi)[0])
    from ftsweep.kinds.dpath import program as dprog

    _, _, m = dprog.sampled_motion(path, z, t, 1e-3)
    d2 = dpath.evaluate(path, s.phi)[2]
    inner = slice(1, -1)
    # within 2e-3 m/s² (0.25 % of the peak): the third derivative jumps at the junctions
    assert np.allclose(m.accel[inner, 1], omega**2 * d2[inner] * 1e-6, rtol=0.0, atol=2e-3)
    # why the planned path: the polyline of 21 points a cut, sampled a period apart, reads its
    # kinks (the slope change at a point over one period), several times the curve's value
    from ftsweep.stages.kinematics import axes as kinematics

    poly = np.interp(s.phi, path.phi, path.rho) * 1e-6
    a_poly = kinematics.motion(s.t, np.column_stack([s.phi, poly, s.z]))[2][:, 1]
    assert np.abs(a_poly).max() > 2.0 * np.abs(m.accel[:, 1]).max()


@settings(max_examples=25, deadline=None)
@given(
    length=st.floats(2000.0, 30000.0),
    width=st.floats(2000.0, 30000.0),
    gap=st.floats(5000.0, 60000.0),
    spacing=st.floats(50.0, 2000.0),
    zones=st.sampled_from([1, 2, 4]),
)
def test_optimised_junctions_are_continuous_to_third_order(length, width, gap, spacing, zones):
    g = dpath.DGeometry(length, width, gap + width, spacing, zones, "optimised")
    try:
        dpath.check_geometry(g)
    except ValueError:
        return  # zones that do not fit are refused, tested below
    path = dpath.plan(g, 5, 5.0)
    j = dpath_motion.junctions(path)
    for name in ("rho", "d1", "d2"):
        scale = max(float(np.abs(j[name]).max()), 1e-300)
        assert float(np.abs(j[f"jump_{name}"]).max()) <= 1e-9 * scale
    # the analytic path and the points agree on the points
    rho, _, _, _ = dpath.evaluate(path, path.phi)
    assert np.allclose(rho, path.rho, rtol=0, atol=1e-6 * path.rho.max())


def test_traditional_junctions_keep_the_radius_and_jump_in_slope():
    path = seed_path("traditional")
    j = dpath_motion.junctions(path)
    assert np.abs(j["jump_rho"]).max() <= 1e-9 * j["rho"].max()
    # the slope of the cut at its end, ρ·tan a, against the arc's (nearly) zero
    assert np.abs(j["jump_d1"]).min() > 0.9 * 40000.0 * 0.25


def test_cuts_are_straight_parallel_lines_at_the_spacing():
    path = seed_path("optimised", spacing_um=500.0, ppc=11)
    on = path.cut >= 0
    x = path.rho[on] * np.cos(path.phi[on] - path.cut_centre[path.cut[on]])
    d = path.cut_d[path.cut[on]]
    assert np.allclose(x, d, atol=1e-9)
    assert path.n_cuts == math.floor(20000.0 / 500.0) + 1
    assert np.allclose(-np.diff(path.cut_d), 500.0)
    assert np.all(np.diff(path.phi) > 0)


def test_zone_geometry_is_checked():
    with pytest.raises(ValueError, match="reaches the C axis"):
        dpath.check_geometry(dpath.DGeometry(20000.0, 20000.0, 15000.0, 10.0, 1, "optimised"))
    with pytest.raises(ValueError, match="zones do not fit"):
        dpath.check_geometry(dpath.DGeometry(20000.0, 20000.0, 22000.0, 10.0, 4, "optimised"))
    with pytest.raises(ValueError, match="spacing"):
        dpath.check_geometry(dpath.DGeometry(20000.0, 200.0, 40000.0, 500.0, 1, "optimised"))


def test_transition_z_is_linear_between_cuts():
    path = seed_path("optimised", spacing_um=2000.0, ppc=5)
    on = path.cut >= 0
    z = dpath_motion.transition_z(path, np.arange(on.sum(), dtype=float))
    first = int(np.flatnonzero(~on)[0])
    a, b = first - 1, int(np.flatnonzero(on[first:])[0]) + first
    expected = z[a] + (z[b] - z[a]) * (path.phi[first:b] - path.phi[a]) / (path.phi[b] - path.phi[a])
    assert np.allclose(z[first:b], expected)


def d_case(surface: str = "concave_sphere", **options) -> Case:
    return Case(
        surface=surface,
        layout=program_request(kind="dpath", **options),
        machine="sts-xzc",
        cutting="dpath-finish",
    )


def test_both_transitions_share_their_compensated_cuts_and_nothing_else(monkeypatch):
    # the D-path study plans both transitions in shared_cuts: one compensation of the common
    # cuts, values bit for bit those of plans made apart; another part is solved anew
    from ftsweep.kinds.dpath import kind as dpath_kind
    from ftsweep.simulate import resolve_case

    apart = {t: resolve_case(d_case(spacing_um=100.0, transition=t)) for t in dstudy.TRANSITIONS}
    calls = []
    solve = dpath_kind.compensate_in_parts
    monkeypatch.setattr(dpath_kind, "compensate_in_parts", lambda *a: calls.append(1) or solve(*a))
    with dpath_kind.shared_cuts():
        shared = {t: resolve_case(d_case(spacing_um=100.0, transition=t)) for t in dstudy.TRANSITIONS}
        assert len(calls) == 1
        resolve_case(d_case(spacing_um=100.0, transition="optimised", offaxis_um=31000.0))
        assert len(calls) == 2  # other cuts: compensated on their own
    resolve_case(d_case(spacing_um=100.0, transition="optimised"))
    assert len(calls) == 3  # outside the block nothing is kept
    for t in dstudy.TRANSITIONS:
        assert np.array_equal(shared[t].values, apart[t].values)
        assert np.array_equal(shared[t].gouge, apart[t].gouge)
    # the paths differ (in their transitions' radii) where their commands need not
    assert not np.array_equal(shared["traditional"].layout.rho, shared["optimised"].layout.rho)


def test_sphere_form_error_matches_the_spiral_within_the_cusp_and_never_cuts_below():
    spacing = 20.0
    record = run_case(d_case(spacing_um=spacing))
    assert record["error_min_nm"] >= -1e-3  # exact compensation: no arc below the design
    spiral = run_case(dstudy.spiral_case(d_case(spacing_um=spacing), record))
    assert abs(record["pv_nm"] - spiral["pv_nm"]) <= record["cusp_nm"]
    # the cusps between cuts: h²/(8Rc) on the rays normal to the cuts, up to 1/cos² off them
    # (the cuts cross the rays h/cos apart), plus the chords between a cut's points
    corner = math.atan(10.0 / 20.0)
    top = record["cusp_nm"] / math.cos(corner) ** 2 + record["pv_interp_nm"] + 1.0
    assert record["cusp_nm"] * 0.9 <= record["pv_nm"] <= top


def test_cylinder_array_d_path_z_velocity_is_far_below_the_spiral():
    case = d_case("integral_mirror", spacing_um=100.0, points_per_cut=101)
    record = run_case(case)
    spiral = dstudy.spiral_motion(dstudy.spiral_case(case, record))
    ratio = record["w_velocity_peak_mm_s"] / float(np.abs(spiral["z_velocity_mm_s"]).max())
    assert ratio < 0.01
    assert record["gouge_points"] == 0


def test_layout_options_are_checked():
    with pytest.raises(ValueError, match="D-path"):
        program_request(kind="spiral", arc_um=10.0, spacing_um=5.0)
    with pytest.raises(ValueError, match="takes no"):
        program_request(kind="dpath", points=1000.0)
    with pytest.raises(CaseError, match="reaches the C axis"):
        run_case(d_case(offaxis_um=5000.0, spacing_um=500.0))
    with pytest.raises(CatalogError):
        run_case(Case(surface="concave_sphere", layout=program_request(kind="dpath"), machine="nope"))


def test_export_lines_stay_within_the_axis_limits_and_verify(tmp_path):
    from ftsweep.engine.planning import resolve_specs

    case = d_case(spacing_um=500.0, points_per_cut=41)
    record = run_case(case)
    out, side = tmp_path / "p.txt", tmp_path / "p.json"
    meta = program.export_dpath(out, side, case, resolve_specs(case), record, {})
    _, data = read_program(out, program.D_MAGIC, program.D_COLUMNS)
    lim = resolve_specs(case)[1].axes
    assert data.shape == (meta["n_points"], 4)
    assert lim.x_min_mm <= data[:, 2].min() and data[:, 2].max() <= lim.x_max_mm
    assert lim.z_min_mm <= data[:, 3].min() and data[:, 3].max() <= lim.z_max_mm
    assert np.all(np.diff(data[:, 0]) > 0)
    checked = verify(out)
    assert abs(checked["pv_nm"] - record["pv_nm"]) <= checked["pv_tolerance_nm"]
    # the motion re-simulated from the file's lines (their C, X and times) is the planned one:
    # times printed to 1 ns move the sampled C by up to ω·0.5 ns, which the second differences
    # over the 1 ms controller period turn into ~1e-5 of an acceleration
    assert checked["feasible"] == record["feasible"] == 1 and checked["infeasible_reason"] == ""
    for k, rel in (("x_max_um", 1e-9), ("x_feed_peak_mm_s", 1e-6), ("x_accel_peak_m_s2", 1e-4)):
        assert checked[k] == pytest.approx(record[k], rel=rel), k
    # a changed line is refused
    text = out.read_text().splitlines()
    text[-1] = text[-1][:-1] + ("1" if text[-1][-1] != "1" else "2")
    out.write_text("\n".join(text) + "\n")
    with pytest.raises(ExportError, match="CRC32"):
        verify(out)


def test_export_refuses_a_program_beyond_the_machine(tmp_path):
    from ftsweep.engine.planning import resolve_specs

    case = d_case(spacing_um=500.0, points_per_cut=41)
    record = run_case(case)
    specs = resolve_specs(case)
    surface, machine, cutting = specs
    tight = machine.model_copy(update={"axes": machine.axes.model_copy(update={"x_max_mm": 60.0})})
    with pytest.raises(ExportError, match="X .* > limit 60 mm"):
        program.export_dpath(
            tmp_path / "p.txt", tmp_path / "p.json", case, specs._replace(machine=tight), record, {}
        )
    assert not (tmp_path / "p.txt").exists()
    # accelerations: the record's figure, on the planned path every controller period
    slow = machine.model_copy(update={"axes": machine.axes.model_copy(update={"x_accel_m_s2": 0.5})})
    assert record["x_accel_peak_m_s2"] > 0.5
    with pytest.raises(ExportError, match=r"X acceleration ([0-9.]+) m/s² > limit 0.5 m/s² \(line \d+, t = "):
        program.export_dpath(
            tmp_path / "p.txt", tmp_path / "p.json", case, specs._replace(machine=slow), record, {}
        )
    loose = machine.model_copy(
        update={"axes": machine.axes.model_copy(update={"x_accel_m_s2": 1.001 * record["x_accel_peak_m_s2"]})}
    )
    program.export_dpath(
        tmp_path / "p.txt", tmp_path / "p.json", case, specs._replace(machine=loose), record, {}
    )


def test_verify_refuses_lines_beyond_the_machine_from_the_record_of_their_own_motion(tmp_path, monkeypatch):
    # verify's limits check is the re-simulated record's motion (the lines' C, X and times):
    # a machine whose X acceleration limit lies below the program's refuses it, naming line
    # and time, and the record of a program within the limits carries no reason
    from ftsweep.engine.planning import resolve_specs
    from ftsweep.inputs.catalogs import AxisLimits

    case = d_case(spacing_um=500.0, points_per_cut=41)
    record = run_case(case)
    out = tmp_path / "p.txt"
    program.export_dpath(out, tmp_path / "p.json", case, resolve_specs(case), record, {})
    assert verify(out)["infeasible_reason"] == ""
    real = AxisLimits.limits

    def slower(self, names):
        got = real(self, names)
        return got._replace(
            accel=np.where(np.array(names) == "X", 0.5 * record["x_accel_peak_m_s2"], got.accel)
        )

    monkeypatch.setattr(AxisLimits, "limits", slower)
    with pytest.raises(
        ExportError, match=r"leaves the axis limits .*X acceleration .* \(line \d+, t = .*do not run it"
    ):
        verify(out)


@pytest.mark.slow  # 7-15 s on 2 cores: the full command runs it, the quick one leaves it out
def test_dpath_sweep_is_scheduler_independent_and_compares(tmp_path):
    from ftsweep.sweeps.run import run_sweep
    from ftsweep.tools.compare import compare_rows

    spec = {
        "surface": "concave_sphere",
        "layout": "dpath",
        "machine": "sts-xzc",
        "cutting": "dpath-finish",
        "dpath": {"transition": "optimised"},
        "axes": {"spacing_um": [250.0, 500.0], "points_per_cut": [21, 41]},
    }
    path = tmp_path / "d.yaml"
    path.write_text(json.dumps(spec))
    run_sweep(str(path), tmp_path / "a.zarr", scheduler="synchronous")
    run_sweep(str(path), tmp_path / "b.zarr", workers=2)
    import xarray as xr

    a, b = xr.open_zarr(tmp_path / "a.zarr").load(), xr.open_zarr(tmp_path / "b.zarr").load()
    for var in ("pv_nm", "rms_nm", "x_accel_peak_m_s2", "n_points"):
        assert np.array_equal(a[var].values, b[var].values, equal_nan=True)
    assert a["pv_nm"].dims == ("spacing_um", "points_per_cut")
    rows, _ = compare_rows([tmp_path / "a.zarr"])
    assert {r["program"].split()[0] for r in rows} == {"dpath"}


def test_dpath_cli_json_reports_the_ratio(tmp_path):
    from click.testing import CliRunner

    from ftsweep.cli.main import main

    res = CliRunner().invoke(
        main,
        ["dpath", "--spacing-um", "500", "--points-per-cut", "41", "--plots", str(tmp_path), "--json"],
    )
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    assert 0.0 < out["x_accel_ratio"] <= 0.3
    assert out["x_accel_max_on_cut"] is True
    # over a C step h on the planned curves: the traditional spike is the slope jump over h
    # (h·peak constant within 5 % up to 1°, the cut's own curvature aside), the optimised peak
    # the cuts' analytic ω²·d·sec·(tan² + sec²) within 2 %; [5]'s 0.16 needs h ≈ 2°
    table = out["x_accel_by_step"]
    small = [r for r in table["rows"] if r["step_deg"] <= 1.0]
    spike = [r["traditional_m_s2"] * r["step_deg"] for r in small]
    assert max(spike) <= 1.05 * min(spike)
    omega = 40.0 * 2.0 * math.pi / 60.0
    half = math.atan(10.0 / 40.0)
    sec = 1.0 / math.cos(half)
    cut_peak = omega**2 * 40000.0 * sec * (math.tan(half) ** 2 + sec**2) * 1e-6
    assert all(r["optimised_m_s2"] == pytest.approx(cut_peak, rel=0.02) for r in small)
    assert 1.5 <= table["paper_ratio_step_deg"] <= 3.0
    # the record's figures are formed over the machine's own step: one controller period
    # (sts-xzc: 1 kHz) at 40 rpm, 0.24°, a row of the table
    assert out["accel_period_s"] == pytest.approx(1e-3)
    assert out["accel_step_deg"] == pytest.approx(math.degrees(omega * 1e-3))
    machine_row = [r for r in table["rows"] if r["machine"]]
    assert len(machine_row) == 1 and machine_row[0]["step_deg"] == pytest.approx(out["accel_step_deg"])
    assert out["optimised"]["x_accel_peak_m_s2"] == pytest.approx(cut_peak, rel=0.02)
    # the spike read on samples a period apart: the junction falls between two samples, so
    # between half and all of the slope jump over the step
    spike_h = machine_row[0]["traditional_m_s2"]
    assert 0.5 * spike_h <= out["traditional"]["x_accel_peak_m_s2"] <= 1.001 * spike_h
    assert out["optimised"]["d2_rel_jump"] <= 1e-9
    assert out["traditional"]["slope_jump_um_rad"] > 0.0
    assert out["spiral"]["pv_nm"] > 0.0
    # constant feed (docs/kinds.md, DIFFSYS): along the whole path the optimised C speed changes
    # smoothly, the traditional jumps at the junctions; on the cuts only, the transitions run
    # at the C cap (40 rpm) and both paths take the same time
    whole = {k: out[k]["feed_mode"] for k in ("traditional", "optimised")}
    cuts = {k: out[k]["feed_mode_cuts"] for k in ("traditional", "optimised")}
    assert whole["optimised"]["c_speed_jump_rpm"] < 0.5 * whole["traditional"]["c_speed_jump_rpm"]
    assert whole["optimised"]["time_s"] > whole["traditional"]["time_s"]
    for f in cuts.values():
        assert f["c_speed_max_rpm"] == pytest.approx(40.0)
        assert f["c_speed_cut_max_rpm"] < 40.0
    assert cuts["optimised"]["time_s"] == pytest.approx(cuts["traditional"]["time_s"], rel=0.01)
    for plot in out["plots"]:
        assert (tmp_path / plot.split("/")[-1]).stat().st_size > 0


def test_predict_takes_a_d_path_and_refuses_the_options_of_other_kinds():
    from click.testing import CliRunner

    from ftsweep.cli.main import main

    base = ["predict", "--surface", "concave_sphere", "--layout", "dpath", "--machine", "sts-xzc"]
    args = [*base, "--cutting", "dpath-finish", "--spacing-um", "500", "--points-per-cut", "21"]
    res = CliRunner().invoke(main, [*args, "--json"])
    assert res.exit_code == 0, res.output
    record = json.loads(res.stdout)
    assert record["layout"] == "dpath" and record["n_cuts"] == 41 and record["pv_nm"] > 0
    assert record == {**record, **{"spacing_um": 500.0, "points_per_cut": 21}}
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 0 and "D path: 13,718 points, 41 cuts of 21 points" in res.output, res.output
    res = CliRunner().invoke(main, [*args, "--points-per-rev", "100"])
    assert (
        res.exit_code != 0
        and "--points-per-rev belongs to spiral programs (--layout spiral), not to a D-path" in res.output
    )
    res = CliRunner().invoke(
        main, ["predict", "--surface", "sinewave2d", "--spacing-um", "5", "--points", "1e4"]
    )
    assert res.exit_code != 0 and "--spacing-um belongs to D-path programs" in res.output


def test_evaluate_walks_increasing_angles_and_searches_others_alike():
    # the kernel walks increasing angles along the junctions and searches the others afresh
    path = seed_path("optimised", spacing_um=500.0, ppc=21)
    phi = np.random.default_rng(0).uniform(path.phi[0], path.phi[-1], 2000)
    order = np.argsort(phi)
    walked, searched = dpath.evaluate(path, phi[order]), dpath.evaluate(path, phi)
    for w, s in zip(walked, searched, strict=True):
        assert np.array_equal(w, s[order])
    # at a junction (a bound exactly) the cut's value: [5] eq. 3 at the cut's end angle
    rho, d1, _, on_cut = dpath.evaluate(path, path.bounds)
    assert on_cut.all()
    cut = np.repeat(np.arange(path.n_cuts), 2)
    x = path.bounds - path.cut_centre[cut]
    assert np.allclose(rho, path.cut_d[cut] / np.cos(x), rtol=1e-14)
    assert np.allclose(d1, path.cut_d[cut] * np.tan(x) / np.cos(x), rtol=1e-12)


@pytest.mark.parametrize("transition", ["traditional", "optimised"])
@pytest.mark.parametrize("step_deg", [0.05, 1.0, 30.0, 1e4])
def test_peak_acceleration_at_a_step_is_the_largest_of_the_points(transition, step_deg):
    # one compiled pass over blocks: the largest of ω²|ρ(φ+h) − 2ρ(φ) + ρ(φ−h)|/h² at the
    # points whose φ ± h stay on the program, to the last bit (0 when none does)
    path = seed_path(transition, spacing_um=500.0, ppc=21)
    h = math.radians(step_deg)
    want, any_point = _every_points_peak(path, h)
    assert dpath_motion.x_accel_peak_at_step(path, 40.0, h) == want
    assert (want > 0.0) == any_point


def _every_points_peak(path: dpath.DPath, h: float) -> tuple[float, bool]:
    """ω²|ρ(φ+h) − 2ρ(φ) + ρ(φ−h)|/h² [m/s²] at 40 rpm, largest over every point whose φ ± h
    stay on the program (0 when none does), each evaluated; and whether any does."""
    omega = 40.0 * 2.0 * math.pi / 60.0
    ok = (path.phi - h >= path.phi[0]) & (path.phi + h <= path.phi[-1])
    p = path.phi[ok]
    mid, ahead, behind = (dpath.radius_at(path, p + d)[0] for d in (0.0, h, -h))
    return np.abs(omega**2 * (ahead - 2.0 * mid + behind) / h**2 * 1e-6).max(initial=0.0), bool(ok.any())


def _random_path(transition, zones, length_mm, width_mm, inner_mm, spacing_fraction, ppc):
    geometry = dpath.DGeometry(
        length_um=length_mm * 1e3,
        width_um=width_mm * 1e3,
        outer_um=(inner_mm + width_mm) * 1e3,
        spacing_um=max(spacing_fraction * width_mm * 1e3, 300.0),
        zones=zones,
        transition=transition,
    )
    try:
        dpath.check_geometry(geometry)
    except ValueError:
        assume(False)  # zones that do not fit a revolution: refused by the planner
    return dpath.plan(geometry, ppc, 1.0)


def _segment_bound(path: dpath.DPath, s: int, h: float) -> float:
    """The second-difference bound of segment ``s`` of ``path`` (cut or transition) at step h."""
    b, i = path.bounds, s // 2
    reach = max(abs(path.phi[0]), abs(path.phi[-1])) + h
    if s % 2 == 0:
        return dpath_motion._cut_difference_bound(h, b[s], b[s + 1], path.cut_d[i], path.cut_centre[i], reach)
    return dpath_motion._transition_difference_bound(h, b[s + 1] - b[s], path.coeffs[i], reach)


PATHS = {
    "transition": st.sampled_from(["traditional", "optimised"]),
    "zones": st.sampled_from([1, 2, 4]),
    "length_mm": st.floats(2.0, 40.0),
    "width_mm": st.floats(1.0, 15.0),
    "inner_mm": st.floats(5.0, 60.0),
    "spacing_fraction": st.floats(0.02, 1.0),
    "ppc": st.integers(3, 41),
}


@settings(max_examples=30, deadline=None)
@given(step_fraction=st.floats(1e-4, 0.2), **PATHS)
def test_second_difference_bounds_hold_inside_every_segment(step_fraction, **geometry):
    # the bound of a cut (eq. 3) or a transition (its quintic) is at least the computed
    # |ρ(φ+h) − 2ρ(φ) + ρ(φ−h)| wherever φ ± h lie strictly inside the segment; and tight
    # for a small step (h²·ρ'' at its largest): on some segment the second differences at a
    # step of 1e-4 of its span come within 1 % of it, so a bound too small would show
    path = _random_path(**geometry)
    b = path.bounds
    tightest = 0.0
    for s in range(b.size - 1):
        span = b[s + 1] - b[s]
        for fraction in (step_fraction, 1e-4):
            h = fraction * span
            bound = _segment_bound(path, s, h)
            p = np.linspace(b[s] + 1.001 * h, b[s + 1] - 1.001 * h, 257)
            mid, ahead, behind = (dpath.radius_at(path, p + d)[0] for d in (0.0, h, -h))
            second = np.abs(ahead - 2.0 * mid + behind).max()
            assert second <= bound, (s, h, second, bound)
            # where h²·ρ'' stands well above the rounding allowance (the bound at h = 0)
            if fraction == 1e-4 and bound > 100.0 * _segment_bound(path, s, 0.0):
                tightest = max(tightest, second / bound)
    assert tightest > 0.99


@settings(max_examples=40, deadline=None)
@given(step_deg=st.floats(1e-3, 20.0), **PATHS)
def test_peak_at_a_step_leaves_out_only_points_that_cannot_reach_it(step_deg, **geometry):
    # the inner points of a cut or transition are evaluated only where the segment's bound
    # on the second difference reaches the peak of the others: the peak is still the largest
    # of every point's, to the last bit, on any geometry and step
    path = _random_path(**geometry)
    h = math.radians(step_deg)
    assert dpath_motion.x_accel_peak_at_step(path, 40.0, h) == _every_points_peak(path, h)[0]


@pytest.mark.parametrize("transition", ["traditional", "optimised"])
def test_angles_a_few_ulp_beyond_the_path_ends_continue_its_end_cuts(transition):
    # a program's C is printed to 1e-9°: read back, its last angle can land a few ulp past the
    # last bound; it must continue the last cut, not evaluate the last transition's polynomial
    # outside its span (the seed's program then re-simulated with X 32.5 mm instead of 22.4 and
    # 10 m/s at its last line)
    path = seed_path(transition, spacing_um=500.0, ppc=21)
    end, first = path.bounds[-1], path.bounds[0]
    beyond = np.array([np.nextafter(end, np.inf), end + 1e-12, end + 1e-9])
    before = np.array([np.nextafter(first, -np.inf), first - 1e-12, first - 1e-9])
    for phi, cut in ((beyond, path.n_cuts - 1), (before, 0)):
        rho, on_cut = dpath.radius_at(path, phi)
        assert on_cut.all()
        assert np.allclose(rho, path.cut_d[cut] / np.cos(phi - path.cut_centre[cut]), rtol=1e-14)
        assert np.allclose(rho, path.rho[-1 if cut else 0], rtol=1e-9)


@pytest.mark.parametrize("transition", ["traditional", "optimised"])
def test_radius_at_is_evaluates_radius_and_cut_flags_bit_for_bit(transition):
    # the motion checks take ρ without the derivatives: the same values, to the last bit
    path = seed_path(transition, spacing_um=500.0, ppc=21)
    phi = np.concatenate(
        [np.random.default_rng(1).uniform(path.phi[0], path.phi[-1], 3000), path.bounds, path.phi]
    )
    rho, _, _, on_cut = dpath.evaluate(path, phi)
    fast_rho, fast_on = dpath.radius_at(path, phi)
    assert np.array_equal(fast_rho, rho) and np.array_equal(fast_on, on_cut)


@settings(max_examples=40, deadline=None)
@given(
    steps=st.lists(st.floats(0.01, 3.0), min_size=3, max_size=60),
    start=st.floats(-20.0, 20.0),
    ray_angles=st.lists(st.floats(0.0, 2.0 * math.pi, exclude_max=True), min_size=1, max_size=6),
)
def test_crossings_are_where_the_path_passes_each_ray(steps, start, ray_angles):
    """The bisecting search finds, for every ray and revolution, the program step that holds
    the crossing angle, and interpolates the path linearly there (a brute-force check)."""
    phi = start + np.concatenate([[0.0], np.cumsum(steps)])
    rho = 1000.0 + 10.0 * np.sin(phi)
    z = np.cos(3.0 * phi)
    pos, w, seg = rays.crossings(phi, rho, z, np.sort(np.array(ray_angles)))
    base = math.floor(phi[0] / (2.0 * math.pi)) * 2.0 * math.pi
    for a, theta in enumerate(np.sort(np.array(ray_angles))):
        for c in range(pos.shape[1]):
            q = theta + base + 2.0 * math.pi * c
            if q < phi[0] or q > phi[-1]:
                assert seg[a, c] == -1 and math.isnan(pos[a, c])
                continue
            j = seg[a, c]
            assert phi[j] <= q <= phi[j + 1] and (j == 0 or phi[j] < q)
            assert pos[a, c] == pytest.approx(np.interp(q, phi, rho), rel=1e-12, abs=1e-9)
            assert w[a, c] == pytest.approx(np.interp(q, phi, z), rel=1e-12, abs=1e-9)


def test_study_is_the_same_on_one_thread_and_two_and_reports_progress_once_over_all_cases():
    # the study runs its cases and the ratio table side by side: nothing may depend on it
    base = dstudy.default_case(options={"spacing_um": 200.0, "points_per_cut": 41})
    seen: list[tuple[int, int]] = []
    one = dstudy.study(base, 2000.0, threads=1)
    two = dstudy.study(base, 2000.0, progress=lambda d, t: seen.append((d, t)), threads=2)
    assert dstudy.public(one) == dstudy.public(two)
    assert one["spiral"]["pv_nm"] > 0 and one["x_accel_by_step"]["rows"]
    for a, b in zip(one["_programs"]["optimised"], two["_programs"]["optimised"], strict=True):
        assert np.array_equal(getattr(a, "phi", a), getattr(b, "phi", b))
    assert np.array_equal(one["_spiral_motion"]["z"], two["_spiral_motion"]["z"])
    # one report over the batches of the three cases: never backwards, ending complete
    done = [d for d, _ in seen]
    assert done == sorted(done) and seen[-1][0] == seen[-1][1] > 0


def test_plots_drawn_beside_the_study_are_those_drawn_after_it(tmp_path):
    # the figures' own process draws from the curves the study hands it while its cases run:
    # the same pixels as drawing them here from the finished study
    import matplotlib.image as image

    from ftsweep.kinds.dpath.figures import Plots

    base = dstudy.default_case(options={"spacing_um": 500.0, "points_per_cut": 41})
    with Plots(tmp_path / "beside", base.surface) as plots:
        summary = dstudy.study(base, 2000.0, plots=plots)
        beside = plots.paths()
        (process,) = plots._process
        assert process.exitcode is not None  # drawn: the process is ended, not left behind
    assert [p.name for p in beside] == [f"dpath-{base.surface}-x.png", f"dpath-{base.surface}-z.png"]
    (tmp_path / "after").mkdir()
    programs, rpm = summary["_programs"], summary["optimised"]["spindle_rpm"]
    after = [
        dstudy.plot_x_motion(programs, rpm, summary["accel_period_s"], tmp_path / "after" / beside[0].name),
        dstudy.plot_z_motion(
            summary["_spiral_motion"], programs["optimised"], rpm, tmp_path / "after" / beside[1].name
        ),
    ]
    for a, b in zip(beside, after, strict=True):
        pa, pb = image.imread(a), image.imread(b)
        assert pa.shape == pb.shape and np.array_equal(pa, pb), a.name
        # and the figure is drawn, not blank
        assert np.ptp(pa[..., :3]) > 0.5


def test_plots_report_what_drawing_raised_and_a_lost_process(tmp_path):
    import os
    import signal

    from ftsweep.kinds.dpath.figures import Plots

    with Plots(tmp_path, "part") as plots:
        plots.x_motion({"optimised": {"deg": [0.0, 1.0]}}, "no curves")  # rho_mm missing
        with pytest.raises(KeyError, match="rho_mm"):
            plots.paths()
    assert not list(tmp_path.glob("*.png")) and not list(tmp_path.glob(".*"))
    plots = Plots(tmp_path, "part")
    plots._pool.submit(int).result()  # the process is up
    # killed (an out-of-memory kill, a user's signal): an error that says what happened
    for process in plots._process:
        os.kill(process.pid, signal.SIGKILL)
    plots.z_motion({})
    with pytest.raises(RuntimeError, match="process drawing the D-path plots ended"):
        plots.paths()


def test_plots_left_by_an_error_end_their_process_at_once(tmp_path):
    # bad input found by the study: the process is ended, not waited for through its imports
    import signal

    from ftsweep.kinds.dpath.figures import Plots

    with pytest.raises(ValueError, match="bad input"), Plots(tmp_path, "part") as plots:
        (process,) = plots._process
        raise ValueError("bad input")
    assert process.exitcode == -signal.SIGTERM
    with Plots(tmp_path, "part") as plots:
        (process,) = plots._process
    assert process.exitcode == 0  # left without an error: shut down once idle


def test_dpath_command_with_bad_input_names_it_and_draws_nothing(tmp_path):
    from click.testing import CliRunner

    from ftsweep.cli.main import main

    res = CliRunner().invoke(main, ["dpath", "--surface", "no_such_part", "--plots", str(tmp_path / "p")])
    assert res.exit_code != 0 and "no_such_part" in res.output
    assert not list((tmp_path / "p").glob("*.png"))
    (tmp_path / "file").write_text("")
    # click refuses a file itself; a folder that cannot be made under one is refused here
    res = CliRunner().invoke(main, ["dpath", "--plots", str(tmp_path / "file" / "plots")])
    assert res.exit_code != 0 and "--plots" in res.output and "cannot write plots there" in res.output


def test_plots_are_drawn_here_where_no_process_can_be_started(tmp_path, monkeypatch):
    # e.g. a container without POSIX semaphores: ProcessPoolExecutor refuses to start
    import concurrent.futures

    from ftsweep.kinds.dpath.figures import Plots

    def refuse(*args, **kwargs):
        raise NotImplementedError("no sem_open here")

    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", refuse)
    deg = np.linspace(0.0, 720.0, 50)
    x = {
        "optimised": {
            "deg": deg,
            "rho_mm": 30.0 + np.sin(deg),
            "mid_deg": deg[1:],
            "x_feed_mm_s": deg[1:],
            "x_accel_m_s2": deg,
        }
    }
    z = {"spiral": {"deg": deg, "z_um": deg, "step_deg": deg[1:], "z_velocity_mm_s": deg[1:]}}
    with pytest.warns(
        UserWarning, match=r"drawn after the study: no process can be started \(no sem_open here\)"
    ):
        plots = Plots(tmp_path, "part")
    with plots:
        plots.z_motion(z)
        plots.x_motion(x, "title")
        drawn = plots.paths()
    assert drawn == [tmp_path / "dpath-part-x.png", tmp_path / "dpath-part-z.png"]
    assert all(p.stat().st_size > 0 for p in drawn)


def test_dpath_command_names_a_plot_it_cannot_write(tmp_path, monkeypatch):
    # drawn here (no process may start) so that the disk can be made to fail here
    import concurrent.futures
    import errno

    from click.testing import CliRunner

    from ftsweep.cli.main import main
    from ftsweep.kinds.dpath import figures as dfigures

    def refuse(*args, **kwargs):
        raise NotImplementedError("no sem_open here")

    def full(fig, path):
        raise OSError(errno.ENOSPC, f"{path}: cannot write it (No space left on device)")

    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor", refuse)
    monkeypatch.setattr(dfigures, "save_figure", full)
    args = ["dpath", "--spacing-um", "500", "--points-per-cut", "41", "--no-spiral", "--plots", str(tmp_path)]
    with pytest.warns(UserWarning, match="drawn after the study"):
        res = CliRunner().invoke(main, args)
    assert res.exit_code == 1, res.output
    assert "the D-path plots:" in res.output and "dpath-concave_sphere-x.png: cannot write it" in res.output
