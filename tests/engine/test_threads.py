"""Threads of one case (ftsweep.engine.threads): the work splits, the results do not change."""

from __future__ import annotations

import numpy as np
import pytest

from ftsweep.engine.threads import (
    MAX_PART_POINTS,
    PART_POINTS,
    THREAD_PART_POINTS,
    THREADS,
    compensate_in_parts,
    current,
    using_threads,
)
from ftsweep.inputs import catalogs
from ftsweep.stages.interpolation import compensation


def test_a_table_compensated_in_parts_equals_one_call_bit_for_bit():
    spec = catalogs.entry("surfaces", "sinewave2d")
    surface = catalogs.surface_callable(spec)
    rng = np.random.default_rng(7)
    n = 5 * PART_POINTS + 123  # several parts, the last one short
    rho = rng.uniform(0.0, 5000.0, n).reshape(-1, 1)
    theta = rng.uniform(0.0, 2.0 * np.pi, n).reshape(-1, 1)
    calls = []

    def solve(r, t):
        calls.append(r.size)
        return compensation.compensate(surface, r, t, 83.0, "exact", catalogs.gradient_bound(spec))

    one = solve(rho, theta)
    assert calls == [n]
    for threads, largest in ((1, MAX_PART_POINTS), (3, THREAD_PART_POINTS)):
        calls.clear()
        parts = compensate_in_parts(solve, rho, theta, threads=threads)
        assert len(calls) >= 3 and sum(calls) == n and max(calls) <= largest  # it did split
        assert parts[0].shape == rho.shape and np.array_equal(one[0], parts[0])
        assert np.array_equal(one[1], parts[1])


def test_the_context_sets_the_threads_and_restores_them():
    assert current() == 1
    with using_threads(3):
        assert current() == 3 == THREADS.get()
        assert current(2) == 2  # an explicit number wins
    assert current() == 1
    with pytest.raises(ValueError, match="at least 1"):
        with using_threads(0):
            pass
