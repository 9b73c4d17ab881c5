"""Dynamics of the W command (model §6): closed forms on a tilted plane."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ftsweep.stages.kinematics import dynamics
from ftsweep.stages.layouts import grids as layouts


@given(st.floats(0.001, 0.05), st.floats(20.0, 200.0), st.floats(200.0, 2000.0))
def test_tilted_plane_moves_w_once_per_revolution(m, rpm, radius):
    """On f = m·x the command along a circle of radius r is m·r·cosθ: peak velocity m·r·ω,
    peak acceleration m·r·ω², content at the spindle frequency, stroke 2·m·R."""
    lay = layouts.ring_layout(radius, radius / 200, 360.0 / 720)
    rho, theta = layouts.layout_nodes(lay)
    table = m * rho * np.cos(theta)
    d = dynamics.analyse(lay, table, radius, 1.0, rpm, 20_000.0)
    omega = 2 * math.pi * rpm / 60
    assert d.velocity_peak_mm_s == pytest.approx(m * radius * omega * 1e-3, rel=0.01)
    # bilinear kinks between table columns add to the second difference; it stays of the order
    # of the smooth m·r·ω² times the commands per column
    smooth = m * radius * omega**2 * 1e-6
    assert smooth * 0.9 <= d.accel_peak_m_s2 <= smooth * 20_000 * 60 / rpm / 720 * 4
    assert d.freq_max_hz == pytest.approx(rpm / 60)
    assert d.stroke_um == pytest.approx(2 * m * radius, rel=1e-6)
    assert d.commands_per_rev == round(20_000 * 60 / rpm)


def test_commands_are_one_continuous_sequence():
    lay = layouts.ring_layout(100.0, 1.0, 1.0)
    rho, theta = layouts.layout_nodes(lay)
    table = 0.01 * rho * np.sin(theta) + 1e-4 * rho**2
    k = 2400
    w = dynamics.revolution_commands(lay, table, 90.0, 1.0, k, k + 2, first=-1)
    assert w.size == k + 2
    # no jumps: consecutive commands differ by at most the slope times the arc per command
    step = 90.0 * 2 * math.pi / k
    assert np.max(np.abs(np.diff(w))) <= 0.03 * step


def test_feasibility_names_every_limit():
    d = dynamics.Dynamics(6000.0, 1.0, 500.0, 300.0, 1000.0, 24000)
    ok, why = dynamics.feasibility(d, 5000.0, 400.0, 250.0, 440.0)
    assert not ok
    for word in ("travel", "peak acceleration", "continuous", "bandwidth"):
        assert word in why
    assert dynamics.feasibility(dynamics.Dynamics(1.0, 0.1, 1.0, 0.5, 100.0, 24000), 5000, 400, 250, 440) == (
        True,
        "",
    )


@given(st.integers(1, 40), st.floats(0.1, 10.0), st.floats(-50.0, 50.0), st.integers(200, 3000))
def test_the_feeds_drift_leaves_no_leakage_in_a_revolutions_spectrum(n, amplitude, drift, k):
    """A harmonic n on the feed's drift (the command change over a revolution, its next
    command given): the spectrum is that harmonic alone, at its amplitude; no 1/f line of the
    jump a periodic extension of the drift would have (the least-squares line left one)."""
    t = np.arange(k + 1)
    w = amplitude * np.sin(2 * np.pi * n * t / k) + drift * t / k
    freq, amp = dynamics.spectrum(w, k, 60.0)  # 1 rev/s: harmonic n at n Hz
    assert freq[n - 1] == pytest.approx(n)
    assert amp[n - 1] == pytest.approx(amplitude, rel=1e-9)
    others = np.delete(amp, n - 1)
    assert others.max() <= 1e-9 * (amplitude + abs(drift))
