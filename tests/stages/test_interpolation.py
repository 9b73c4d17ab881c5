"""The controller's bilinear interpolation (model §3) and the spiral path (§1)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ftsweep.stages.interpolation import tables as interpolation
from ftsweep.stages.layouts import grids as layouts
from ftsweep.stages.paths import spiral

coef = st.floats(-10.0, 10.0)


@given(coef, coef, coef, coef, st.integers(0, 2**32 - 1))
def test_mesh_reproduces_bilinear_functions(a, b, c, d, seed):
    lay = layouts.mesh_layout(100.0, 60.0, 7.0, 3.0)
    x, y = (
        np.asarray(v)
        for v in np.meshgrid(
            lay.origin[0] + np.arange(lay.shape[0]) * lay.pitch[0],
            lay.origin[1] + np.arange(lay.shape[1]) * lay.pitch[1],
            indexing="ij",
        )
    )
    table = a + b * x + c * y + d * x * y
    rng = np.random.default_rng(seed)
    qx = rng.uniform(-50.0, 50.0, 500)
    qy = rng.uniform(-30.0, 30.0, 500)
    got = interpolation.interpolate(lay, table, np.hypot(qx, qy), np.arctan2(qy, qx))
    np.testing.assert_allclose(got, a + b * qx + c * qy + d * qx * qy, rtol=1e-9, atol=1e-9)


@given(coef, coef, coef, coef, st.integers(0, 2**32 - 1))
def test_ring_reproduces_bilinear_functions_of_rho_and_theta(a, b, c, d, seed):
    lay = layouts.ring_layout(100.0, 2.5, 360.0 / 48)
    rho, theta = layouts.layout_nodes(lay)
    deg = np.degrees(theta)
    table = a + b * rho + c * deg + d * rho * deg
    rng = np.random.default_rng(seed)
    # away from the seam the table is one bilinear function of (ρ, θ[deg])
    qr = rng.uniform(0.0, 100.0, 500)
    qt = rng.uniform(0.0, 360.0 - lay.pitch[1], 500)
    got = interpolation.interpolate(lay, table, qr, np.radians(qt))
    np.testing.assert_allclose(got, a + b * qr + c * qt + d * qr * qt, rtol=1e-9, atol=1e-8)


@given(coef, coef, coef, coef, st.integers(0, 2**32 - 1))
def test_ring_reproduces_bilinear_functions_across_the_seam(a, b, c, d, seed):
    """Across θ = 0/360° column Np−1 neighbours column 0: a function bilinear in (ρ, φ) with
    φ measured forward from the last column is reproduced in the wrap-around cell."""
    lay = layouts.ring_layout(100.0, 2.5, 360.0 / 48)
    dth = lay.pitch[1]
    last = 360.0 - dth
    rho, theta = layouts.layout_nodes(lay)
    phi = (np.degrees(theta) - last) % 360.0  # 0 on the last column, Δθ on column 0
    table = a + b * rho + c * phi + d * rho * phi
    rng = np.random.default_rng(seed)
    qr = rng.uniform(0.0, 100.0, 500)
    qphi = rng.uniform(0.0, dth, 500)
    qt = (last + qphi) % 360.0
    # the same angle given below 0 or past 360 must interpolate identically
    for shift in (0.0, 360.0, -360.0):
        got = interpolation.interpolate(lay, table, qr, np.radians(qt + shift))
        np.testing.assert_allclose(got, a + b * qr + c * qphi + d * qr * qphi, rtol=1e-9, atol=1e-8)


def test_table_nodes_are_reproduced_exactly_and_edges_clamp():
    lay = layouts.ring_layout(10.0, 2.0, 90.0)
    table = np.arange(24.0).reshape(6, 4)
    rho, theta = layouts.layout_nodes(lay)
    np.testing.assert_array_equal(interpolation.interpolate(lay, table, rho, theta), table)
    # beyond the last ring the controller holds the edge value
    beyond = interpolation.interpolate(lay, table, np.array([12.0, 50.0]), np.radians([90.0, 90.0]))
    np.testing.assert_array_equal(beyond, [table[-1, 1], table[-1, 1]])


def test_bilinear_broadcasts_theta_against_rho():
    lay = layouts.ring_layout(10.0, 2.0, 90.0)
    table = np.arange(24.0).reshape(6, 4)
    rho = np.array([[1.0, 3.0, 5.0], [2.0, 4.0, 6.0]])
    theta = np.radians(np.array([[45.0], [200.0]]))
    got = interpolation.interpolate(lay, table, rho, theta)
    want = interpolation.interpolate(lay, table, rho, np.broadcast_to(theta, rho.shape).copy())
    np.testing.assert_array_equal(got, want)


@given(st.floats(100.0, 2000.0), st.floats(0.2, 5.0), st.integers(1, 8))
def test_spiral_passes_and_nodes(rho0, feed, ppf):
    lines = interpolation.line_angles(16)
    grid = interpolation.path_grid(lines, rho0, feed, ppf, margin_um=3.0)
    # rays 2l and 2l+1 are opposite
    np.testing.assert_allclose(grid.ray_theta[1::2] - grid.ray_theta[0::2], math.pi)
    # ρ_k = ρ0 − F·(k + θ/2π), and the last pass is the last one with ρ ≥ 0
    k = np.arange(grid.pass_rho.shape[1])
    np.testing.assert_allclose(
        grid.pass_rho, rho0 - feed * (k[None, :] + grid.ray_theta[:, None] / (2 * math.pi))
    )
    last = grid.pass_rho[np.arange(grid.ray_theta.size), grid.n_passes - 1]
    assert np.all(last >= -1e-9) and np.all(last < feed)
    # passes sit on nodes n = k·ppf
    rows = np.arange(grid.ray_theta.size)[:, None]
    np.testing.assert_allclose(grid.node_r[rows, grid.pass_nodes], grid.pass_rho, atol=1e-9)
    assert grid.node_r[:, 0].min() >= grid.first_pass.min() + 3.0 - 1e-9
    assert grid.node_r[:, -1].max() <= -3.0 + 1e-9


def test_line_angles_cover_the_circle_evenly():
    lines = interpolation.line_angles(8)
    rays = np.sort(np.concatenate([lines, lines + math.pi]))
    np.testing.assert_allclose(np.diff(rays), 2 * math.pi / 8)
    with pytest.raises(ValueError, match="even"):
        interpolation.line_angles(7)


def test_hermite_sampling_is_exact_for_cubics():
    lines = interpolation.line_angles(4)
    grid = interpolation.path_grid(lines, 50.0, 1.0, 2, 3.0)
    r = grid.node_r
    g = 0.3 + 0.01 * r - 2e-4 * r**2 + 1e-6 * r**3
    gp = 0.01 - 4e-4 * r + 3e-6 * r**2
    q = np.array([[10.3, 20.77, np.nan]] * r.shape[0])
    got = interpolation.sample_on_nodes(grid, g, gp, q)
    want = 0.3 + 0.01 * q - 2e-4 * q**2 + 1e-6 * q**3
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("kind", ["ring", "mesh"])
def test_pass_commands_are_the_lookup_at_the_pass_positions_bit_for_bit(kind):
    """The fused pass-command kernel forms ρ_k and the table indices itself; it must give
    exactly what the lookup at max(pass_rho, 0) gives (the stored expectations rely on it)."""
    rng = np.random.default_rng(7)
    lay = (
        layouts.ring_layout(400.0, 7.0, 3.0)
        if kind == "ring"
        else layouts.mesh_layout(800.0, 800.0, 9.0, 13.0)
    )
    table = rng.normal(size=lay.shape)
    lines = interpolation.line_angles(38)
    grid = interpolation.path_grid(lines, 400.0, 5.0, 2, 12.0)
    want = interpolation.interpolate(lay, table, np.maximum(grid.pass_rho, 0.0), grid.ray_theta[:, None])
    got = interpolation.pass_commands(lay, table, grid)
    np.testing.assert_array_equal(got, want)


@given(st.floats(100.0, 2000.0), st.floats(0.2, 5.0), st.integers(1, 8), st.floats(0.05, 1.2))
def test_a_grid_left_out_beyond_a_reach_is_the_tail_of_the_whole_grid(rho0, feed, ppf, frac):
    """Passes beyond ``reach_um`` on every ray are left out with their nodes; what is held
    is the whole spiral's grid to the last bit, and every pass within the reach is held."""
    lines = interpolation.line_angles(16)[3:7]
    whole = interpolation.path_grid(lines, rho0, feed, ppf, margin_um=3.0)
    reach = frac * rho0
    part = interpolation.path_grid(lines, rho0, feed, ppf, margin_um=3.0, reach_um=reach)
    k0, j0 = part.first_revolution, part.first_revolution * ppf
    assert part.node_offset == whole.node_offset and part.origin_node == whole.node_offset - j0
    np.testing.assert_array_equal(part.node_r, whole.node_r[:, j0:])
    np.testing.assert_array_equal(part.n_passes, whole.n_passes - k0)
    np.testing.assert_array_equal(part.pass_rho, whole.pass_rho[:, k0 : k0 + part.pass_rho.shape[1]])
    # pass k0 − 1, the last one left out, lies beyond the reach on every ray
    if k0 > 0:
        assert np.all(whole.pass_rho[:, k0 - 1] > reach)
    assert np.all(part.pass_rho[:, 0] <= reach + feed) or k0 == 0
    table = np.random.default_rng(1).normal(size=50)
    path = spiral.constant_angle(rho0, feed, 50)
    values = np.interp(np.arange(path.phi.size), np.arange(50) * path.phi.size / 50, table)
    got = interpolation.pass_commands(path, values, part)
    want = interpolation.pass_commands(path, values, whole)[:, k0 : k0 + got.shape[1]]
    held = np.arange(got.shape[1])[None, :] < part.n_passes[:, None]
    np.testing.assert_array_equal(got[held], want[held])


def test_infinite_and_nan_indices_are_held_at_an_edge():
    table = np.arange(20.0).reshape(4, 5)
    u = np.array([np.inf, -np.inf, 1.5, 1.5, np.nan])
    v = np.array([2.0, 2.0, np.inf, -np.inf, 2.0])
    got = interpolation.bilinear(table, u, v, False)
    # ±inf lie beyond the last or the first row or column: the controller holds that edge
    edges = [table[3, 2], table[0, 2], 0.5 * (table[1, 4] + table[2, 4]), 0.5 * (table[1, 0] + table[2, 0])]
    np.testing.assert_array_equal(got[:4], edges)
    assert np.isnan(got[4])  # a NaN index never reads outside the table: its value is NaN


@settings(max_examples=100, deadline=None)
@given(st.integers(1, 6), st.integers(1, 9), st.integers(0, 2**32 - 1))
def test_nonfinite_passes_counts_only_the_passes(rays, kmax, seed):
    rng = np.random.default_rng(seed)
    w = rng.normal(size=(rays, kmax))
    n_passes = rng.integers(0, kmax + 1, rays)
    bad = rng.random((rays, kmax)) < 0.3
    w[bad] = rng.choice([np.nan, np.inf, -np.inf], int(bad.sum()))
    valid = np.arange(kmax)[None, :] < n_passes[:, None]
    expected = ~np.isfinite(w) & valid
    count, first = interpolation.nonfinite_passes(w, n_passes)
    assert count == int(expected.sum())
    assert first == (int(np.flatnonzero(expected.ravel())[0]) if count else -1)
