"""The scheduling replay (ftsweep.sweeps.replay): a list schedule of recorded case times
through the sweep's own task planning. Properties of list scheduling, and the replay of a
catalog sweep covering each case once."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ftsweep.sweeps.replay import format_replay, list_schedule, replay

times = st.lists(st.floats(0.001, 10.0, allow_nan=False), min_size=1, max_size=60)


@settings(max_examples=200, deadline=None)
@given(times, st.integers(1, 20), st.integers(1, 5))
def test_a_list_schedule_is_bounded_by_grahams_guarantee(seconds, threads, per_task):
    """One thread: wall = summed. Any count: wall ≥ summed ÷ threads and ≥ the longest task,
    and a list schedule ends at most the longest task after the ideal (Graham 1966)."""
    cases = dict(enumerate(seconds))
    tasks = [list(range(j, min(j + per_task, len(seconds)))) for j in range(0, len(seconds), per_task)]
    r = list_schedule(tasks, cases, threads)
    summed = sum(seconds)
    assert r["summed_case_s"] == pytest.approx(summed)
    assert r["wall_s"] >= max(summed / threads, r["longest_task_s"]) - 1e-9
    assert r["wall_s"] <= summed / threads + r["longest_task_s"] * (1 - 1 / threads) + 1e-9
    assert 0.0 < r["efficiency"] <= 1.0 + 1e-12
    if threads == 1:
        assert r["wall_s"] == pytest.approx(summed) and r["efficiency"] == pytest.approx(1.0)


def test_equal_tasks_that_divide_among_the_threads_keep_every_thread_busy():
    r = list_schedule([[i] for i in range(8)], dict.fromkeys(range(8), 2.0), 4)
    assert r["wall_s"] == 4.0 and r["efficiency"] == 1.0 and r["tail_s"] == 0.0


def test_no_threads_is_refused():
    with pytest.raises(ValueError, match="at least one thread"):
        list_schedule([[0]], {0: 1.0}, 0)


def test_a_catalog_sweep_replays_every_case_it_ran_once_on_each_count():
    """The reference sweep's 84 cases, each 'recorded' at 1 s: planned as a run plans them on
    2 and 16 threads, every case in one task."""
    seconds = dict.fromkeys(range(84), 1.0)
    rows = replay("sinewave-ring", seconds, [2, 16])
    assert [r["threads"] for r in rows] == [2, 16]
    for r in rows:
        assert r["cases"] == 84 and r["summed_case_s"] == pytest.approx(84.0)
        assert r["wall_s"] >= 84.0 / r["threads"]
    assert "replayed on 16 thread(s)" in format_replay(rows)
