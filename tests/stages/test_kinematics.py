"""The one kinematics stage: every kind's axis velocities and accelerations by one
difference scheme ([2] eq. 14), checked against the machine's limits by one function."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ftsweep.inputs import catalogs
from ftsweep.stages.kinematics import axes as kinematics
from ftsweep.stages.kinematics import dynamics
from ftsweep.stages.paths import dpath_motion


@settings(max_examples=50, deadline=None)
@given(
    a=st.floats(-50.0, 50.0),
    b=st.floats(-5.0, 5.0),
    seed=st.integers(0, 10_000),
)
def test_quadratic_motion_has_its_exact_acceleration_over_uneven_steps(a, b, seed):
    steps = np.random.default_rng(seed).uniform(0.2, 3.0, 30)
    t = np.concatenate([[0.0], np.cumsum(steps)])
    q = np.column_stack([0.5 * a * t * t + b * t, b * t])
    m = kinematics.motion(t, q)
    np.testing.assert_allclose(m.accel[1:-1, 0], a, rtol=1e-7, atol=1e-7)
    np.testing.assert_allclose(m.accel[1:-1, 1], 0.0, atol=1e-9)
    assert np.all(m.accel[[0, -1]] == 0.0)
    # the velocity over a step is the quadratic's at the step's middle
    mid = 0.5 * (t[1:] + t[:-1])
    np.testing.assert_allclose(m.velocity[:, 0], a * mid + b, rtol=1e-9, atol=1e-9)


def test_uniform_steps_give_the_second_difference():
    w = np.sin(np.linspace(0.0, 3.0, 101))[:, None]
    m = kinematics.over_steps(w, np.full(100, 0.01))
    np.testing.assert_allclose(m.accel[1:-1, 0], np.diff(w[:, 0], 2) / 1e-4, rtol=1e-9, atol=1e-12)


def test_time_must_increase():
    with pytest.raises(ValueError, match="time does not increase"):
        kinematics.motion(np.array([0.0, 1.0, 1.0]), np.zeros((3, 1)))


def _xzc() -> kinematics.Limits:
    return catalogs.entry("machines", "sts-xzc").axes.limits(("C", "X", "Z"))


def test_machine_limits_in_si():
    lim = _xzc()
    assert lim.names == ("C", "X", "Z") and lim.rotary == (True, False, False)
    assert lim.high[1] == pytest.approx(0.150) and lim.velocity[1] == pytest.approx(0.250)
    assert lim.velocity[0] == pytest.approx(100.0 * 2.0 * math.pi / 60.0)
    assert math.isinf(lim.accel[0])  # an X-Z-C lathe sets no C acceleration
    with pytest.raises(ValueError, match="no Y axis"):
        catalogs.entry("machines", "sts-xzc").axes.limits(("C", "X", "Y", "Z"))


def test_limits_reason_names_axis_value_limit_and_line():
    lim = _xzc()
    t = np.arange(5) * 0.1
    q = np.zeros((5, 3))
    assert kinematics.limits_reason(q, kinematics.steps_of(t), lim) == ""
    q[3, 1] = 0.001  # X jumps 1 mm in 0.1 s and back: 10 mm/s, 0.1 m/s² → within the X limits
    assert kinematics.limits_reason(q, kinematics.steps_of(t), lim) == ""
    t = np.arange(5) * 0.125  # exact binary steps and positions: no ties broken by rounding
    q[3:, 1] = (0.25, 0.5)  # X to 250 mm then 500 mm: out of range, 2 m/s, 16 m/s² at line 3
    reason = kinematics.limits_reason(q, kinematics.steps_of(t), lim)
    assert "X 500 mm > limit 150 mm (line 5)" in reason
    assert "X velocity 2000 mm/s > limit 250 mm/s (line 3)" in reason
    assert "X acceleration 16 m/s² > limit 10 m/s² (line 3)" in reason
    assert "Z" not in reason and "C" not in reason
    # a relative slack admits a value just over its limit (printed digits read back)
    q = np.zeros((3, 3))
    q[:, 0] = np.arange(3) * lim.velocity[0] * (1.0 + 1e-8) * 0.1
    assert "C velocity" in kinematics.limits_reason(q, kinematics.steps_of(np.arange(3) * 0.1), lim)
    assert kinematics.limits_reason(q, kinematics.steps_of(np.arange(3) * 0.1), lim, slack=1e-6) == ""


def test_every_kind_forms_accelerations_by_the_same_scheme():
    # the W command of a table (dynamics), a D path's axes (dpath) and a Fresnel program's
    # (fresnel.relative_peaks) all go through kinematics.over_steps: the same numbers
    t = np.linspace(0.0, 1.0, 41) ** 1.3
    x = 1e3 * np.cos(3.0 * t)  # µm
    m = dpath_motion.axis_motion(t, np.zeros_like(t), x, x)
    ref = kinematics.motion(t, (x * 1e-6)[:, None])
    np.testing.assert_array_equal(m["x_accel_m_s2"], ref.accel[:, 0])
    np.testing.assert_array_equal(m["z_velocity_mm_s"], ref.velocity[:, 0] * 1e3)
    assert dynamics.kinematics is kinematics


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(0, 40),
    axes=st.integers(1, 3),
    seed=st.integers(0, 10_000),
    ties=st.booleans(),
)
def test_extremes_in_one_pass_are_the_motion_arrays_own(n, axes, seed, ties):
    # the values, and the first point of each, that argmin/argmax of Motion's arrays give
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, axes))
    if ties:  # repeated values: the first occurrence must win, as argmax's
        q = np.round(q)
    steps = rng.uniform(0.1, 2.0, max(n - 1, 0))
    group = rng.integers(0, 3, n)
    e = kinematics.extremes(q, steps, group, 3)
    if n == 0:
        assert np.all(np.isinf(e.low)) and np.all(e.speed < 0.0)
        return
    m = kinematics.over_steps(q, steps)
    speed, accel = np.abs(m.velocity), np.abs(m.accel)
    np.testing.assert_array_equal(e.low, q.min(axis=0))
    np.testing.assert_array_equal(e.low_at, q.argmin(axis=0))
    np.testing.assert_array_equal(e.high, q.max(axis=0))
    np.testing.assert_array_equal(e.high_at, q.argmax(axis=0))
    if n > 1:
        np.testing.assert_array_equal(e.speed, speed.max(axis=0))
        np.testing.assert_array_equal(e.speed_at, speed.argmax(axis=0))
    np.testing.assert_array_equal(e.accel, accel.max(axis=0))
    np.testing.assert_array_equal(e.accel_at, accel.argmax(axis=0))
    for g in range(3):
        own = accel[group == g]
        np.testing.assert_array_equal(e.accel_group[g], own.max(axis=0) if own.size else 0.0)
    np.testing.assert_allclose(e.accel_sq, np.sum(m.accel**2, axis=0), rtol=1e-12)


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(0, 60),
    axes=st.integers(1, 3),
    seed=st.integers(0, 2**32 - 1),
    ties=st.booleans(),
    cuts=st.lists(st.integers(1, 59), max_size=6),
)
def test_extremes_taken_stretch_by_stretch_are_those_of_one_pass(n, axes, seed, ties, cuts):
    # stretches in order, each with its neighbours (as a long sampled program is taken):
    # every value and first point, and the running sum to the last bit, as one pass gives
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, axes))
    if ties:
        q = np.round(q)
    steps = rng.uniform(0.1, 2.0, max(n - 1, 0))
    group = rng.integers(0, 3, n)
    whole = kinematics.extremes(q, steps, group, 3)
    over = kinematics.ExtremesOver(n, axes, 3)
    edges = sorted({0, n, *(c for c in cuts if c < n)})
    for lo, hi in zip(edges[:-1], edges[1:], strict=False):
        a, b = max(lo - 1, 0), min(hi + 1, n)
        over.add(q[a:b], steps[a : b - 1], group[a:b], lo - a, hi - a, a)
    for name, value in whole._asdict().items():
        np.testing.assert_array_equal(getattr(over.out, name), value, err_msg=name)


def test_extremes_stretches_start_at_the_first_point():
    over = kinematics.ExtremesOver(5, 1)
    with pytest.raises(ValueError, match="first stretch"):
        over.add(np.zeros((3, 1)), np.ones(2), None, 1, 2, 1)


def test_extremes_refuses_groups_it_has_no_room_for():
    # the compiled pass indexes its per-group peaks by the group: one out of range is refused
    q, steps = np.zeros((4, 2)), np.ones(3)
    with pytest.raises(ValueError, match="numbered 0 to 1"):
        kinematics.extremes(q, steps, np.array([0, 1, 2, 0]), 2)
    with pytest.raises(ValueError, match="a group for each of the 4 points"):
        kinematics.extremes(q, steps, np.array([0, 1]), 2)
