"""Benchmark of the case runner: seconds per case and per stage, on one core.

Runs the published reference cases (catalogs/references.yaml) and two layouts of about one
million points at the default resolution, after a warm-up case that pays numba's compile
or cache-load cost, and prints a table. It measures; it asserts nothing about time.
"""

from __future__ import annotations

import math
import os
import platform
import time
from typing import Any

from ftsweep import __version__, catalogs
from ftsweep.case import STAGE_TIMERS, run_case
from ftsweep.kinds.requests import program_request
from ftsweep.lines import LineCache
from ftsweep.spec import Case, Resolution

MILLION_CASES = {
    "ring-1M-a8": ("sinewave2d", program_request(kind="ring", points=1_000_000, aspect=8.0)),
    "mesh-1M-a1": ("lens_array", program_request(kind="mesh", points=1_000_000, aspect=1.0)),
}


# "<case>-shared": the case run after another case computed its lines, as in a sweep whose
# cases share their angular sampling (ftsweep.lines.LineCache): the table's own work only
SHARED_SUFFIX = "-shared"
SHARED_CACHE_BYTES = 8 * 2**30


def bench_cases() -> dict[str, Case]:
    """The benchmarked cases: the six references plus two ~10⁶-point layouts, each also
    without the exact-command envelope and with its lines shared (:data:`SHARED_SUFFIX`)."""
    cases = {
        name: Case(surface=ref.surface, layout=program_request(kind=ref.layout, pitch=ref.pitch))
        for name, ref in catalogs.entries("references").items()
    }
    for name, (surface, request) in MILLION_CASES.items():
        cases[name] = Case(surface=surface, layout=request)
        # the same without the exact-command envelope (pv_interp_nm), as sweeps may run
        cases[f"{name}-nointerp"] = Case(
            surface=surface, layout=request, resolution=Resolution(interp_error=False)
        )
        cases[f"{name}{SHARED_SUFFIX}"] = cases[name]
    return cases


def run_benchmark(names: list[str] | None = None, repeat: int = 1) -> dict[str, Any]:
    """Run the benchmark; returns machine info and one row per case (best of ``repeat``)."""
    cases = bench_cases()
    chosen = names or list(cases)
    unknown = [n for n in chosen if n not in cases]
    if unknown:
        raise ValueError(f"unknown benchmark case(s) {unknown}; known: {', '.join(cases)}")
    # warm-up: compile or load every kernel once, for both layout kinds
    for surface, kind, pitch in (("sinewave2d", "ring", (20.0, 10.0)), ("lens_array", "mesh", (50.0, 50.0))):
        run_case(Case(surface=surface, layout=program_request(kind=kind, pitch=pitch)))
    rows = []
    for name in chosen:
        best: dict[str, Any] | None = None
        cache = None
        if name.endswith(SHARED_SUFFIX):
            cache = LineCache(SHARED_CACHE_BYTES)
            run_case(cases[name], lines=cache)  # the earlier case that computes the lines
        for _ in range(repeat):
            record = run_case(cases[name], lines=cache)
            if best is None or record["seconds"] < best["seconds"]:
                best = record
        assert best is not None
        row = {"case": name, "n_points": best["n_points"], "pv_nm": best["pv_nm"], "seconds": best["seconds"]}
        row.update({f"seconds_{s}": best[f"seconds_{s}"] for s in STAGE_TIMERS})
        row["n_eval"] = best["n_eval"]
        rows.append(row)
    return {
        "version": __version__,
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "machine": platform.machine(),
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "threads": os.environ.get("NUMBA_NUM_THREADS", "kernels are single-threaded"),
        "rows": rows,
    }


def format_table(result: dict[str, Any]) -> str:
    """A fixed-width table of a :func:`run_benchmark` result."""
    head = (
        f"{'case':24s} {'points':>9s} {'P-V nm':>8s} {'total s':>8s} {'comp.':>7s} "
        f"{'sampl.':>7s} "
        f"{'interp.':>7s} {'envel.':>7s} {'metric':>7s} {'eval pts/s':>11s}"
    )
    lines = [head, "-" * len(head)]
    for r in result["rows"]:
        lines.append(
            f"{r['case']:24s} {r['n_points']:9,d} {r['pv_nm']:8.2f} {r['seconds']:8.2f} "
            f"{r['seconds_compensation']:7.2f} {r['seconds_sampling']:7.2f} "
            f"{r['seconds_interpolation']:7.2f} {r['seconds_envelope']:7.2f} {r['seconds_metrics']:7.2f} "
            f"{r['n_eval'] / r['seconds']:11.3g}"
        )
    lines.append(
        "compensation: control table + exact commands along the path; sampling: design surface on the "
        "evaluation grid; compile time excluded (warm-up case first); -shared: the lines (sampling, exact "
        "commands and their envelope) computed by an earlier case, as in a sweep whose cases share them."
    )
    return "\n".join(lines)


# whole-process figures (issue 29): what a user waits for, start-up and exit included
WHOLE_PROCESS = {
    "ftsweep --help": ["--help"],
    "ftsweep predict --help": ["predict", "--help"],
    "predict 5k-point ring": [
        "predict", "--surface", "sinewave2d", "--points", "5000", "--aspect", "8", "--json",
    ],
    "predict 950k-point ring": [
        "predict", "--surface", "sinewave2d", "--drho-um", "3.04", "--dtheta-deg", "0.125", "--json",
    ],
}  # fmt: skip


def whole_process(repeat: int = 3, names: list[str] | None = None) -> list[dict[str, Any]]:
    """Seconds of each :data:`WHOLE_PROCESS` command run as its own process (the console
    script beside this interpreter, else ``python -m ftsweep.cli``), best of ``repeat``; with
    the case's own seconds for a predict (the rest is start-up, imports, kernel loading and
    exit)."""
    import json
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    script = Path(sys.executable).with_name("ftsweep")
    found = str(script) if script.exists() else shutil.which("ftsweep")
    head = [found] if found else [sys.executable, "-m", "ftsweep.cli"]
    rows = []
    for name in names or list(WHOLE_PROCESS):
        best, inside = float("inf"), float("nan")
        for _ in range(repeat):
            started = time.perf_counter()
            done = subprocess.run([*head, *WHOLE_PROCESS[name]], capture_output=True, text=True)
            took = time.perf_counter() - started
            if done.returncode != 0:
                raise ValueError(f"{name} failed: {done.stderr.strip()[-300:]}")
            if took < best:
                best = took
                if "--json" in WHOLE_PROCESS[name]:
                    inside = float(json.loads(done.stdout)["seconds"])
        rows.append({"command": name, "seconds": best, "case_seconds": inside})
    return rows


def format_whole_process(rows: list[dict[str, Any]]) -> str:
    """The whole-process table: seconds per command, and for a predict its case's own."""
    head = f"{'whole process (best of runs)':32s} {'seconds':>8s} {'case s':>8s}"
    lines = [head, "-" * len(head)]
    for r in rows:
        case = "" if math.isnan(r["case_seconds"]) else f"{r['case_seconds']:8.2f}"
        lines.append(f"{r['command']:32s} {r['seconds']:8.2f} {case:>8s}")
    return "\n".join(lines)


def sweep_throughput(name: str, workers: int) -> dict[str, Any]:
    """Run sweep ``name`` on a LocalCluster of ``workers`` processes into a temporary cube and
    return its wall time, summed case time and cases per second (the cube is discarded)."""
    import tempfile
    from pathlib import Path

    from ftsweep.run import run_sweep

    with tempfile.TemporaryDirectory(prefix="ftsweep-bench-") as folder:
        started = time.perf_counter()
        report = run_sweep(name, Path(folder) / f"{name}.zarr", workers=workers)
        wall = time.perf_counter() - started
    summed = float(sum(row.get("seconds", 0.0) for row in report.rows))
    return {
        "sweep": name,
        "workers": workers,
        "cases": len(report.rows),
        "failed": report.failed,
        "wall_s": wall,
        "summed_case_s": summed,
        "cases_per_s": len(report.rows) / wall if wall > 0 else float("nan"),
    }
