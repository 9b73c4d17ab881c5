"""Envelope of the tool arcs (model §5): exact lower envelope, feed cusps."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ftsweep.stages.envelope import arcs as envelope


def brute_force(pos, w, rc, query):
    d = query[:, None] - pos[None, :]
    arcs = np.where(np.abs(d) < rc, w[None, :] + rc - np.sqrt(np.maximum(rc * rc - d * d, 0.0)), np.inf)
    return arcs.min(axis=1)


def run_envelope(pos, w, rc, query):
    out = np.empty(query.size)
    stack = np.empty(pos.size, dtype=np.int64)
    breaks = np.empty(pos.size)
    n = envelope.lower_envelope(pos, w, rc, query, out, stack, breaks)
    return out, stack[:n], breaks[1:n]


@settings(max_examples=200, deadline=None)
@given(
    st.integers(2, 60),
    st.floats(0.2, 5.0),
    st.floats(10.0, 200.0),
    st.floats(0.0, 0.3),
    st.integers(0, 2**32 - 1),
)
def test_lower_envelope_equals_brute_force(n, feed, rc, slope, seed):
    rng = np.random.default_rng(seed)
    pos = np.cumsum(rng.uniform(0.2, 1.0, n) * feed)
    w = slope * pos + rng.normal(0.0, 0.05 * feed, n)  # a sloped, rough command sequence
    query = np.sort(rng.uniform(pos[0], pos[-1], 400))
    got, _, _ = run_envelope(pos, w, rc, query)
    np.testing.assert_allclose(got, brute_force(pos, w, rc, query), rtol=0, atol=1e-12)


@given(st.floats(0.1, 10.0), st.floats(20.0, 500.0))
def test_flat_cusps_are_f2_over_8rc(feed, rc):
    pos = np.arange(40) * feed
    w = np.zeros(pos.size)
    query = np.linspace(pos[5], pos[-5], 4001)
    z, _, breaks = run_envelope(pos, w, rc, query)
    cusp = feed**2 / (8 * rc)
    assert abs(z.max() - cusp) <= 0.02 * cusp  # nodes sample within 2 %
    # the breakpoints are the cusp peaks, midway between passes
    np.testing.assert_allclose(breaks, pos[:-1] + 0.5 * feed, atol=1e-9)
    zb, _, _ = run_envelope(pos, w, rc, breaks[5:-5].copy())
    np.testing.assert_allclose(zb, rc - math.sqrt(rc * rc - feed * feed / 4), rtol=1e-9)


def test_envelope_lines_covers_both_rays_and_reports_cusps():
    # two rays of one line; flat commands; 20 passes, 2 nodes per feed
    feed, rc, ppf, off = 1.0, 50.0, 2, 4
    n_nodes = off + 2 * 20 + 10
    first = np.array([19.9, 19.4])
    node_r = first[:, None] - (np.arange(n_nodes)[None, :] - off) * (feed / ppf)
    n_passes = np.array([20, 20])
    pass_w = np.zeros((2, 20))
    z = np.empty(node_r.shape)
    cr = np.empty((2, 22))
    cz = np.empty((2, 22))
    envelope.envelope_lines(node_r, pass_w, n_passes, off, ppf, off + ppf, rc, z, cr, cz)
    ev = ~np.isnan(z)
    assert np.all(node_r[ev] >= 0.0) and np.all(node_r[ev] <= first[:, None].max() - feed + 1e-9)
    cusp = rc - math.sqrt(rc * rc - 0.25)
    # across the axis the last passes of the two rays (0.9 and −0.4 µm) are 1.3 feeds apart,
    # so that one cusp is higher; everywhere else the flat-surface cusp F²/8Rc
    gap = 0.9 + 0.4
    axis_cusp = rc - math.sqrt(rc * rc - 0.25 * gap * gap)
    assert np.nanmax(z) <= axis_cusp + 1e-12
    assert np.nanmin(z) >= -1e-12
    peaks = ~np.isnan(cr)
    away = peaks & ~np.isclose(cr, 0.5 * (0.9 - 0.4))  # the axis cusp sits midway across the axis
    np.testing.assert_allclose(cz[away], cusp, rtol=1e-6)
    np.testing.assert_allclose(cz[peaks & ~away], axis_cusp, rtol=1e-6)
    assert peaks[0].sum() + peaks[1].sum() == 2 * 19 + 1 - 2  # all peaks but the two first ones


@settings(max_examples=150, deadline=None)
@given(
    st.integers(2, 40),
    st.sampled_from([1, 2, 3]),
    st.floats(0.0, 0.2),
    st.integers(-3, 200),
    st.integers(0, 2**32 - 1),
)
def test_envelope_lines_cusps_are_the_hull_breaks_on_each_ray(n_pass, ppf, slope, start, seed):
    """Each ray's cusp peaks are the takeovers of the line's hull (lower_envelope of both rays'
    passes in ascending position) within its evaluated part, in order, NaN-padded; wherever
    the evaluation starts, including past the axis on one ray only."""
    rng = np.random.default_rng(seed)
    feed, rc = 1.0, 30.0
    off = 3
    n_nodes = off + ppf * n_pass + 4
    first = np.array([n_pass - 0.3, n_pass - 0.8])  # the opposite ray is half a feed inwards
    node_r = first[:, None] - (np.arange(n_nodes)[None, :] - off) * (feed / ppf)
    n_passes = np.array([n_pass, n_pass])
    pass_w = slope * node_r[:, off : off + ppf * n_pass : ppf] + rng.uniform(0.0, 0.05, (2, n_pass))
    start = min(start, n_nodes + 2)
    z = np.empty(node_r.shape)
    cr, cz = np.full((2, n_pass + 2), 7.0), np.full((2, n_pass + 2), 7.0)
    envelope.envelope_lines(node_r, pass_w, n_passes, off, ppf, start, rc, z, cr, cz)
    passes = slice(off, off + ppf * n_pass, ppf)
    pos = np.concatenate([-node_r[1, passes], node_r[0, passes][::-1]])
    w = np.concatenate([pass_w[1], pass_w[0][::-1]])
    out, stack, breaks = run_envelope(pos, w, rc, np.zeros(1))
    top = [node_r[a, start] if start < n_nodes else -1.0 for a in (0, 1)]
    height = w[stack[1:]] + rc - np.sqrt(np.maximum(rc * rc - (breaks - pos[stack[1:]]) ** 2, 0.0))
    opp = (breaks < 0.0) & (-breaks <= top[1])
    own = (breaks >= 0.0) & (breaks <= top[0])
    for row, sel, sign in ((1, opp, -1.0), (0, own, 1.0)):
        k = int(sel.sum())
        np.testing.assert_array_equal(cr[row, :k], sign * breaks[sel])
        np.testing.assert_array_equal(cz[row, :k], height[sel])
        assert np.isnan(cr[row, k:]).all() and np.isnan(cz[row, k:]).all()
