"""The least-time timesteps of a program with fixed points and the lower bound that certifies
them (:mod:`ftsweep.stages.kinematics.timing`; docs/kinds.md "Time-optimal timing"): every
program they give meets its limits by a finite-difference check written here, independent of
the kinematics stage; no program a brute-force search finds beats the bound; and on the
Chebyshev example the program is within 2 % of its bound, exported and verified."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.motion import exported_axes, within

from ftsweep.stages.kinematics import certificate, timing


@st.composite
def programs(draw: st.DrawFn, most: int = 40, least: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points of 1-4 axes with displacements of either sign (reversals included), and limits."""
    n = draw(st.integers(least, most))
    axes = draw(st.integers(1, 4))
    # a step of either sign and 1e-7 to 1e-3 m, drawn as such: filtering out the small ones
    # of a symmetric range discards most draws and trips Hypothesis's health check
    step = st.builds(lambda size, up: size if up else -size, st.floats(1e-7, 1e-3), st.booleans())
    d = np.array(draw(st.lists(st.lists(step, min_size=axes, max_size=axes), min_size=n - 1, max_size=n - 1)))
    q = np.vstack([np.zeros((1, axes)), np.cumsum(d, axis=0)])
    velocity = np.array(draw(st.lists(st.floats(0.01, 1.0), min_size=axes, max_size=axes)))
    accel = np.array(draw(st.lists(st.floats(0.1, 10.0), min_size=axes, max_size=axes)))
    return q, velocity, accel


@settings(max_examples=60, deadline=None)
@given(programs())
def test_the_least_time_program_meets_every_limit_and_no_step_beats_its_bound(prog):
    q, velocity, accel = prog
    steps = timing.least_time_steps(q, velocity, accel)
    assert np.all(steps > 0.0)
    assert within(q, steps, velocity, accel, 1e-9)
    # no faster than the bound in all, and, a program none of whose steps is longer than the
    # bound's starting class, step by step no faster than the passes' speeds
    low = certificate.least_time_bound(q, velocity, accel, float(steps.max()))
    assert low.total_s <= steps.sum()
    assert np.all(steps >= low.step_s), np.flatnonzero(steps < low.step_s)


@settings(max_examples=20, deadline=None)
@given(programs(most=12), st.floats(0.1, 10.0))
def test_limits_scaled_by_lambda_and_lambda_squared_scale_the_times_by_one_over_lambda(prog, lam):
    q, velocity, accel = prog
    steps = timing.least_time_steps(q, velocity, accel)
    faster = timing.least_time_steps(q, velocity * lam, accel * lam * lam)
    np.testing.assert_allclose(faster, steps / lam, rtol=1e-9)
    low = certificate.least_time_bound(q, velocity, accel, float(steps.max()))
    low_fast = certificate.least_time_bound(q, velocity * lam, accel * lam * lam, float(steps.max()) / lam)
    np.testing.assert_allclose(low_fast.step_s, low.step_s / lam, rtol=1e-9)
    assert low_fast.total_s == pytest.approx(low.total_s / lam, rel=1e-9)


def test_a_straight_line_at_constant_pitch_runs_at_the_velocity_limit_and_the_bound_agrees():
    q = np.outer(np.arange(50.0), [1e-6, 2e-6])
    velocity, accel = np.array([0.1, 0.1]), np.array([0.5, 0.5])
    steps = timing.least_time_steps(q, velocity, accel)
    # Y moves 2 µm a step at 0.1 m/s: 20 µs, and no point accelerates (1e-12: the scale that
    # keeps a velocity rounded above its limit within it)
    np.testing.assert_allclose(steps, 2e-5, rtol=1e-11)
    low = certificate.least_time_bound(q, velocity, accel, 1.0)
    np.testing.assert_allclose(low.step_s, 2e-5, rtol=1e-8)
    assert low.total_s == pytest.approx(49 * 2e-5, rel=1e-8)


def _grid_least(q: np.ndarray, velocity: np.ndarray, accel: np.ndarray, longest: float) -> float:
    """The least total time of the programs through q (4 points) whose three steps lie on a
    geometric grid up to ``longest`` (fine up to a hundredth of it) and meet the limits (plain
    numpy, exhaustive)."""
    d = np.diff(q, axis=0)
    shortest = float((np.abs(d) / velocity).max(axis=1).min())
    grid = np.r_[np.geomspace(shortest, longest / 100.0, 75), np.geomspace(longest / 90.0, longest, 15)]
    best = math.inf
    for t0, t1 in itertools.product(grid, grid):
        t2 = grid  # the third step over the whole grid at once
        v0, v1, v2 = d[0] / t0, d[1] / t1, d[2][None, :] / t2[:, None]
        a1 = 2.0 * (v1 - v0) / (t0 + t1)
        a2 = 2.0 * (v2 - v1) / (t1 + t2)[:, None]
        if np.any(np.abs(v0) > velocity) or np.any(np.abs(v1) > velocity) or np.any(np.abs(a1) > accel):
            continue
        ok = np.all(np.abs(v2) <= velocity, axis=1) & np.all(np.abs(a2) <= accel, axis=1)
        if ok.any():
            best = min(best, t0 + t1 + float(t2[ok].min()))
    return best


@settings(max_examples=10, deadline=None)
@given(programs(most=4, least=4))
def test_no_program_a_brute_force_search_finds_beats_the_bound(prog):
    # every grid program within the limits is one the bound must not exceed: exact, whatever
    # the grid's coarseness; axes reversing, and steps up to 100 × the passes' longest, included
    q, velocity, accel = prog
    steps = timing.least_time_steps(q, velocity, accel)
    best = _grid_least(q, velocity, accel, 100.0 * float(steps.max()))
    low = certificate.least_time_bound(q, velocity, accel, float(steps.max()))
    assert low.total_s <= best * (1.0 + 1e-12)
    assert low.total_s <= steps.sum()


def test_the_fresnel_example_is_timed_within_2_percent_of_its_bound_and_exported_within_limits(tmp_path):
    # the CLI's own settings on chebyshev_example (K = 360, Δr = 2 µm, K_s = 1.25): 300,601 points
    from ftsweep.inputs import catalogs
    from ftsweep.kinds.fresnel import program as fp
    from ftsweep.kinds.fresnel import study as fstudy

    inp = fstudy.inputs("chebyshev_example", "xyzc-nanoform", "fresnel-finish")
    s = fstudy.study(inp)
    assert s["timing"] == "optimal" and s["n_points"] == 300_601
    # measured 275.15 s against [2]'s eqs. 15-16 at 318.5 s; the bound 274.59 s
    assert s["time_adaptive_s"] <= 280.0
    assert 0.0 <= s["optimality_gap_pct"] <= 2.0
    assert max(s["facet_gap_pct"]) <= 2.0 and min(s["facet_gap_pct"]) >= 0.0
    assert sum(s["facet_time_s"]) == pytest.approx(s["time_adaptive_s"], rel=1e-12)
    assert np.all(s["_steps"].steps >= s["_bound"].step_s)
    out, side = tmp_path / "f.txt", tmp_path / "f.json"
    fstudy.export(s, out, side, inp)
    assert any(line.startswith("# limits: every axis within 1/K_s") for line in out.read_text().splitlines())
    q, steps = exported_axes(out)
    limits = fp.limits_of(catalogs.entry("machines", "xyzc-nanoform"))
    # within the machine's limits as printed; within 1/K_s to what the printed times move the
    # peaks: 1 ns on 0.5-0.9 ms steps is up to 1e-9·v/T² of a C acceleration (C peaks 0.8016)
    assert within(q, steps, limits.velocity, limits.accel, 0.0)
    assert within(q, steps, limits.velocity / 1.25, limits.accel / 1.25, 5e-3)
    assert fstudy.verify(out)["within_limits"]


def test_a_fresnel_case_takes_its_timing_from_its_request():
    # unset, the request keeps the key it had before the timing was an option (the golden
    # keys hold it); set, it names another case; constant steps take longer than the least time
    from ftsweep.engine.case import Case, program_request
    from ftsweep.simulate import run_case

    def case(**timing: str) -> Case:
        layout = program_request(kind="fresnel", points_per_turn=60, **timing)
        return Case(
            surface="chebyshev_example",
            layout=layout,
            machine="xyzc-nanoform",
            cutting="fresnel-finish",
            feed_um=8.0,
        )

    assert case().key() != case(timing="constant").key() != case(timing="optimal").key()
    optimal, constant = run_case(case()), run_case(case(timing="constant"))
    assert constant["machining_s"] > optimal["machining_s"] > 0.0
    assert constant["pv_nm"] == pytest.approx(optimal["pv_nm"], rel=1e-9)  # a linear machine: the path alone
