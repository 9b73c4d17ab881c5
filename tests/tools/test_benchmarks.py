"""Benchmarks (pytest-benchmark): they print timings and assert nothing about time.

Run with: pytest -m bench --benchmark-only   (or `ftsweep bench` for the per-stage table)
"""

from __future__ import annotations

import numpy as np
import pytest

from ftsweep.simulate import run_case
from ftsweep.stages.envelope import arcs as envelope
from ftsweep.stages.interpolation import tables as interpolation
from ftsweep.stages.layouts import grids as layouts
from ftsweep.tools.bench import bench_cases


@pytest.mark.bench
@pytest.mark.parametrize("name", ["sinewave-ring-0.25deg", "lens-mesh-2um", "ring-1M-a8"])
def test_bench_case(benchmark, name):
    case = bench_cases()[name]
    run_case(case)  # compile / cache-load outside the timing
    record = benchmark.pedantic(run_case, args=(case,), rounds=2, iterations=1)
    benchmark.extra_info.update({k: v for k, v in record.items() if k.startswith("seconds") or k == "pv_nm"})
    assert record["pv_nm"] > 0


@pytest.mark.bench
def test_bench_bilinear_10M(benchmark):
    lay = layouts.ring_layout(1000.0, 1.0, 0.2)
    table = np.random.default_rng(0).normal(size=lay.shape)
    rng = np.random.default_rng(1)
    rho = rng.uniform(0, 1000, 10_000_000)
    theta = rng.uniform(0, 2 * np.pi, rho.size)
    out = benchmark(interpolation.interpolate, lay, table, rho, theta)
    assert out.shape == rho.shape


@pytest.mark.bench
def test_bench_envelope_line(benchmark):
    pos = np.arange(2000, dtype=float)
    w = 1e-3 * np.sin(pos / 50.0)
    query = np.linspace(5, 1995, 4000)
    out = np.empty(query.size)
    stack = np.empty(pos.size, dtype=np.int64)
    breaks = np.empty(pos.size)
    benchmark(envelope.lower_envelope, pos, w, 83.0, query, out, stack, breaks)
    assert np.isfinite(out).all()


@pytest.mark.bench
@pytest.mark.parametrize("dialect", ["iso-sts", "pmac-pvt"])
def test_bench_dialect_1M_blocks(benchmark, dialect):
    """Writing and reading back a million-block program (docs/controllers.md)."""
    from ftsweep.exports import dialects
    from ftsweep.inputs.catalogs import entry

    n = 1_000_000
    k = np.arange(n)
    z = np.sin(k * 0.01) * 0.1
    velocity = (
        {"C": np.full(n, 50.0), "X": np.zeros(n), "Z": np.cos(k * 0.01)} if dialect == "pmac-pvt" else None
    )
    moves = dialects.Moves(k * 0.5, 8.0 - k * 0.5 / 360 * 0.001, z, np.full(n - 1, 0.01), velocity=velocity)
    ctrl = entry("machines", "sts-moore" if dialect == "iso-sts" else "sts-pmac-pvt").controller

    def both() -> dialects.Moves:
        return dialects.read(dialects.render(moves, dialect, ["bench"], ctrl), dialect, ctrl)

    read = benchmark.pedantic(both, rounds=1, iterations=1)
    np.testing.assert_allclose(read.z_mm, np.round(z, 6), atol=1e-12)


@pytest.mark.bench
@pytest.mark.parametrize("segments", ["linear", "pvt"])
def test_bench_crossings_1M_points(benchmark, segments):
    """Crossings of 64 rays (one batch) with a 1M-point, 2,000-revolution timed program:
    the linear segments against the cubic segments' root per crossing."""
    from ftsweep.stages.interpolation import rays, timed_path

    n = 1_000_000
    t = np.linspace(0.0, 3000.0, n)
    phi = 2.0 * np.pi * t / 1.5
    rho = 20000.0 + 10000.0 * np.abs(np.sin(phi / 7.0))
    z = 100.0 * np.cos(phi / 3.0)
    theta = np.linspace(-0.4, 0.4, 64)
    if segments == "linear":
        pos, _, _ = benchmark(rays.crossings, phi, rho, z, theta)
    else:
        chan = np.column_stack([phi, rho, z])
        tan = timed_path.tangents(t, chan)
        pos, _, _ = benchmark(timed_path.crossings, phi, chan, tan, theta)
    benchmark.extra_info["crossings"] = int(np.isfinite(pos).sum())
    assert np.isfinite(pos).sum() >= 64 * 1999
