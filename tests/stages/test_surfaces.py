"""Surface families (model §7): gradients, continuity, reference geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ftsweep.inputs import catalogs
from ftsweep.stages.sampling.surfaces import FAMILIES, Aperture, lens_array, radial_section, sinewave2d

LENS = dict(radius_um=252.5, sag_um=5.0, pitch_um=150.0, count_x=11, count_y=11)
SINE = dict(
    amplitude_x_um=0.5,
    amplitude_y_um=0.5,
    wavelength_x_um=100.0,
    wavelength_y_um=100.0,
    phase_x_deg=90.0,
    phase_y_deg=90.0,
)


def finite_difference(fn, x, y, h=1e-4):
    fxp, _, _ = fn(x + h, y)
    fxm, _, _ = fn(x - h, y)
    fyp, _, _ = fn(x, y + h)
    fym, _, _ = fn(x, y - h)
    return (fxp - fxm) / (2 * h), (fyp - fym) / (2 * h)


@given(st.integers(0, 2**32 - 1))
def test_sinewave_gradient_matches_finite_difference(seed):
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(-1000, 1000, (2, 200))
    fn = lambda a, b: sinewave2d(a, b, **SINE)  # noqa: E731
    _, fx, fy = fn(x, y)
    dx, dy = finite_difference(fn, x, y)
    np.testing.assert_allclose(fx, dx, atol=1e-7)
    np.testing.assert_allclose(fy, dy, atol=1e-7)


@given(st.integers(0, 2**32 - 1))
def test_lens_array_gradient_matches_finite_difference_away_from_seams(seed):
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(-825, 825, (2, 400))
    fn = lambda a, b: lens_array(a, b, **LENS)  # noqa: E731
    _, fx, fy = fn(x, y)
    dx, dy = finite_difference(fn, x, y)
    # the blend is C1, so the gradient is continuous even across seams; only the
    # cell boundaries between lenslets (where r > Rt is plane on both sides) are exact
    np.testing.assert_allclose(fx, dx, atol=2e-5)
    np.testing.assert_allclose(fy, dy, atol=2e-5)


def _lens_piecewise(x: float, y: float) -> tuple[float, float, float]:
    """lens_array's formulas (model §7) one point at a time, branch by branch, in Python."""
    R, h, pitch, n = 252.5, 5.0, 150.0, 11
    a = math.sqrt(2 * h * R - h * h)
    rt = R / 2
    Rt = a * (1 + rt / R)
    i = min(max(math.floor(x / pitch + (n - 1) / 2 + 0.5), 0), n - 1)
    j = min(max(math.floor(y / pitch + (n - 1) / 2 + 0.5), 0), n - 1)
    dx, dy = x - (i - (n - 1) / 2) * pitch, y - (j - (n - 1) / 2) * pitch
    r = math.hypot(dx, dy)
    if r <= a:
        root = math.sqrt(R * R - r * r)
        return R - h - root, dx / root, dy / root
    if r <= Rt:
        root = math.sqrt(max(rt * rt - (r - Rt) ** 2, 0.0))
        q = -(r - Rt) / (root * r) if root > 0 else 0.0
        return root - rt * (R - h) / R, q * dx, q * dy
    return rt * h / R, 0.0, 0.0


@given(st.integers(0, 2**32 - 1))
def test_lens_array_branch_free_kernel_selects_each_points_own_piece(seed):
    # the kernel forms every piece and selects (so that it vectorises): the values are those
    # of evaluating the point's own piece, at random points and on the seams r = a, r = Rt,
    # the lenslet centres and beyond the outermost lenslets
    rng = np.random.default_rng(seed)
    ang = rng.uniform(0, 2 * np.pi, 60)
    centres = rng.integers(-5, 6, (2, 60)) * 150.0
    radii = rng.choice([0.0, 50.0, 75.0, 49.999999, 75.000001, 30.0, 60.0], 60)
    x = np.concatenate([rng.uniform(-1000, 1000, 200), centres[0] + radii * np.cos(ang)])
    y = np.concatenate([rng.uniform(-1000, 1000, 200), centres[1] + radii * np.sin(ang)])
    f, fx, fy = lens_array(x, y, **LENS)
    ref = np.array([_lens_piecewise(a, b) for a, b in zip(x, y, strict=True)])
    np.testing.assert_allclose(f, ref[:, 0], rtol=0, atol=1e-13)
    np.testing.assert_allclose(fx, ref[:, 1], rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(fy, ref[:, 2], rtol=1e-14, atol=1e-15)


def test_lens_array_geometry():
    a = math.sqrt(2 * 5.0 * 252.5 - 25.0)
    assert a == pytest.approx(50.0)
    f, fx, fy = lens_array(
        np.array([0.0, 150.0, 50.0, 75.0, 75.0 + 1e-9, 70.0]),
        np.array([0.0, -300.0, 0.0, 0.0, 0.0, 70.0]),
        **LENS,
    )
    assert f[0] == pytest.approx(-5.0)  # the lenslet bottom, sag h below the seam
    assert f[1] == pytest.approx(-5.0)  # every lenslet is the same
    assert f[2] == pytest.approx(0.0, abs=1e-12)  # the sphere meets the torus at f = 0
    assert f[3] == pytest.approx(2.5)  # the torus top meets the plane rt·h/R
    assert f[4] == pytest.approx(2.5)
    assert f[5] == pytest.approx(2.5) and fx[5] == 0.0 and fy[5] == 0.0  # a cell corner: plane


def test_gradient_bounds_hold():
    for fam, params in (("sinewave2d", SINE), ("lens_array", LENS)):
        family = FAMILIES[fam]
        bound = family.gradient_bound(**params)
        x, y = np.meshgrid(np.linspace(-825, 825, 801), np.linspace(-825, 825, 801))
        _, fx, fy = family.evaluate(x, y, **params)
        steepest = np.hypot(fx, fy).max()
        assert steepest <= bound * (1 + 1e-12)
        assert steepest >= 0.95 * bound  # and the bound is tight, so contact windows stay small


def test_radial_section_through_the_axis():
    f, gp = radial_section(
        lambda x, y: (x + 2 * y, np.ones_like(x), 2 * np.ones_like(x)),
        np.array([-3.0, 0.0, 3.0]),
        math.cos(0.3),
        math.sin(0.3),
    )
    np.testing.assert_allclose(f, np.array([-3.0, 0.0, 3.0]) * (math.cos(0.3) + 2 * math.sin(0.3)))
    np.testing.assert_allclose(gp, math.cos(0.3) + 2 * math.sin(0.3))


def test_apertures():
    circle = Aperture("circle", radius_um=10.0)
    rect = Aperture("rectangle", width_um=20.0, height_um=10.0)
    x = np.array([0.0, 9.0, 8.0, 10.0])
    y = np.array([0.0, 4.0, 8.0, 5.0])
    np.testing.assert_array_equal(circle.contains(x, y), [True, True, False, False])
    np.testing.assert_array_equal(rect.contains(x, y), [True, True, False, True])
    assert rect.outer_radius_um == pytest.approx(math.hypot(10, 5))
    assert rect.inner_radius_um == 5.0 and circle.outer_radius_um == 10.0
    assert rect.half_extent_um == (10.0, 5.0) and circle.half_extent_um == (10.0, 10.0)


def test_catalog_surfaces_build_callables():
    spec = catalogs.entry("surfaces", "sinewave2d")
    f, _, _ = catalogs.surface_callable(spec)(np.array([0.0]), np.array([0.0]))
    assert f[0] == pytest.approx(1.0)  # both cosines at their crest


LINE_FAMILIES = {"sinewave2d": SINE, "lens_array": LENS}


def test_every_line_evaluator_is_checked_here():
    # a family that registers a line evaluator must add its parameters to LINE_FAMILIES
    assert {name for name, fam in FAMILIES.items() if fam.lines is not None} == set(LINE_FAMILIES)


@pytest.mark.parametrize("name", sorted(LINE_FAMILIES))
@given(
    seed=st.integers(0, 2**32 - 1),
    spacing=st.floats(0.05, 20.0),
    offset=st.integers(0, 40),
    n_nodes=st.integers(1, 700),
)
def test_line_evaluator_equals_the_section_of_the_pointwise_surface(name, seed, spacing, offset, n_nodes):
    # the line evaluators sample the node grid of path_grid in one pass; sinewave2d carries
    # its sin/cos by rotation between exact anchors, which may move g by a few 1e-15
    # relative, so it is compared to 1e-12 µm (1e-9 nm), lens_array to the last bit
    from ftsweep.stages.interpolation.tables import path_grid

    rng = np.random.default_rng(seed)
    family, params = FAMILIES[name], LINE_FAMILIES[name]
    grid = path_grid(np.sort(rng.uniform(0.0, math.pi, 3)), rng.uniform(100.0, 900.0), 4.0 * spacing, 4, 0.0)
    node_r = grid.first_pass[:, None] - (np.arange(n_nodes)[None, :] - offset) * spacing
    ct, sn = np.cos(grid.ray_theta[:, None]), np.sin(grid.ray_theta[:, None])
    g0, gp0 = radial_section(lambda x, y: family.evaluate(x, y, **params), node_r, ct, sn)
    g1, gp1 = family.lines(grid.first_pass, spacing, offset, n_nodes, ct, sn, **params)
    assert g1.shape == gp1.shape == node_r.shape
    tol = 0.0 if name == "lens_array" else 1e-12
    np.testing.assert_allclose(g1, g0, rtol=0.0, atol=tol)
    np.testing.assert_allclose(gp1, gp0, rtol=0.0, atol=tol)


def test_line_evaluator_refuses_mismatched_rays():
    with pytest.raises(ValueError, match="one cos and sin per ray"):
        FAMILIES["sinewave2d"].lines(np.zeros(3), 1.0, 0, 5, np.ones(2), np.zeros(2), **SINE)
