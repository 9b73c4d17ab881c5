"""The vectorisable sine and cosine (stages.trig) against the C library's."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from ftsweep.stages.numerics import trig
from ftsweep.stages.sampling.surfaces import sinewave2d

# 2 ulp of 1: the documented accuracy, in absolute value (|sin|, |cos| ≤ 1)
TOL = 2.0 * 2.0**-52


def libm(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The C library's cos and sin (Python's math module; NaN where it refuses ±inf)."""
    finite = np.isfinite(x)
    c = np.array([math.cos(v) if ok else math.nan for v, ok in zip(x, finite, strict=True)])
    s = np.array([math.sin(v) if ok else math.nan for v, ok in zip(x, finite, strict=True)])
    return c, s


@given(st.lists(st.floats(-trig.REACH, trig.REACH), min_size=1, max_size=50))
def test_within_two_ulp_of_the_c_library(values):
    x = np.array(values)
    c, s = trig.cos_sin(x)
    c0, s0 = libm(x)
    assert np.all(np.abs(c - c0) <= TOL) and np.all(np.abs(s - s0) <= TOL)


def test_hardest_arguments_and_every_quadrant():
    # multiples of π/2 (the reduction cancels to the last bits) and their neighbours, up to
    # the reach; plus a dense sweep of a few periods for the quadrant signs
    n = np.arange(-(2**19), 2**19, 97, dtype=np.float64)
    base = n * (math.pi / 2)
    ends = [0.0, -0.0, 1e-300, -trig.REACH, trig.REACH]
    x = np.concatenate(
        [
            base,
            np.nextafter(base, np.inf),
            np.nextafter(base, -np.inf),
            np.linspace(-20.0, 20.0, 40_001),
            ends,
        ]
    )
    c, s = trig.cos_sin(x)
    c0, s0 = libm(x)
    assert np.max(np.abs(c - c0)) <= TOL and np.max(np.abs(s - s0)) <= TOL
    # relative accuracy where the values themselves are not tiny: the sign and size of a
    # quadrant are right, not only their difference
    big = np.abs(s0) > 1e-3
    assert np.max(np.abs(s - s0)[big] / np.abs(s0[big])) < 1e-14


def test_beyond_the_reach_the_c_library_answers():
    x = np.array([0.3, trig.REACH * 1.5, -1e300, np.inf, -np.inf, np.nan, 2.0])
    c, s = trig.cos_sin(x)
    c0, s0 = libm(x)
    # beyond the reach exactly the C library's values (NaN where it gives NaN)
    np.testing.assert_array_equal(c[1:6], c0[1:6])
    np.testing.assert_array_equal(s[1:6], s0[1:6])
    assert np.all(np.abs(c[[0, 6]] - c0[[0, 6]]) <= TOL)
    assert c.shape == x.shape


def test_shape_is_kept():
    x = np.linspace(0.0, 7.0, 12).reshape(3, 4)
    c, s = trig.cos_sin(x)
    assert c.shape == s.shape == (3, 4)
    np.testing.assert_allclose(c, np.cos(x), rtol=0, atol=TOL)


def test_sinewave_kernel_beyond_the_reach_and_nan():
    # phases k·x beyond the reach and NaN coordinates go through the C library's pass: the
    # same values as the formula evaluated by numpy, NaN where a coordinate is NaN
    params = dict(
        amplitude_x_um=0.5,
        amplitude_y_um=0.3,
        wavelength_x_um=1e-3,
        wavelength_y_um=100.0,
        phase_x_deg=10.0,
        phase_y_deg=20.0,
    )
    x = np.array([1.0, 1e3, 2e5, np.nan, 3.0])  # kx·x = 2π·1e3·x: beyond 1e6 rad from x ≈ 160
    y = np.array([2.0, 5.0, 7.0, 1.0, np.nan])
    f, fx, fy = sinewave2d(x, y, **params)
    kx, ky = 2 * math.pi / 1e-3, 2 * math.pi / 100.0
    ax, ay = kx * x + math.radians(10.0), ky * y + math.radians(20.0)
    np.testing.assert_allclose(f, 0.5 * np.sin(ax) + 0.3 * np.sin(ay), rtol=0, atol=1e-15)
    np.testing.assert_allclose(fx, 0.5 * kx * np.cos(ax), rtol=0, atol=1e-15 * kx)
    np.testing.assert_allclose(fy, 0.3 * ky * np.cos(ay), rtol=0, atol=1e-15 * ky)
    assert np.isnan(f[3]) and np.isnan(f[4]) and np.isfinite(f[:3]).all()
