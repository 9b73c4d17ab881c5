"""Spiral path programs (seed 003): sampling rules, the residual-budget feed, linear
interpolation along the path, and the seed's own numbers through the one engine."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from ftsweep.engine.case import Case, CaseError, Resolution, program_request
from ftsweep.inputs.catalogs import CatalogError
from ftsweep.simulate import resolve_case, run_case
from ftsweep.stages.interpolation import spiral_passes, spiral_program
from ftsweep.stages.interpolation import tables as interpolation
from ftsweep.stages.interpolation.tables import path_grid
from ftsweep.stages.paths import cusp_budget, spiral

# ----------------------------------------------------------------- sampling rules


@given(
    rho0=st.floats(50.0, 2000.0),
    feed=st.floats(1.0, 40.0),
    n=st.integers(3, 720),
)
@settings(max_examples=40, deadline=None)
def test_constant_angle_counts_and_steps(rho0, feed, n):
    path = spiral.constant_angle(rho0, feed, n)
    steps = np.diff(path.phi)
    end = spiral_program.spiral_end_rad(rho0, feed)
    assert path.phi[0] == 0.0 and path.phi[-1] == pytest.approx(end, rel=1e-12)
    assert np.all(steps > 0) and np.all(steps <= 2 * math.pi / n * (1 + 1e-9))
    # the layout formula: Np points per revolution over ρ0/F revolutions, plus the centre
    assert path.n_points == math.ceil(end * n / (2 * math.pi) - 1e-9) + 1


@given(rho0=st.floats(100.0, 2000.0), feed=st.floats(1.0, 20.0), arc=st.floats(1.0, 50.0))
@settings(max_examples=30, deadline=None)
def test_constant_arc_spacing(rho0, feed, arc):
    path = spiral.constant_arc(rho0, feed, arc)
    b = feed / (2 * math.pi)
    s = spiral_program._arc_from_centre(path.rho, b)
    ds = -np.diff(s)
    cap = 2 * math.pi / spiral.MIN_POINTS_PER_REV
    # every step is the arc length asked, or shorter near the centre, where the angular floor
    # splits steps wider than 2π/16 (and the last step, which ends at the centre)
    assert np.all(ds <= arc * (1 + 1e-6) + 1e-9)
    short = ds[:-1] < arc * (1 - 1e-6)
    assert np.all(path.rho[:-2][short] <= arc / cap + feed)
    assert np.all(np.diff(path.phi) <= cap * (1 + 1e-9))


def _wavy(phi: np.ndarray, rho0: float, feed: float, amp: float, waves: int) -> np.ndarray:
    rho = spiral_program.spiral_radius(phi, rho0, feed)
    return amp * (rho / rho0) * np.sin(waves * phi) + 1e-3 * rho


@given(
    amp=st.floats(0.05, 2.0),
    waves=st.integers(1, 30),
    budget=st.floats(0.005, 0.2),
)
@settings(max_examples=12, deadline=None)
def test_chord_budget_holds_on_every_segment(amp, waves, budget):
    rho0, feed = 500.0, 5.0

    def commands(phi):
        return _wavy(phi, rho0, feed, amp, waves)

    path, values, errors = spiral.chord_budget(rho0, feed, budget, commands)
    # refined samples are the cubic through the first sampling where proven within 1e-3·Δ
    assert np.abs(values - commands(path.phi)).max() <= spiral.INTERP_TOL * budget
    assert errors.max() <= budget
    # the budget holds between the dense samples too: the chord against the path itself
    u = np.linspace(0.0, 1.0, 33)[1:-1]
    phi = path.phi[:-1, None] + np.diff(path.phi)[:, None] * u[None, :]
    chord = values[:-1, None] + np.diff(values)[:, None] * u[None, :]
    assert np.max(np.abs(chord - commands(phi))) <= budget


def test_chord_budget_takes_fewer_points_where_the_path_is_straighter():
    rho0, feed = 500.0, 5.0
    gentle, _, _ = spiral.chord_budget(rho0, feed, 0.01, lambda p: _wavy(p, rho0, feed, 0.1, 4))
    steep, _, _ = spiral.chord_budget(rho0, feed, 0.01, lambda p: _wavy(p, rho0, feed, 1.0, 12))
    assert steep.n_points > 2 * gentle.n_points


# ----------------------------------------------------------------- interpolation along the path


@given(a=st.floats(-2.0, 2.0), b=st.floats(-1e-3, 1e-3), n=st.integers(3, 400))
@settings(max_examples=30, deadline=None)
def test_a_command_linear_along_the_path_is_interpolated_exactly(a, b, n):
    rho0, feed = 300.0, 3.0
    path = spiral.constant_angle(rho0, feed, n)
    values = a + b * path.phi
    grid = path_grid(np.array([0.1, 1.3, 2.9]), rho0, feed, 2, 10.0)
    w = interpolation.pass_commands(path, values, grid)
    k = np.arange(w.shape[1])
    phi = 2 * math.pi * k[None, :] + grid.ray_theta[:, None]
    valid = k[None, :] < grid.n_passes[:, None]
    assert np.allclose(w[valid], (a + b * phi)[valid], rtol=0, atol=1e-12)
    # the same commands from the tool positions (what the dynamics stage asks for)
    rho = np.maximum(grid.pass_rho, 0.0)
    again = interpolation.interpolate(path, values, rho, np.broadcast_to(grid.ray_theta[:, None], rho.shape))
    assert np.allclose(again[valid], w[valid], atol=1e-12)


# ----------------------------------------------------------------- residual budget (eqs. 1–3)


@given(h=st.floats(1e-4, 5.0), r=st.floats(20.0, 2000.0), radius=st.floats(-1e6, 1e6))
@settings(max_examples=80, deadline=None)
def test_feed_for_cusp_inverts_cusp_for_feed(h, r, radius):
    if radius > 0 and radius <= r + h:
        return  # a concave section tighter than the arc: no feed (tested below)
    if abs(radius) < 1e-3:
        return
    if radius < 0 and h >= -radius:
        # a convex section of radius |R| ≤ h: the arcs' cusp above it stays below |R| however
        # wide the feed, so no feed gives h (hypothesis found h = 5, R = −0.5 µm; the
        # sections of a real part are millimetres to metres)
        return
    f = cusp_budget.feed_for_cusp(h, r, np.array([radius]), np.array([0.0]))
    assert f[0] > 0
    assert cusp_budget.cusp_for_feed(float(f[0]), r, np.array([radius]), np.array([0.0]))[0] == pytest.approx(
        h, rel=1e-6, abs=1e-9
    )


def test_feed_for_cusp_flat_limit_and_order():
    h, r = 0.5, 496.0
    flat = cusp_budget.feed_for_cusp(h, r, np.array([np.inf]), np.array([0.0]))[0]
    assert flat == pytest.approx(2 * math.sqrt(h * (2 * r - h)), rel=1e-12)
    # F²/(8·Rc) ≈ Δres for a small budget (model §6)
    assert flat**2 / (8 * r) == pytest.approx(h, rel=1e-3)
    for big in (1e7, -1e7):
        assert cusp_budget.feed_for_cusp(h, r, np.array([big]), np.array([0.0]))[0] == pytest.approx(
            flat, rel=1e-4
        )
    concave = cusp_budget.feed_for_cusp(h, r, np.array([2000.0]), np.array([0.0]))[0]
    convex = cusp_budget.feed_for_cusp(h, r, np.array([-2000.0]), np.array([0.0]))[0]
    # with the tool-centre spacing as the feed, a valley leaves higher cusps than a crest
    assert concave < flat < convex
    assert cusp_budget.feed_for_cusp(h, r, np.array([r]), np.array([0.0]))[0] == 0.0
    # on a slope the centres are further apart than the X advance
    assert cusp_budget.feed_for_cusp(h, r, np.array([np.inf]), np.array([0.5]))[0] == pytest.approx(
        flat / math.sqrt(1.25)
    )


# ----------------------------------------------------------------- through the engine


def test_flat_part_machines_to_the_feed_cusp(catalog_dir):
    """A flat part cut by a constant-angle spiral program: cusps F²/(8·Rc) away from the
    axis (model §6), only the last passes across the axis further apart (as for tables)."""
    for feed, rc, n in ((4.0, 83.0, 36), (2.0, 50.0, 7)):
        case = Case(
            surface="flat",
            layout=program_request(kind="spiral", points_per_rev=n),
            feed_um=feed,
            nose_radius_um=rc,
            resolution=Resolution(n_theta=8),
        )
        rec = run_case(case, catalog_dir)
        exact = (rc - math.sqrt(rc**2 - feed**2 / 4)) * 1e3
        assert rec["pv_outer_nm"] == pytest.approx(exact, rel=1e-9)
        assert rec["pv_outer_nm"] == pytest.approx(feed**2 / (8 * rc) * 1e3, rel=1e-3)
        assert rec["pv_nm"] <= (1.5 * feed) ** 2 / (8 * rc) * 1e3 * 1.02
        assert rec["pv_interp_nm"] == pytest.approx(0.0, abs=1e-9)
        # the layout formula: Np points per revolution over ρ0/F revolutions, plus the centre
        assert rec["n_points"] == n * round(300.0 / feed) + 1 and rec["layout"] == "spiral"


def test_the_seed_003_case_meets_its_budgets():
    """Seed 003 §2.2 and Table 1: Δres = Δcho = 0.5 µm, rε = 0.496 mm on the complex
    sinusoidal mesh. The residual budget gives the feed (Table 1: 0.0402 mm; within 3 %),
    the chord and residual errors stay within 0.5 µm, and the P-V within eq. 7's 2 µm."""
    case = Case(
        surface="sinusoidal_mesh",
        machine="sts-nanoform",
        cutting="seed003",
        layout=program_request(kind="spiral", chord_um=0.5, residual_um=0.5),
    )
    rec = run_case(case)
    assert rec["feed_um"] == pytest.approx(40.2, rel=0.03)
    assert rec["chord_error_nm"] <= 500.0
    assert rec["residual_error_nm"] <= 500.0 * (1 + 1e-9)
    assert rec["pv_nm"] <= 2000.0
    assert rec["feasible"], rec["infeasible_reason"]


def test_spiral_requests_are_checked():
    with pytest.raises(ValueError, match="exactly one sampling rule"):
        program_request(kind="spiral", chord_um=1.0, arc_um=2.0)
    with pytest.raises(ValueError, match="belong"):
        program_request(kind="ring", points=1e5, aspect=1.0, chord_um=1.0)
    with pytest.raises(CaseError, match="not both"):
        resolve_case(
            Case(
                surface="sinewave2d",
                feed_um=1.0,
                layout=program_request(kind="spiral", arc_um=5.0, residual_um=0.01),
            )
        )
    # a table case's key does not change with the spiral's fields
    case = Case(surface="sinewave2d", layout=program_request(kind="ring", pitch=(2.0, 1.0)))
    assert "chord_um" not in case.model_dump()["layout"]


# ----------------------------------------------------------------- sweeps of spiral programs
SPIRAL_SWEEP = """
surface: small_sine
layout: spiral
axes:
  points_per_rev: [40, 90]
  feed_um: [2.0, 4.0]
"""


@pytest.mark.slow  # 7-15 s on 2 cores: the full command runs it, the quick one leaves it out
def test_spiral_sweep_is_scheduler_independent_and_selectable(tmp_path, catalog_dir, monkeypatch):
    monkeypatch.setenv("FTSWEEP_CATALOGS", str(catalog_dir))  # verify compares the entries with it
    import xarray as xr

    from ftsweep.sweeps.run import run_sweep
    from ftsweep.sweeps.spec import case_at, load_sweep
    from ftsweep.tools.query import best_per_points
    from ftsweep.tools.select import choose

    spec_path = tmp_path / "spiral.yaml"
    spec_path.write_text(SPIRAL_SWEEP)
    _, spec = load_sweep(str(spec_path), catalog_dir)
    assert case_at(spec, 3).layout.points_per_rev == 90 and case_at(spec, 3).feed_um == 4.0
    sync = run_sweep(str(spec_path), tmp_path / "a.zarr", scheduler="synchronous", catalog_folder=catalog_dir)
    dist = run_sweep(str(spec_path), tmp_path / "b.zarr", workers=2, catalog_folder=catalog_dir)
    assert sync.done == dist.done == 4
    a, b = xr.open_zarr(tmp_path / "a.zarr").load(), xr.open_zarr(tmp_path / "b.zarr").load()
    for name in ("pv_nm", "rms_nm", "n_points", "dphi_deg", "w_accel_peak_m_s2"):
        assert np.array_equal(a[name].values, b[name].values), name
    # N = Np·(ρ0/F) + 1
    assert a["n_points"].values.tolist() == [[40 * 150 + 1, 40 * 75 + 1], [90 * 150 + 1, 90 * 75 + 1]]
    chosen = choose(a, budget_points=20_000)
    assert chosen["layout"] == "spiral" and chosen["n_points"] <= 20_000
    assert chosen["pv_nm"] == pytest.approx(float(a["pv_nm"].where(a["n_points"] <= 20_000).min()))
    assert [target for target, _ in best_per_points(a)] == [40.0, 90.0]

    # export the chosen program as text, verify it, and catch a changed line or sidecar
    from ftsweep.tools.export import ExportError, export, verify

    out = tmp_path / "part.txt"
    meta = export(tmp_path / "a.zarr", out, budget_points=20_000)
    lines = out.read_text().splitlines()
    data = lines[lines.index("C_deg X_mm Z_mm") + 1 :]
    assert len(data) == chosen["n_points"] == meta["n_points"]
    assert any(line.startswith("# predicted P-V") for line in lines)
    record = verify(out)
    assert record["pv_nm"] == pytest.approx(chosen["pv_nm"], abs=record["pv_tolerance_nm"])
    with pytest.raises(ExportError, match="exists"):
        export(tmp_path / "a.zarr", out, budget_points=20_000)
    c, x, z = data[5].split()
    out.write_text("\n".join(lines).replace(data[5], f"{c} {x} {float(z) + 1e-6:.9f}") + "\n")
    with pytest.raises(ExportError, match="CRC32"):
        verify(out)

    # compare: the spiral cube beside a ring cube of the same part, table and plot
    from click.testing import CliRunner

    from ftsweep.cli.main import main

    ring = tmp_path / "ring.yaml"
    ring.write_text("surface: small_sine\nlayout: ring\naxes: {points: [6000, 13000], aspect: [1, 4]}\n")
    run_sweep(str(ring), tmp_path / "r.zarr", scheduler="synchronous", catalog_folder=catalog_dir)
    png = tmp_path / "cmp.png"
    res = CliRunner().invoke(
        main,
        # the spiral cube sweeps feeds of 2 and 4 µm/rev against the ring's 1: listed, flagged
        [
            "compare",
            str(tmp_path / "r.zarr"),
            str(tmp_path / "a.zarr"),
            "-o",
            str(png),
            "--json",
            "--allow-different",
        ],
        env={"FTSWEEP_CATALOGS": str(catalog_dir)},
    )
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    rows = out["rows"]
    assert {r["program"].split()[0] for r in rows} == {"ring", "spiral"} and len(rows) == 4
    spiral_rows = [r for r in rows if r["program"].startswith("spiral")]
    # the cube's P-V is kept as recorded; every row is simulated again on one sampling, the
    # finest among them (tables by their cells, spirals by their densest revolution)
    assert [r["pv_recorded_nm"] for r in spiral_rows] == [best_pv(a, 40), best_pv(a, 90)]
    assert png.stat().st_size > 0
    assert out["different"] == ["feed_um"]
    common = out["common_n_theta"]
    assert common > 0 and all(r["n_theta"] == common for r in rows)
    recorded = CliRunner().invoke(
        main,
        [
            "compare",
            str(tmp_path / "r.zarr"),
            str(tmp_path / "a.zarr"),
            "--json",
            "--allow-different",
            "--as-recorded",
        ],
        env={"FTSWEEP_CATALOGS": str(catalog_dir)},
    )
    as_recorded = json.loads(recorded.stdout)["rows"]
    assert len({r["n_theta"] for r in as_recorded}) > 1  # each kind on its own sampling
    for r, again in zip(as_recorded, rows, strict=True):
        if r["n_theta"] == common:  # already on the common sampling: not simulated again
            assert again["pv_nm"] == r["pv_nm"]

    # cubes made at different feeds are refused, naming the difference; --allow-different
    # lists them with the difference flagged
    fast = tmp_path / "fast.yaml"
    fast.write_text("surface: small_sine\nlayout: spiral\naxes: {points_per_rev: [40], feed_um: [4.0]}\n")
    run_sweep(str(fast), tmp_path / "f.zarr", scheduler="synchronous", catalog_folder=catalog_dir)
    args = ["compare", str(tmp_path / "r.zarr"), str(tmp_path / "f.zarr")]
    res = CliRunner().invoke(main, args, env={"FTSWEEP_CATALOGS": str(catalog_dir)})
    assert res.exit_code == 1 and "different conditions (feed_um: 1 (r) vs 4 (f))" in res.output
    res = CliRunner().invoke(main, [*args, "--allow-different"], env={"FTSWEEP_CATALOGS": str(catalog_dir)})
    assert res.exit_code == 0, res.output
    assert "feed_um 4 (differs)" in res.output and "nose_radius_um 83;" in res.output

    # the report of a spiral cube: P-V against points, the chosen case's map and spectrum
    from ftsweep.tools.report import make_report

    paths = make_report(tmp_path / "a.zarr", tmp_path / "report", map_bins=16)
    assert {"pv_vs_points", "error_map", "w_spectrum", "index"} <= set(paths)
    assert all(p.stat().st_size > 0 for p in paths.values())
    with pytest.raises(ValueError, match="aspect axis"):
        a.ftsweep.optimum()


def test_spiral_results_do_not_depend_on_the_batch_size(catalog_dir):
    case = Case(surface="small_sine", layout=program_request(kind="spiral", arc_um=15.0), feed_um=3.0)
    small = run_case(case, catalog_dir, batch_nodes=3_000)
    large = run_case(case, catalog_dir, batch_nodes=2_000_000)
    for name in ("pv_nm", "rms_nm", "pv_interp_nm", "n_points", "w_accel_peak_m_s2"):
        assert small[name] == large[name], name


def best_pv(ds, points_per_rev):
    """Lowest eligible P-V [nm] of a spiral cube at one points_per_rev."""
    from ftsweep.tools.query import eligible_pv

    return float(eligible_pv(ds).sel(points_per_rev=points_per_rev).min())


def test_spiral_sweep_axes_are_checked(tmp_path, catalog_dir):
    from ftsweep.sweeps.spec import load_sweep

    bad = {
        "points": "surface: small_sine\nlayout: spiral\naxes: {points: [1000], chord_um: [0.1]}\n",
        "exactly one rule axis": (
            "surface: small_sine\nlayout: spiral\naxes: {chord_um: [0.1], arc_um: [3]}\n"
        ),
        "belongs to spiral": "surface: small_sine\naxes: {points: [1e4], aspect: [1], chord_um: [0.1]}\n",
    }
    for message, text in bad.items():
        path = tmp_path / "bad.yaml"
        path.write_text(text)
        with pytest.raises(CatalogError, match=message):
            load_sweep(str(path), catalog_dir)


@settings(max_examples=25, deadline=None)
@example(rho0=1000.0, feed=1.0, arc=1.5, floor=128)  # 2.1 M points: 32 parts
# b = 0.175 µm/rad: a last-bit difference in ρ (2.3e-13 µm) is 1.3e-12 rad, 1.4 ulp of Φ
@example(rho0=1167.650588649521, feed=1.1, arc=4.517176517833026, floor=3)
@given(
    rho0=st.floats(50.0, 3000.0),
    feed=st.floats(0.3, 20.0),
    arc=st.floats(0.05, 5.0),
    floor=st.integers(3, 300),
)
def test_constant_arc_is_the_whole_array_newton_solve(rho0, feed, arc, floor):
    """The compiled solve, one Newton per point from the large-radius expansion and the gaps
    split in place, gives the points of a plain numpy solve over the whole array (from
    t = ρ²/2b, every point as many steps as the slowest): the same count, every angle within
    4 ulp of Φ (numba's asinh and numpy's vectorised one differ in the last bit; the Newton
    steps below 1e-9·ρ0 that the per-point stop leaves out move a point by less), plus 4 ulp
    of ρ0 over b: φ = (ρ0 − ρ)/b carries a last-bit difference of ρ magnified by 1/b, which
    exceeds an ulp of Φ on fine feeds (hypothesis found 6 ulp of Φ at a 1.1 µm feed)."""
    b = feed / (2.0 * math.pi)
    total = spiral_program.path_length_um(rho0, feed)
    if total / arc > 3e6:
        return
    target = np.maximum(total - np.arange(int(math.ceil(total / arc - 1e-9)) + 1) * arc, 0.0)
    rho = np.minimum(np.sqrt(2.0 * b * target), rho0)
    for _ in range(60):
        step = (spiral_program._arc_from_centre(rho, b) - target) * b / np.sqrt(rho * rho + b * b)
        rho = np.clip(rho - step, 0.0, rho0)
        if np.max(np.abs(step)) < 1e-9 * max(rho0, 1.0):
            break
    phi = spiral._close(np.sort((rho0 - rho) / b), spiral_program.spiral_end_rad(rho0, feed))
    gaps = np.diff(phi)
    pieces = np.maximum(np.ceil(gaps / (2.0 * math.pi / floor) - 1e-9), 1).astype(np.int64)
    starts = np.repeat(phi[:-1], pieces)
    within = np.arange(pieces.sum()) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    want = np.append(starts + within * np.repeat(gaps / pieces, pieces), phi[-1])
    got = spiral.constant_arc(rho0, feed, arc, floor).phi
    assert got.size == want.size
    assert np.abs(got - want).max() <= 4 * np.spacing(want[-1]) + 4 * np.spacing(rho0) / b
    assert np.all(np.diff(got) >= 0.0) and got[-1] == spiral_program.spiral_end_rad(rho0, feed)


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(2, 400),
    seed=st.integers(0, 2**31),
    rays=st.integers(1, 6),
    revs=st.integers(1, 30),
    first=st.integers(0, 3),
)
def test_spiral_pass_kernel_is_np_interp_value_for_value(n, seed, rays, revs, first):
    # passes a revolution apart, searched from the last one's place: the same values as
    # np.interp (interval, slope, ends, repeated angles) for any path, bit for bit
    rng = np.random.default_rng(seed)
    xp = np.sort(rng.uniform(0.0, 2.0 * math.pi * revs * 0.8, n))
    xp[rng.integers(0, n, n // 5)] = xp[rng.integers(0, n, n // 5)]  # repeated angles
    xp = np.sort(xp)
    fp = rng.normal(size=n)
    theta = rng.uniform(0.0, 2.0 * math.pi, rays)
    out = np.empty((rays, revs))
    spiral_passes.pass_commands_kernel(xp, fp, np.empty(0), np.empty(0), theta, first, out)
    phi = 2.0 * math.pi * (np.arange(revs) + first)[None, :] + theta[:, None]
    np.testing.assert_array_equal(out, np.interp(phi, xp, fp))


@pytest.mark.parametrize("kinked", [False, True])
def test_subdivided_samples_are_interpolated_only_where_proven(kinked):
    # a smooth path is interpolated almost everywhere; across a kink (|sin|) the cubic would
    # miss by far more than the tolerance, so the samples there are computed exactly
    def commands(phi):
        wave = np.sin(3.0 * phi)
        return 0.5 * (np.abs(wave) if kinked else wave)

    coarse_phi = np.linspace(0.0, 20.0, 4001)
    tol = 1e-6
    phi, w, exact = spiral.subdivided((coarse_phi, commands(coarse_phi)), 10, commands, tol)
    np.testing.assert_allclose(phi, np.linspace(0.0, 20.0, 40_001), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(w[::10], commands(coarse_phi))  # the coarse samples kept
    assert np.abs(w - commands(phi)).max() <= tol
    assert exact >= 4 * 9  # the two intervals at either end are always computed
    if kinked:
        assert exact >= 19 * 9  # 19 kinks: the interval around each is computed exactly
    else:
        assert exact < 100


def test_the_w_velocity_of_a_spiral_is_that_of_its_segments():
    """The W motion a spiral program's record reports (model §6 dynamics) is that of its linear
    segments at the spindle speed: never above the steepest segment's |Δw/Δt| (a command read
    a revolution on, across the spiral's start, once made it ten times that), and close to it."""
    from ftsweep.simulate import resolve_case

    case = Case(
        surface="sinusoidal_mesh",
        machine="sts-moore",
        cutting="seed003",
        layout=program_request(kind="spiral", chord_um=0.5, residual_um=0.5),
    )
    rcase = resolve_case(case)
    omega = 6.63 * math.pi / 30.0
    steepest = float(np.max(np.abs(np.diff(rcase.values) / np.diff(rcase.layout.phi)))) * omega * 1e-3
    record = run_case(case)
    assert 0.5 * steepest <= record["w_velocity_peak_mm_s"] <= steepest * (1 + 1e-9)
