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
from pathlib import Path
from typing import Any, Optional

from ftsweep import registry
from ftsweep.engine.case import Case, Resolution, program_request
from ftsweep.engine.contract import BenchRow, ReferenceBench
from ftsweep.engine.lines import LineCache
from ftsweep.engine.simulator import STAGE_TIMERS
from ftsweep.inputs import catalogs
from ftsweep.simulate import run_case
from ftsweep.version import __version__


def million_cases() -> dict[str, tuple[str, Any]]:
    """The kinds' own benchmark cases of about a million points (``bench_cases`` of each)."""
    return {name: case for kind in registry.kinds().values() for name, case in kind.bench_cases().items()}


# "<case>-shared": the case run after another case computed its lines, as in a sweep whose
# cases share their angular sampling (ftsweep.engine.lines.LineCache): the table's own work only
SHARED_SUFFIX = "-shared"
SHARED_CACHE_BYTES = 8 * 2**30
# "<case>-threads": the case on the threads asked of the benchmark (predict's --threads), its
# batches and table compensation in parallel: the same record, less wall time
THREADS_SUFFIX = "-threads"


def bench_cases() -> dict[str, Case]:
    """The benchmarked cases: the six references plus two ~10⁶-point layouts, each also
    without the exact-command envelope and with its lines shared (:data:`SHARED_SUFFIX`)."""
    cases = {
        name: Case(surface=ref.surface, layout=program_request(kind=ref.layout, pitch=ref.pitch))
        for name, ref in catalogs.entries("references").items()
    }
    for name, (surface, request) in million_cases().items():
        cases[name] = Case(surface=surface, layout=request)
        # the same without the exact-command envelope (pv_interp_nm), as sweeps may run
        cases[f"{name}-nointerp"] = Case(
            surface=surface, layout=request, resolution=Resolution(interp_error=False)
        )
        cases[f"{name}{SHARED_SUFFIX}"] = cases[name]
        cases[f"{name}{THREADS_SUFFIX}"] = cases[name]
    return cases


def run_benchmark(names: list[str] | None = None, repeat: int = 1, threads: int = 1) -> dict[str, Any]:
    """Run the benchmark; returns machine info and one row per case (best of ``repeat``), the
    ``-threads`` cases on ``threads`` threads (left out when it is one)."""
    cases = bench_cases()
    chosen = names or [n for n in cases if threads > 1 or not n.endswith(THREADS_SUFFIX)]
    unknown = [n for n in chosen if n not in cases]
    if unknown:
        raise ValueError(f"unknown benchmark case(s) {unknown}; known: {', '.join(cases)}")
    # warm-up: compile or load every kernel once, for each kind benchmarked
    for surface, request in million_cases().values():
        run_case(Case(surface=surface, layout=registry.kind(request.kind).warm_request()))
    rows = [_row(name, cases[name], repeat, threads) for name in chosen]
    return {
        "version": __version__,
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "machine": platform.machine(),
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "threads": threads,
        "rows": rows,
    }


def _row(name: str, case: Case, repeat: int, threads: int) -> dict[str, Any]:
    """One benchmark row: the best of ``repeat`` runs of ``case``."""
    best: dict[str, Any] | None = None
    cache = None
    if name.endswith(SHARED_SUFFIX):
        cache = LineCache(SHARED_CACHE_BYTES)
        run_case(case, lines=cache)  # the earlier case that computes the lines
    n = threads if name.endswith(THREADS_SUFFIX) else 1
    for _ in range(repeat):
        record = run_case(case, lines=cache, threads=n)
        if best is None or record["seconds"] < best["seconds"]:
            best = record
    assert best is not None
    label = f"{name[: -len(THREADS_SUFFIX)]} ×{n}" if name.endswith(THREADS_SUFFIX) else name
    row = {"case": label, "n_points": best["n_points"], "pv_nm": best["pv_nm"], "seconds": best["seconds"]}
    row.update({f"seconds_{s}": best[f"seconds_{s}"] for s in STAGE_TIMERS})
    row["n_eval"] = best["n_eval"]
    return row


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
        "evaluation grid; compile time excluded (warm-up case first); -shared: the lines (sampling and exact "
        "commands) computed by an earlier case, as in a sweep whose cases share them; "
        "×N: on N threads (stage seconds are summed over the threads)."
    )
    return "\n".join(lines)


# whole-process figures: what a user waits for, start-up and exit included. Each row: the
# command's arguments ("{dir}": a scratch folder the rows share) and its most runs (the slow
# ones run once); the kinds add theirs (``bench_rows``), the ones that run their programs
GENERIC_ROWS = (
    BenchRow("ftsweep --help", ("--help",), 3),
    BenchRow("ftsweep predict --help", ("predict", "--help"), 3),
)


def whole_process_rows() -> dict[str, BenchRow]:
    """Every whole-process row by label: the generic ones, then each kind's ``bench_rows``."""
    rows = [*GENERIC_ROWS, *(r for kind in registry.kinds().values() for r in kind.bench_rows)]
    return {row.label: row for row in rows}


def ftsweep_command() -> list[str]:
    """The console script beside this interpreter, else ``python -m ftsweep.cli.main``."""
    import shutil
    import sys

    script = Path(sys.executable).with_name("ftsweep")
    found = str(script) if script.exists() else shutil.which("ftsweep")
    return [found] if found else [sys.executable, "-m", "ftsweep.cli.main"]


def whole_process(repeat: int = 3, names: list[str] | None = None) -> list[dict[str, Any]]:
    """Seconds of each row of :func:`whole_process_rows` run as its own process, best of
    ``repeat`` (at most its own count), with the seconds of the case it simulates where its
    JSON reports them (a predict's case, verify's re-simulation; the rest is start-up,
    imports, kernel loading, checks and exit)."""
    import json
    import tempfile

    head = ftsweep_command()
    known = whole_process_rows()
    unknown = [n for n in names or [] if n not in known]
    if unknown:
        raise ValueError(f"unknown whole-process row(s) {unknown}; known: {', '.join(known)}")
    rows, ran = [], set()
    with tempfile.TemporaryDirectory(prefix="ftsweep-bench-") as folder:
        for name in names or list(known):
            row = known[name]
            for needed in _needs(known, name):
                if needed not in ran:
                    _run(head, known[needed], folder)  # writes the next one's input
                    ran.add(needed)
            best, record = float("inf"), dict[str, Any]()
            for _ in range(max(1, min(repeat, row.runs))):
                took, stdout = _run(head, row, folder)
                if took < best:
                    best = took
                    record = json.loads(stdout) if "--json" in row.args else {}
            ran.add(name)
            rows.append(
                {
                    "command": name,
                    "seconds": best,
                    "case_seconds": float(record.get("seconds", math.nan)),
                    "pv_nm": float(record.get("pv_nm", math.nan)),
                }
            )
    return rows


def reference_bench() -> ReferenceBench:
    """The first kind's row and case its brute-force reference is timed beside (a kind with
    ``has_reference`` and such a row, :meth:`ProgramKind.reference_bench`)."""
    for kind in registry.kinds().values():
        if kind.has_reference:
            try:
                return kind.reference_bench()
            except NotImplementedError:
                continue
    raise ValueError("no kind has a brute-force reference timed beside a whole-process row")


def against_reference(
    repeat: int = 3, row: Optional[str] = None, case: Optional[Case] = None
) -> dict[str, Any]:
    """The whole-process ``predict`` row ``row``, best of ``repeat``, beside its kind's
    brute-force evaluation of the same ``case`` (both by default :func:`reference_bench`'s) in
    this process, once (the kind's ``reference``, e.g.
    :mod:`ftsweep.kinds.table.reference`: a dense scan of eq. (3) for every control value,
    every node against every arc within Rc): both seconds, both P-V [nm], and how many times
    the whole predict the reference takes. ValueError for a kind without a reference."""
    from ftsweep.engine.planning import resolve_case

    if row is None or case is None:
        row, case = reference_bench()
    kind = registry.kind(case.layout.kind)
    if not kind.has_reference:
        raise ValueError(f"{kind.noun}s have no brute-force reference model")
    predicted = whole_process(repeat, [row])[0]
    reference = kind.reference(resolve_case(case, kind))
    return {
        "case": f"{row} ({case.surface})",
        "predict_s": predicted["seconds"],
        "predict_case_s": predicted["case_seconds"],
        "predict_pv_nm": predicted["pv_nm"],
        "reference_s": reference["seconds"],
        "reference_pv_nm": reference["pv_nm"],
        "ratio": reference["seconds"] / predicted["seconds"],
    }


def format_against_reference(r: dict[str, Any]) -> str:
    """The lines of :func:`against_reference`."""
    predict = (
        f"{r['predict_s']:8.2f} s  P-V {r['predict_pv_nm']:.2f} nm  (its case {r['predict_case_s']:.2f} s)"
    )
    reference = f"{r['reference_s']:8.2f} s  P-V {r['reference_pv_nm']:.2f} nm"
    return "\n".join(
        [
            f"{r['case']}:",
            f"  predict, whole process (best of runs)  {predict}",
            f"  brute-force reference model, once      {reference}",
            f"  the reference takes {r['ratio']:.1f}× the whole predict (its P-V is over the nodes alone; "
            "predict's adds the exact cusp peaks between them)",
        ]
    )


def _needs(known: dict[str, BenchRow], name: str) -> list[str]:
    """The rows that must run before row ``name``, first first (each ``needs`` the one
    before it); ValueError for a row that needs one not known, or a circle."""
    chain: list[str] = []
    needed = known[name].needs
    while needed is not None:
        if needed not in known or needed in chain or needed == name:
            raise ValueError(f"the whole-process row {name!r} needs {needed!r}, which cannot run first")
        chain.insert(0, needed)
        needed = known[needed].needs
    return chain


def _run(head: list[str], row: BenchRow, folder: str) -> tuple[float, str]:
    """Run one row's command once: its seconds and stdout (ValueError naming it if it fails)."""
    args = [a.replace("{dir}", folder) for a in row.args]
    return timed_process([*head, *args], row.label)


def timed_process(
    argv: list[str], label: str, cwd: Optional[Path] = None, env: Optional[dict[str, str]] = None
) -> tuple[float, str]:
    """Seconds one command takes as its own process, and its stdout; ValueError naming it
    (``label``) with the end of its stderr if it fails."""
    import subprocess

    started = time.perf_counter()
    done = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True)
    took = time.perf_counter() - started
    if done.returncode != 0:
        raise ValueError(f"{label} failed (exit {done.returncode}): {done.stderr.strip()[-300:]}")
    return took, done.stdout


def format_whole_process(rows: list[dict[str, Any]]) -> str:
    """The whole-process table: seconds per command, and the seconds of the case it simulates."""
    head = f"{'whole process (best of runs)':44s} {'seconds':>8s} {'case s':>8s}"
    lines = [head, "-" * len(head)]
    for r in rows:
        case = "" if math.isnan(r["case_seconds"]) else f"{r['case_seconds']:8.2f}"
        lines.append(f"{r['command']:44s} {r['seconds']:8.2f} {case:>8s}")
    lines.append(
        "case s: the simulated case's own seconds (verify: its re-simulation); all cores: --threads default"
    )
    if not has_bytecode():
        lines.append(
            "note: ftsweep's modules have no bytecode (an editable install where PYTHONDONTWRITEBYTECODE "
            "is set): every process above compiled them from source, ~0.08 s on the README's machine; "
            "`python -m compileall pipeline stages` once gives what a wheel install has"
        )
    return "\n".join(lines)


def has_bytecode() -> bool:
    """Whether ftsweep's own modules have up-to-date bytecode beside them (without it, with
    ``PYTHONDONTWRITEBYTECODE`` set, every process compiles them from source)."""
    import importlib.util
    import os

    source = __file__
    cached = importlib.util.cache_from_source(source)
    return os.path.exists(cached) and os.path.getmtime(cached) >= os.path.getmtime(source)


def sweep_throughput(name: str, workers: int, scheduler: str | None = None) -> dict[str, Any]:
    """Run sweep ``name`` on ``workers`` local worker processes (or on the cluster of the
    ``scheduler`` address, its workers as it reports them) into a temporary cube and return
    the wall time, summed case time, cases per second and the efficiency: summed case time
    over wall time × workers (1: every worker computing cases all the time), and the CPU
    seconds this process (the driver: the cube, the merges, the local scheduler) spent. The
    cube is discarded."""
    import tempfile

    from ftsweep.sweeps.run import run_sweep

    with tempfile.TemporaryDirectory(prefix="ftsweep-bench-") as folder:
        started, cpu = time.perf_counter(), time.process_time()
        report = run_sweep(name, Path(folder) / f"{name}.zarr", workers=workers, scheduler=scheduler)
        whole, cpu = time.perf_counter() - started, time.process_time() - cpu
    # the seconds of every case the run computed (failed ones record none), by case index
    recorded = {int(r["index"]): float(r["seconds"]) for r in report.rows if r.get("seconds") is not None}
    summed = float(sum(recorded.values()))
    wall = report.wall_s
    # the workers' share of the wall: from their warm-up's end (the cluster handed over) on
    busy = wall - report.timeline.get("connected_s", 0.0)
    return {
        "sweep": name,
        "scheduler": scheduler or "local cluster",
        "workers": report.workers,
        "cases": len(report.rows),
        "failed": report.failed,
        "wall_s": wall,
        "whole_s": whole,
        "driver_cpu_s": cpu,
        "summed_case_s": summed,
        "cases_per_s": len(report.rows) / wall if wall > 0 else float("nan"),
        "efficiency": summed / (wall * report.workers) if wall > 0 else float("nan"),
        "efficiency_warmed": summed / (busy * report.workers) if busy > 0 else float("nan"),
        "case_seconds": recorded,
        "timeline": dict(report.timeline),
    }


def format_sweep(sweep: dict[str, Any]) -> str:
    """Two lines of a :func:`sweep_throughput` result: the throughput, and where the wall went
    (to the cluster, to the first case, between the first and the last, after the last)."""
    line = _throughput(sweep)
    tl, wall = sweep.get("timeline", {}), sweep["wall_s"]
    if {"set_up_s", "connected_s", "first_case_s", "last_case_s"} <= set(tl):
        line += (
            f"\n  wall {wall:.1f} s: cube set up at {tl['set_up_s']:.1f} s, cluster connected and "
            f"warmed at {tl['connected_s']:.1f} s, first case "
            f"delivered at {tl['first_case_s']:.1f} s, last at {tl['last_case_s']:.1f} s, then "
            f"{wall - tl['last_case_s']:.1f} s to the end (the cluster closed, the last merge); "
            f"efficiency from the workers warmed to the end {sweep['efficiency_warmed']:.2f}; "
            f"the driver's CPU {sweep.get('driver_cpu_s', float('nan')):.1f} s"
        )
    return line


def _throughput(sweep: dict[str, Any]) -> str:
    return (
        f"sweep {sweep['sweep']} on {sweep['workers']} worker(s) ({sweep['scheduler']}): {sweep['cases']} "
        f"cases in {sweep['wall_s']:.1f} s wall from the run's start ({sweep['whole_s']:.1f} s with the "
        "spec's loading and the lock): "
        f"{sweep['cases_per_s']:.2f} cases/s, summed case time {sweep['summed_case_s']:.1f} s, "
        f"efficiency {sweep['efficiency']:.2f}"
    )


def side_by_side(sweep: str, case_seconds: dict[int, float], count: int = 5) -> list[dict[str, Any]]:
    """The ``count`` costliest cases a sweep run recorded, each run again in this process on
    one thread (best of two, after a warm-up case), beside its seconds inside the sweep: where
    a case costs more in a sweep than alone (other workers sharing the cores' caches and
    memory, serialisation, logs)."""
    from ftsweep.sweeps.spec import case_at, load_sweep

    _, spec = load_sweep(sweep)
    costliest = sorted(case_seconds, key=lambda i: -case_seconds[i])[:count]
    if not costliest:
        return []
    run_case(case_at(spec, min(case_seconds, key=lambda i: case_seconds[i])))  # warm-up
    rows = []
    for i in costliest:
        case = case_at(spec, i)
        alone = min(float(run_case(case, threads=1)["seconds"]) for _ in range(2))
        rows.append(
            {
                "index": i,
                "case": case.layout.label(),
                "sweep_s": case_seconds[i],
                "alone_s": alone,
                "ratio": case_seconds[i] / alone if alone > 0 else float("nan"),
            }
        )
    return rows


def format_side_by_side(rows: list[dict[str, Any]]) -> str:
    """The side-by-side table of :func:`side_by_side`."""
    head = f"{'case in the sweep':32s} {'sweep s':>8s} {'alone s':>8s} {'ratio':>6s}"
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(
            f"{r['index']:>4d} {r['case'][:27]:27s} {r['sweep_s']:8.2f} {r['alone_s']:8.2f} {r['ratio']:6.2f}"
        )
    lines.append("alone: the same case in this process on one thread, the other cores idle")
    return "\n".join(lines)
