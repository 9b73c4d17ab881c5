"""A sweep's recorded case times replayed through its own scheduling policy on any number of
threads (``ftsweep bench --sweep S --simulate-workers N``): how long the sweep would take on a
larger cluster, and where the time not spent computing would go.

The policy is the one a run uses: :func:`ftsweep.sweeps.spec.plan_tasks` groups the cases into
tasks, the costliest first by the sweep's cost model (longest processing time first, LPT),
and the scheduler hands the next task to the first thread that is free (every task is
submitted at once, in that order; Dask runs earlier submissions first). The replay is that
list schedule with each task lasting the sum of its cases' recorded seconds: no round trips,
no cluster start, so its efficiency is the policy's own bound; a measured run's efficiency
beside it shows what the rest costs.
"""

from __future__ import annotations

import heapq
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Optional


def list_schedule(tasks: list[list[int]], seconds: Mapping[int, float], threads: int) -> dict[str, Any]:
    """Tasks (lists of case indices, in submission order) run by ``threads`` threads, each
    free thread taking the next task; a task lasts the sum of its cases' ``seconds`` [s].

    Returns the wall time [s], the summed case time [s], the efficiency (summed ÷ (wall ×
    threads): 1 when no thread idles), the ideal wall (summed ÷ threads), the tail (wall
    less the ideal) and the longest single case and task [s]."""
    if threads < 1:
        raise ValueError(f"a schedule needs at least one thread (got {threads})")
    free = [0.0] * threads
    for task in tasks:
        start = heapq.heappop(free)
        heapq.heappush(free, start + sum(seconds[i] for i in task))
    wall = max(free)
    summed = float(sum(seconds[i] for task in tasks for i in task))
    ideal = summed / threads
    return {
        "threads": threads,
        "tasks": len(tasks),
        "cases": sum(len(t) for t in tasks),
        "wall_s": wall,
        "summed_case_s": summed,
        "ideal_s": ideal,
        "tail_s": wall - ideal,
        "efficiency": summed / (wall * threads) if wall > 0 else float("nan"),
        "longest_case_s": max((seconds[i] for t in tasks for i in t), default=0.0),
        "longest_task_s": max((sum(seconds[i] for i in t) for t in tasks), default=0.0),
    }


def replay(
    sweep: str,
    seconds: Mapping[int, float],
    threads: list[int],
    catalog_folder: Optional[Path] = None,
) -> list[dict[str, Any]]:
    """The cases of sweep ``sweep`` with their recorded ``seconds`` (by case index; the cases
    a run computed) planned as a run on each count of ``threads`` plans them, and list-scheduled
    (:func:`list_schedule`)."""
    from ftsweep.sweeps.spec import case_costs, load_sweep, plan_tasks

    _, spec = load_sweep(sweep)
    indices = sorted(seconds)
    costs, _ = case_costs(spec, indices, catalog_folder)
    ran = [i for i in indices if i in costs]
    return [
        {"sweep": sweep, **list_schedule(plan_tasks(spec, ran, n, catalog_folder, costs), seconds, n)}
        for n in threads
    ]


def format_replay(rows: list[dict[str, Any]]) -> str:
    """One line per simulated thread count."""
    return "\n".join(
        f"sweep {r['sweep']} replayed on {r['threads']} thread(s): {r['cases']} cases in {r['tasks']} "
        f"tasks, predicted wall {r['wall_s']:.1f} s (ideal {r['ideal_s']:.1f} s, tail {r['tail_s']:.1f} s; "
        f"longest case {r['longest_case_s']:.2f} s, task {r['longest_task_s']:.2f} s), "
        f"efficiency {r['efficiency']:.2f}"
        for r in rows
    )
