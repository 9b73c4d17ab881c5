"""Tool-nose compensation (model §4)."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from ftsweep.stages.interpolation import ray_commands
from ftsweep.stages.interpolation.compensation import SCAN_TOL_UM, arc_lift, compensate, contact_window_um
from ftsweep.stages.sampling.surfaces import FAMILIES, lens_array, radial_section, sinewave2d

LENS = dict(radius_um=252.5, sag_um=5.0, pitch_um=150.0, count_x=11, count_y=11)


def sine_params(ax, ay, lx, ly, px, py):
    return dict(
        amplitude_x_um=ax,
        amplitude_y_um=ay,
        wavelength_x_um=lx,
        wavelength_y_um=ly,
        phase_x_deg=px,
        phase_y_deg=py,
    )


def sine_sections(amplitude, wavelength, nose_radius):
    """Strategies of (Ax, Ay, λx, λy, φx, φy, Rc, seed) for random sinewave sections [µm, deg]."""
    return (
        st.floats(*amplitude),
        st.floats(*amplitude),
        st.floats(*wavelength),
        st.floats(*wavelength),
        st.floats(0.0, 360.0),
        st.floats(0.0, 360.0),
        st.floats(*nose_radius),
        st.integers(0, 2**32 - 1),
    )


def random_points(seed, radius, n=60):
    """n random radii [0, radius) µm and section angles [rad]."""
    rng = np.random.default_rng(seed)
    return rng.uniform(0.0, radius, n), rng.uniform(0.0, 2 * math.pi, n)


def sine_bounds(params):
    family = FAMILIES["sinewave2d"]
    return family.gradient_bound(**params), family.curvature_bound(**params)


def worst_undercut(surface, rho, theta, w, rc, n_s=2001):
    """Largest depth [µm] by which any arc at (ρ, θ) with lowest point w cuts below the design."""
    s = np.linspace(-0.999 * rc, 0.999 * rc, n_s)
    c, sn = np.cos(theta)[:, None], np.sin(theta)[:, None]
    g, _ = radial_section(surface, rho[:, None] + s[None, :], c, sn)
    arc = w[:, None] + arc_lift(s, rc)[None, :]
    return float(np.max(g - arc))


# random sinewaves and nose radii, gouging ones included
@given(*sine_sections(amplitude=(0.05, 1.0), wavelength=(60.0, 400.0), nose_radius=(20.0, 200.0)))
# sections with several local maxima that a five-sample scan missed (1.5 and 7.2 nm undercut)
@example(1.0, 1.0, 60.0, 60.0, 0.0, 26.0, 124.0, 0)
@example(1.0, 1.0, 60.0, 60.0, 196.0, 38.0, 99.0, 188)
def test_exact_compensation_never_cuts_below_the_design(ax, ay, lx, ly, px, py, rc, seed):
    params = sine_params(ax, ay, lx, ly, px, py)
    surface = functools.partial(sinewave2d, **params)
    bound, curvature = sine_bounds(params)
    rho, theta = random_points(seed, 1000.0)
    # with the family's curvature bound, as the case runner passes it
    w, gouge = compensate(surface, rho, theta, rc, "exact", bound, curvature_bound=curvature)
    undercut = worst_undercut(surface, rho, theta, w, rc)
    assert undercut <= 0.5e-3  # never more than 0.5 nm below the design
    # and it is tight: the arc touches the section (no gap above 0.5 nm either)
    assert undercut >= -0.5e-3 or gouge.any()


@given(st.floats(20.0, 200.0), st.integers(0, 2**32 - 1))
def test_exact_compensation_on_the_lens_array(rc, seed):
    surface = functools.partial(lens_array, **LENS)
    bound = FAMILIES["lens_array"].gradient_bound(**LENS)
    rho, theta = random_points(seed, 1100.0)
    curvature = FAMILIES["lens_array"].curvature_bound(**LENS)
    w, _ = compensate(surface, rho, theta, rc, "exact", bound, curvature_bound=curvature)
    undercut = worst_undercut(surface, rho, theta, w, rc, n_s=8001)
    assert -0.5e-3 <= undercut <= 0.5e-3


def test_uncompensated_and_slope_tables_cut_into_sloped_parts():
    params = sine_params(0.5, 0.5, 100.0, 100.0, 90.0, 90.0)
    surface = functools.partial(sinewave2d, **params)
    rho = np.linspace(100.0, 900.0, 200)
    theta = np.full(rho.size, 0.3)
    none, _ = compensate(surface, rho, theta, 83.0, "none")
    slope, _ = compensate(surface, rho, theta, 83.0, "slope")
    exact, _ = compensate(surface, rho, theta, 83.0, "exact", FAMILIES["sinewave2d"].gradient_bound(**params))
    assert worst_undercut(surface, rho, theta, none, 83.0) > 0.02  # tens of nm, §4
    # the slope approximation is close to exact (it ignores the contact's sideways shift)
    assert np.max(np.abs(slope - exact)) < 5e-3
    assert np.all(exact >= none - 1e-12)


def test_exact_matches_closed_form_on_a_plane():
    # on a plane of slope m the exact value is f + Rc·(sqrt(1 + m²) − 1): the slope formula
    m = 0.12
    surface = lambda x, y: (m * x, np.full_like(x, m), np.zeros_like(x))  # noqa: E731
    rho = np.linspace(0.0, 500.0, 51)
    w, gouge = compensate(surface, rho, np.zeros(rho.size), 83.0, "exact", m)
    np.testing.assert_allclose(w, m * rho + 83.0 * (math.sqrt(1 + m * m) - 1), atol=1e-9)
    assert not gouge.any()


def test_on_ray_solver_agrees_with_point_solver():
    params = sine_params(0.5, 0.5, 100.0, 100.0, 90.0, 90.0)
    surface = functools.partial(sinewave2d, **params)
    bound = FAMILIES["sinewave2d"].gradient_bound(**params)
    theta, spacing, rc = 0.7, 0.5, 83.0
    r = 600.0 - np.arange(0, 1000) * spacing  # nodes from 600 µm inwards
    g, gp = radial_section(surface, r, math.cos(theta), math.sin(theta))
    nodes = np.arange(20, 980, 2, dtype=np.int64)
    out = np.empty(nodes.size)
    ray_commands.compensate_on_ray(g, gp, spacing, rc, nodes, 0, out, False)
    ref, _ = compensate(surface, r[nodes], np.full(nodes.size, theta), rc, "exact", bound)
    np.testing.assert_allclose(out, ref, atol=0.05e-3)  # 0.05 nm
    for code, mode in ((1, "slope"), (2, "none")):
        ray_commands.compensate_on_ray(g, gp, spacing, rc, nodes, code, out, False)
        want, _ = compensate(surface, r[nodes], np.full(nodes.size, theta), rc, mode)
        np.testing.assert_allclose(out, want, atol=1e-12)


def test_gouge_is_flagged_where_concave_radius_is_below_rc():
    # curvature A·k² = 0.5·(2π/40)² ≈ 0.0123/µm > 1/83: troughs narrower than the tool
    tight = sine_params(0.5, 0.0, 40.0, 100.0, 0.0, 0.0)
    smooth = sine_params(0.5, 0.0, 200.0, 100.0, 0.0, 0.0)
    rho = np.linspace(0.0, 400.0, 400)
    theta = np.zeros(rho.size)
    for params, expect in ((tight, True), (smooth, False)):
        surface = functools.partial(sinewave2d, **params)
        bound = FAMILIES["sinewave2d"].gradient_bound(**params)
        w, gouge = compensate(surface, rho, theta, 83.0, "exact", bound)
        assert gouge.any() == expect
        assert worst_undercut(surface, rho, theta, w, 83.0) <= 0.5e-3


def test_rejects_bad_arguments():
    surface = functools.partial(sinewave2d, **sine_params(0.5, 0.5, 100.0, 100.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="unknown compensation mode"):
        compensate(surface, np.ones(3), np.zeros(3), 83.0, "magic")
    with pytest.raises(ValueError, match="exceeds the gradient bound"):
        compensate(surface, np.linspace(0, 100, 30), np.zeros(30), 83.0, "exact", 0.001)
    # the secant solver checks the slopes its kernels form, at the start and at every iterate
    _, curvature = sine_bounds(sine_params(0.5, 0.5, 100.0, 100.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="surface slope 0.03.* exceeds the gradient bound 0.001"):
        rho = np.linspace(0, 100, 30)
        compensate(surface, rho, np.zeros(30), 83.0, "exact", 1e-3, curvature_bound=curvature)


# ------------------------------------------------------------------ the fast (secant) solver
@given(*sine_sections(amplitude=(0.02, 1.0), wavelength=(60.0, 400.0), nose_radius=(20.0, 200.0)))
def test_secant_solver_equals_scan_and_refine_where_the_section_is_concave(ax, ay, lx, ly, px, py, rc, seed):
    params = sine_params(ax, ay, lx, ly, px, py)
    bound, curvature = sine_bounds(params)
    assume(curvature * rc < 1.0)  # h(s) strictly concave: one maximum, which both must find
    surface = functools.partial(sinewave2d, **params)
    rho, theta = random_points(seed, 1000.0)
    fast, gouge = compensate(
        surface, rho, theta, rc, "exact", bound, curvature_bound=curvature, solver="newton"
    )
    scan, _ = compensate(surface, rho, theta, rc, "exact", bound, solver="scan")  # the 5-sample scan
    np.testing.assert_allclose(fast, scan, rtol=0, atol=1e-6)
    assert not gouge.any()


@given(st.floats(20.0, 110.0), st.integers(0, 2**32 - 1))
def test_secant_solver_equals_scan_and_refine_on_the_lens_array(rc, seed):
    # K·Rc < 1 up to Rc ≈ 119 µm; the seams between sphere, torus and plane are only C¹
    surface = functools.partial(lens_array, **LENS)
    family = FAMILIES["lens_array"]
    bound, curvature = family.gradient_bound(**LENS), family.curvature_bound(**LENS)
    rho, theta = random_points(seed, 1100.0)
    fast, _ = compensate(surface, rho, theta, rc, "exact", bound, curvature_bound=curvature, solver="newton")
    scan, _ = compensate(surface, rho, theta, rc, "exact", bound, solver="scan")
    np.testing.assert_allclose(fast, scan, rtol=0, atol=1e-6)


def brute_force(surface, rho, theta, rc, bound, n_s=40001):
    """max over a dense grid of the contact window of eq. (3), without any search [µm]."""
    half = contact_window_um(bound, rc)
    s = np.linspace(-half, half, n_s)
    g, _ = radial_section(surface, rho[:, None] + s[None, :], np.cos(theta)[:, None], np.sin(theta)[:, None])
    return np.max(g - arc_lift(s, rc)[None, :], axis=1)


@settings(max_examples=30, deadline=None)
@given(*sine_sections(amplitude=(0.3, 1.0), wavelength=(30.0, 80.0), nose_radius=(60.0, 200.0)))
def test_dense_scan_finds_the_global_maximum_on_gouging_sections(ax, ay, lx, ly, px, py, rc, seed):
    params = sine_params(ax, ay, lx, ly, px, py)
    bound, curvature = sine_bounds(params)
    assume(curvature * rc >= 1.0)  # h(s) may have several maxima (gouging)
    surface = functools.partial(sinewave2d, **params)
    rho, theta = random_points(seed, 1000.0, n=40)
    w, _ = compensate(surface, rho, theta, rc, "exact", bound, curvature_bound=curvature)
    ref = brute_force(surface, rho, theta, rc, bound)
    # the brute-force grid is within ~1e-8 µm of the true maximum; the solver within SCAN_TOL_UM
    assert np.all(w >= ref - SCAN_TOL_UM - 1e-8)
    assert np.all(w <= ref + 1e-7)  # a sample of h never exceeds its maximum


@given(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(20.0, 400.0), st.floats(20.0, 400.0))
def test_sinewave_curvature_bound_holds(ax, ay, lx, ly):
    params = sine_params(ax, ay, lx, ly, 37.0, 11.0)
    check_curvature_bound(functools.partial(sinewave2d, **params), sine_bounds(params)[1], 1000.0)


@given(st.floats(100.0, 500.0), st.floats(1.0, 20.0))
def test_lens_array_curvature_bound_holds(radius, sag):
    params = {**LENS, "radius_um": radius, "sag_um": sag}
    check_curvature_bound(
        functools.partial(lens_array, **params), FAMILIES["lens_array"].curvature_bound(**params), 800.0
    )


def check_curvature_bound(surface, bound, half_width, n=20000, eps=1e-3):
    """|∇f(p + εu) − ∇f(p)|/ε = |H·u| ≤ ‖H‖ at random points p and directions u."""
    rng = np.random.default_rng(7)
    x, y = rng.uniform(-half_width, half_width, (2, n))
    phi = rng.uniform(0.0, 2 * math.pi, n)
    _, fx0, fy0 = surface(x, y)
    _, fx1, fy1 = surface(x + eps * np.cos(phi), y + eps * np.sin(phi))
    quotient = np.hypot(fx1 - fx0, fy1 - fy0) / eps
    assert quotient.max() <= bound * (1.0 + 1e-3) + 1e-9
    assert quotient.max() >= 0.3 * bound  # and the bound is not vacuous


def test_a_wrong_curvature_bound_is_refused():
    params = sine_params(0.5, 0.5, 100.0, 100.0, 90.0, 90.0)
    surface = functools.partial(sinewave2d, **params)
    bound, curvature = sine_bounds(params)
    rho, theta = random_points(3, 1000.0, n=500)
    with pytest.raises(ValueError, match="exceeds the curvature bound"):
        compensate(surface, rho, theta, 83.0, "exact", bound, curvature_bound=0.2 * curvature)


def _sampled_maximum(g, spacing, rc, n):
    """The exact command at node n by brute force over the sampled section: the best sample
    h_j = g[n + j] − arc(j·spacing) in the whole window, refined by the parabola through it and
    its neighbours (what the climb converges to on a single-peaked section)."""
    jmax = int(rc / spacing) - 1
    j = np.arange(max(-jmax, -n), min(jmax, g.size - 1 - n) + 1)
    h = g[n + j] - (rc - np.sqrt(np.maximum(rc * rc - (j * spacing) ** 2, 0.0)))
    b = int(np.argmax(h))
    if 0 < b < h.size - 1:
        hm, hj, hp = h[b - 1], h[b], h[b + 1]
        curv = hm - 2.0 * hj + hp
        if curv < 0.0:
            return hj - (hp - hm) * (hp - hm) / (8.0 * curv)
    return h[b]


@settings(max_examples=80, deadline=None)
@given(
    st.floats(-0.6, 0.6),
    st.floats(-0.008, 0.008),
    st.floats(20.0, 150.0),
    st.integers(0, 2**32 - 1),
    st.booleans(),
    st.booleans(),
)
def test_on_ray_climb_finds_the_sampled_maximum(slope, curvature, rc, seed, from_passes, even):
    """From any start, gentle slopes (the series start), steep ones (the exact start) and the
    line through the last two passes' contacts alike, on passes at random nodes or evenly
    spaced as on a path grid, the climb ends on the best sample of a single-peaked section
    (curvature below 1/Rc)."""
    rng = np.random.default_rng(seed)
    spacing = 0.5
    r = 400.0 - np.arange(1600) * spacing
    phase = rng.uniform(0.0, 2.0 * math.pi)
    c = min(curvature, 0.9 / rc)  # with the wiggle's ≤ 0.2/31² µm⁻¹, below 1/Rc
    g = slope * r + 0.5 * c * (r - 200.0) ** 2 + 0.2 * np.sin(r / 31.0 + phase)
    gp = slope + c * (r - 200.0) + 0.2 / 31.0 * np.cos(r / 31.0 + phase)
    if even:
        nodes = np.arange(int(rng.integers(1, 20)), 1599, int(rng.integers(1, 5)), dtype=np.int64)
    else:
        nodes = np.sort(rng.choice(np.arange(1, 1599), 60, replace=False)).astype(np.int64)
    out = np.empty(nodes.size)
    ray_commands.compensate_on_ray(g, gp, spacing, rc, nodes, 0, out, from_passes)
    want = np.array([_sampled_maximum(g, spacing, rc, int(n)) for n in nodes])
    np.testing.assert_array_equal(out, want)
