"""Freeform Fresnel programs on an X-Y-Z-C lathe (README reference [2]): slicing, the
quasi-spiral path, the adaptive tool pose, tool-edge compensation, adaptive timesteps,
export and verify, and the ``ftsweep fresnel`` command."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st
from support.catalogs import make_catalog_dir

from ftsweep.cli.main import main
from ftsweep.inputs import catalogs
from ftsweep.kinds.fresnel import program as fp
from ftsweep.kinds.fresnel import study as fstudy
from ftsweep.stages.paths import fresnel as ff

SURFACE = "chebyshev_example"
# a coarser program than the CLI's default (K = 360, Δr = 2 µm) so the module runs in seconds
K_TEST = 120


@pytest.fixture(scope="module")
def cheb():
    spec = catalogs.entry("surfaces", SURFACE)
    return catalogs.base_callable(spec), catalogs.aperture_of(spec)


@pytest.fixture(scope="module")
def coarse(cheb, tmp_path_factory):
    """A study of the Chebyshev example at h = 10 µm with Δr = 8 µm and K = 120."""
    folder = make_catalog_dir(tmp_path_factory.mktemp("fresnel") / "catalogs")
    text = (folder / "cutting.yaml").read_text()
    text += "\ncoarse-fresnel:\n  feed_um: 8.0\n  nose_radius_um: 40.0\n  spindle_rpm: 30.0\n"
    (folder / "cutting.yaml").write_text(text)
    inp = fstudy.inputs(SURFACE, "xyzc-nanoform", "coarse-fresnel", points_per_turn=K_TEST, timing="paper")
    return inp, fstudy.study(inp, folder), folder


# --------------------------------------------------------------------------- slicing
def test_slicing_stays_in_one_facet_height_and_steps_by_h(cheb):
    fn, aperture = cheb
    h = 10.0
    rng = fp.surface_range(fn, aperture)
    x, y = np.meshgrid(np.linspace(-1000, 1000, 401), np.linspace(-1000, 1000, 401))
    inside = aperture.contains(x, y)
    f = fn(x, y)[0]
    fc, j = ff.sliced(f, rng["f_ref_um"], h)
    assert np.all(fc[inside] >= 0.0) and np.all(fc[inside] < h)
    # f_c − f is one constant per facet: −f_ref − j·h
    np.testing.assert_allclose((fc - f)[inside], (-rng["f_ref_um"] - j * h)[inside], atol=1e-9)
    # across an edge (neighbours in different facets) the offset steps by whole facet heights
    dj = np.diff(j, axis=1)[(inside[:, 1:] & inside[:, :-1])]
    step = np.diff(fc - f, axis=1)[(inside[:, 1:] & inside[:, :-1])]
    assert np.any(dj != 0)
    np.testing.assert_allclose(step, -dj * h, atol=1e-9)
    assert set(np.unique(j[inside])) == {0, 1, 2, 3}


def test_catalog_fresnel_transform_slices_any_surface(catalog_dir):
    tmp_path = catalog_dir
    text = (tmp_path / "surfaces.yaml").read_text()
    text = text.replace("chebyshev_example:\n", "chebyshev_example:\n  fresnel: {facet_height_um: 5.0}\n", 1)
    (tmp_path / "surfaces.yaml").write_text(text)
    spec = catalogs.entry("surfaces", SURFACE, tmp_path)
    sliced = catalogs.surface_callable(spec, tmp_path)
    base = catalogs.base_callable(spec, tmp_path)
    x = np.linspace(-900.0, 900.0, 301)
    fc, gx, gy = sliced(x, 0.3 * x)
    f, bx, by = base(x, 0.3 * x)
    assert np.all((fc >= 0.0) & (fc < 5.0))
    # the offset f_c − f differs between points by whole facet heights only
    shift = fc - f - (fc - f)[0]
    np.testing.assert_allclose(np.mod(shift + 2.5, 5.0), 2.5, atol=1e-9)
    np.testing.assert_array_equal(gx, bx)
    assert catalogs.line_sampler(spec) is None
    with pytest.raises(catalogs.CatalogError, match="facet_height_um"):
        (tmp_path / "surfaces.yaml").write_text(text.replace("facet_height_um: 5.0", "facet_height_um: -1"))
        catalogs.entry("surfaces", SURFACE, tmp_path)


def test_edges_are_closed_contours_and_both_schemes_agree(cheb):
    fn, aperture = cheb
    rng = fp.surface_range(fn, aperture)
    h = 10.0
    n = 4
    polar = ff.plan(fn, rng["apex_um"], rng["f_ref_um"], h, n, 8.0, 90, rng["reach_um"], "polar")
    arc = ff.plan(fn, rng["apex_um"], rng["f_ref_um"], h, n, 8.0, 90, rng["reach_um"], "arc")
    assert polar.scheme == "polar" and arc.scheme == "arc"
    for plan in (polar, arc):
        for i, edge in enumerate(plan.edges[:-1]):
            level = rng["f_ref_um"] + h * (n - i)
            np.testing.assert_allclose(fn(edge[:, 0], edge[:, 1])[0], level, atol=1e-6)
            # closed: the gap from the last control point back to the first is an ordinary step
            gaps = np.hypot(*np.diff(np.vstack([edge, edge[:1]]), axis=0).T)
            assert gaps[-1] <= 2.0 * np.median(gaps)
    # A.3 spaces its points evenly along the edge
    gaps = np.hypot(*np.diff(np.vstack([arc.edges[0], arc.edges[0][:1]]), axis=0).T)
    assert gaps.max() / gaps.min() < 1.01
    # the same closed curves: every arc point lies on the polar polygon's curve (same level)
    assert arc.n_facets == polar.n_facets


def test_surface_without_interior_minimum_is_refused():
    from ftsweep.stages.sampling.geometry import Aperture

    def tilted(x, y):
        x, y = np.asarray(x, float), np.asarray(y, float)
        return 0.01 * x + 0.0 * y, np.full_like(x, 0.01), np.zeros_like(y)

    with pytest.raises(ff.FresnelError, match="lowest point lies on the aperture's edge"):
        fp.plan(tilted, Aperture("circle", radius_um=1000.0), 10.0, 2.0, 40.0, 60)


# --------------------------------------------------------------------------- path and pose
def test_feed_between_turns_never_exceeds_the_feed(coarse):
    inp, s, _ = coarse
    plan = s["_plan"]
    assert s["feed_per_turn_max_um"] <= plan.feed_um + 1e-9
    # the distance from every point to the previous turn's polyline is no more than that
    k = plan.path.points_per_turn
    xy = plan.path.xy[:-1]
    for m in (1, 40, plan.path.n_turns // 2, plan.path.n_turns - 1):
        prev = xy[(m - 1) * k : m * k]
        here = xy[m * k : (m + 1) * k]
        d = np.min(np.hypot(here[:, None, 0] - prev[None, :, 0], here[:, None, 1] - prev[None, :, 1]), axis=1)
        assert d.max() <= plan.feed_um + 1e-9
    assert plan.path.xy.shape[0] == plan.path.n_turns * k + 1
    assert s["n_facets"] == 4


@settings(max_examples=60, deadline=None)
@given(
    st.floats(-2000, 2000),
    st.floats(-2000, 2000),
    st.floats(0.001, 1.0),
    st.floats(-math.pi, math.pi),
    st.floats(-0.5, 0.5),
)
def test_pose_puts_the_tool_on_the_path_with_the_rake_face_on_the_cutting_direction(X, Y, slope, ang, dev):
    xy = np.array([[X, Y]])
    gx, gy = np.array([slope * math.cos(ang)]), np.array([slope * math.sin(ang)])
    phi, x, y = ff.pose(xy, gx, gy, dev)
    # eq. 9 rows 1-2: the tool, rotated by φ, lies on the path point
    np.testing.assert_allclose(ff.workpiece_of(phi, x, y), xy, atol=1e-9)
    # the rake face's normal is the global y axis: in the workpiece frame R(φ)·(0, 1)
    normal = np.array([math.sin(phi[0]), math.cos(phi[0])])
    g = np.array([gx[0], gy[0]]) / slope
    # it deviates from the cutting direction (⊥ gradient) by Δφ; Δφ = 0: normal ⊥ gradient
    assert abs(float(normal @ g) - math.sin(dev)) < 1e-9
    if dev == 0.0:
        assert abs(float(normal @ g)) < 1e-12


def test_spindle_angle_increases_along_the_path(coarse):
    plan = coarse[1]["_plan"]
    assert np.all(np.diff(plan.phi) > 0.0)
    turns = (plan.phi[-1] - plan.phi[0]) / (2 * np.pi)
    assert abs(turns - plan.path.n_turns) < 1.5


# --------------------------------------------------------------------------- compensation
def test_exact_and_straight_compensation_agree_on_a_straight_profile():
    def plane(x, y):
        x, y = np.asarray(x, float), np.asarray(y, float)
        return 0.05 * x - 0.12 * y, np.full_like(x, 0.05), np.full_like(y, -0.12)

    x = np.linspace(-500, 500, 11)
    exact = ff.compensation_exact(plane, x, x, 40.0)
    straight = ff.compensation_straight(np.full(11, 0.05), np.full(11, -0.12), 40.0)
    np.testing.assert_allclose(exact, straight, atol=1e-9)
    assert straight[0] > 0.0


def test_compensation_on_the_chebyshev_example(cheb, coarse):
    fn, _ = cheb
    s = coarse[1]
    plan = s["_plan"]
    # [2]: with a 40 µm nose the two differ by less than 10 nm where slopes stay small
    assert s["slope_max"] < 0.1
    assert s["ez_difference_max_nm"] < 10.0
    assert s["ez_exact_max_nm"] > 0.0
    # the compensated arc never cuts below the design along the gradient (eq. 10's purpose)
    idx = np.linspace(0, plan.path.xy.shape[0] - 2, 400).astype(int)
    p = plan.path.xy[idx]
    f0, gx, gy = fn(p[:, 0], p[:, 1])
    g = np.hypot(gx, gy)
    u = np.column_stack([gx / g, gy / g])
    r = plan.nose_radius_um
    for d in np.linspace(0.0, 0.999 * r, 80):
        arc = plan.ez_exact_um[idx] + r - math.sqrt(r * r - d * d)
        above = fn(p[:, 0] + u[:, 0] * d, p[:, 1] + u[:, 1] * d)[0] - f0
        assert np.all(above <= arc + 1e-9)


# --------------------------------------------------------------------------- timesteps
def test_adaptive_timesteps_level_each_turn_and_beat_constant_steps(coarse):
    inp, s, folder = coarse
    steps = s["_steps"]
    reduction = 1.0 - steps.peak_optimised / steps.peak_constant
    # [2]: about 50 % within a rotation; asked: at least 40 %
    assert reduction[0] >= 0.4
    assert np.median(reduction) >= 0.4
    # [2]: 3.1× and 3.8×; asked: at least 2.5×
    assert s["speedup"] >= 2.5
    assert s["time_constant_s"] > s["time_adaptive_s"] > 0.0
    # every step after the K_s scaling: within 1/K_s of every limit
    limits = fp.limits_of(catalogs.entry("machines", inp.machine, folder))
    q = s["_plan"].axes_si()
    acc, vel = fp.relative_peaks(q, steps.steps, limits)
    assert acc.max() <= 1.0 / inp.safety + 1e-9
    assert vel.max() <= 1.0 / inp.safety + 1e-9
    assert s["within_limits"]


def _direct_minimax(deltas: np.ndarray, inv: np.ndarray, first: bool, t0: float) -> float:
    """The turn's least largest relative acceleration at mean step T0, solved directly: SLSQP
    on the epigraph form (min s subject to −s ≤ a_kj(T)/a_lim,j ≤ s, ΣT = K·T0)."""
    from scipy.optimize import minimize

    k = deltas.shape[0] - 1

    def rel(x: np.ndarray) -> np.ndarray:
        return ff._turn_relative(np.ascontiguousarray(x[:-1]), deltas, inv, first)[0].ravel()

    start = np.full(k, t0)
    x0 = np.append(start, ff.turn_peak(start, deltas, inv, first))
    constraints = [
        {"type": "ineq", "fun": lambda x: x[-1] - rel(x)},
        {"type": "ineq", "fun": lambda x: x[-1] + rel(x)},
        {"type": "eq", "fun": lambda x: x[:-1].sum() - k * t0},
    ]
    res = minimize(
        lambda x: x[-1],
        x0,
        jac=lambda x: np.r_[np.zeros(k), 1.0],
        constraints=constraints,
        bounds=[(1e-3 * t0, None)] * k + [(0.0, None)],
        method="SLSQP",
        options={"maxiter": 500, "ftol": 1e-12},
    )
    return float(ff.turn_peak(np.ascontiguousarray(res.x[:-1]), deltas, inv, first))


@pytest.mark.slow  # 7-15 s on 2 cores: the full command runs it, the quick one leaves it out
def test_the_turn_optimiser_comes_within_5_percent_of_the_direct_minimax(coarse):
    # eq. 15 per turn against a direct minimax solution of the same turn: the first (cold),
    # the next, the turns onto each new facet, the one the optimiser reduced least, the last
    inp, s, folder = coarse
    fplan, steps = s["_plan"], s["_steps"]
    k, turns = fplan.path.points_per_turn, fplan.path.n_turns
    q = fplan.axes_si()
    inv = 1.0 / fp.limits_of(catalogs.entry("machines", inp.machine, folder)).accel
    facet = fplan.path.facet[: turns * k : k]
    onto = [int(m) for m in np.flatnonzero(np.diff(facet)) + 1]
    worst = int(np.argmax(steps.peak_optimised / steps.peak_constant))
    for m in sorted({0, 1, *onto, worst, turns - 1}):
        direct = _direct_minimax(fp._turn_deltas(q, k, m), inv, m == 0, steps.reference)
        assert steps.peak_optimised[m] <= 1.05 * direct, (m, steps.peak_optimised[m], direct)
    # and never worse than constant steps on any turn (the fallback)
    assert np.all(steps.peak_optimised <= steps.peak_constant)


def test_machine_without_a_y_axis_is_refused():
    with pytest.raises(ff.FresnelError, match="not a 4-axis X-Y-Z-C lathe"):
        fp.limits_of(catalogs.entry("machines", "sts-xzc"), "sts-xzc")


# --------------------------------------------------------------------------- export
def test_export_and_verify_round_trip(coarse, tmp_path):
    inp, s, folder = coarse
    out = tmp_path / "fresnel.txt"
    side = tmp_path / "fresnel.json"
    fstudy.export(s, out, side, inp)
    lines = out.read_text().splitlines()
    assert lines[0].startswith(fstudy.F_MAGIC) and fstudy.F_COLUMNS in lines
    record = fstudy.verify(out)
    assert record["lines"] == s["n_points"] and record["within_limits"]
    assert abs(record["machining_s"] - s["time_adaptive_s"]) < 1e-6
    data = np.loadtxt(out, comments="#", skiprows=lines.index(fstudy.F_COLUMNS) + 1)
    assert np.all(np.diff(data[:, 0]) > 0.0)
    # a changed line is refused (CRC), and so is a line faster than the machine allows
    from ftsweep.exports.files import ProgramError

    start = lines.index(fstudy.F_COLUMNS) + 1
    bad = lines.copy()
    bad[start + 5] = bad[start + 5].replace(bad[start + 5].split()[2], "1.000000000")
    out.write_text("\n".join(bad) + "\n")
    with pytest.raises(ProgramError, match="CRC32"):
        fstudy.verify(out)
    data = np.array([[float(v) for v in line.split()] for line in lines[start:]])
    data[:, 0] *= 0.25
    limits = fp.limits_of(catalogs.entry("machines", inp.machine))
    assert "acceleration" in fstudy.lines_reason(data, limits)


def test_cli_fresnel_json_and_verify(coarse, tmp_path, monkeypatch):
    _, _, folder = coarse
    monkeypatch.setenv("FTSWEEP_CATALOGS", str(folder))
    runner = CliRunner()
    out = tmp_path / "p.txt"
    res = runner.invoke(
        main,
        [
            "fresnel",
            "--cutting",
            "coarse-fresnel",
            "--points-per-turn",
            str(K_TEST),
            "--facet-height-um",
            "10",
            "--json",
            "--plots",
            str(tmp_path),
            "-o",
            str(out),
        ],
    )
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["time_constant_s"] > doc["time_adaptive_s"] > 0
    assert doc["n_facets"] == 4
    for plot in doc["plots"]:
        assert (tmp_path / plot.split("/")[-1]).stat().st_size > 1000
    res = runner.invoke(main, ["verify", str(out)])
    assert res.exit_code == 0, res.output
    assert "every line within the machine's limits" in res.output
    res = runner.invoke(main, ["fresnel", "--machine", "sts-xzc", "--json"])
    assert res.exit_code != 0 and "4-axis" in res.output
