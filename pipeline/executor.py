"""Dask execution of sweep tasks: the synchronous scheduler, a LocalCluster, or an
existing ``dask.distributed`` scheduler, running the same task function.

A task computes a list of cases and writes each into the cube as soon as it finishes
(:class:`ftsweep.cube.CubeWriter`); it returns one small summary dict per case, which the
driver streams into progress and the final summary.
"""

from __future__ import annotations

import logging
import traceback
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Optional

import dask

from ftsweep.case import Case, LayoutRequest, run_case
from ftsweep.cube import CubeWriter
from ftsweep.sweep import SweepSpec, case_at

SYNCHRONOUS = "synchronous"
# a scheduler that does not answer within this many seconds is reported, not waited for
CONNECT_TIMEOUT_S = 5


class ExecutorError(RuntimeError):
    """The sweep could not be run on the asked scheduler; the message says why."""


def run_task(
    cube: str, spec_json: str, catalog_folder: Optional[str], indices: list[int], run_id: str
) -> list[dict]:
    """Compute the cases ``indices`` of a sweep and write each into ``cube`` (worker side)."""
    spec = SweepSpec.model_validate_json(spec_json)
    folder = Path(catalog_folder) if catalog_folder else None
    writer = CubeWriter(Path(cube))
    out = []
    for index in indices:
        case = case_at(spec, index)
        try:
            record = run_case(case, folder)
        except Exception as exc:  # a failing case is recorded and the rest run on
            message = f"{type(exc).__name__}: {exc}"
            writer.write_failed(index, message, run_id)
            out.append(
                {
                    "index": index,
                    "status": "failed",
                    "message": message,
                    "points": case.layout.points,
                    "aspect": case.layout.aspect,
                }
            )
            continue
        writer.write_done(index, record, run_id)
        out.append(
            {
                "index": index,
                "status": "done",
                "pv_nm": record["pv_nm"],
                "n_points": record["n_points"],
                "points": case.layout.points,
                "aspect": case.layout.aspect,
                "seconds": record["seconds"],
            }
        )
    return out


def warm_up(surface: str, kind: str, catalog_folder: Optional[str] = None) -> float:
    """Compile (or load from numba's cache) every kernel once in this process; returns seconds."""
    import time

    t = time.perf_counter()
    pitch = (50.0, 10.0) if kind == "ring" else (50.0, 50.0)
    try:
        run_case(
            Case(surface=surface, layout=LayoutRequest(kind=kind, pitch=pitch)),
            Path(catalog_folder) if catalog_folder else None,
        )
    except ValueError:
        pass  # a coarse pitch may not fit every surface; the kernels compiled anyway
    return time.perf_counter() - t


def execute(
    tasks: list[list[int]],
    task_args: tuple[str, str, Optional[str], str],
    scheduler: Optional[str],
    workers: int,
    on_result: Callable[[list[dict]], None],
    warm: tuple[str, str],
) -> None:
    """Run ``tasks`` (lists of case indices) and call ``on_result`` with each task's summaries.

    scheduler : ``"synchronous"`` for dask's synchronous scheduler in this process, an
        address (``tcp://host:port``) of a running ``dask scheduler``, or None for a
        ``LocalCluster`` with ``workers`` single-threaded worker processes.
    task_args : (cube path, sweep spec JSON, catalog folder, run id) passed to every task.
    warm : (surface, layout kind) for the per-worker warm-up before any task starts.
    """
    if not tasks:
        return
    cube, spec_json, folder, run_id = task_args
    if scheduler == SYNCHRONOUS:
        warm_up(*warm, folder)
        _run_synchronous(tasks, task_args, on_result)
        return

    from distributed import Client, LocalCluster, as_completed

    cluster = None
    if scheduler:
        try:
            client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise ExecutorError(
                f"no dask scheduler answered at {scheduler[:200]} within {CONNECT_TIMEOUT_S} s "
                f"({type(exc).__name__}); start one (dask scheduler) or omit --scheduler for a local cluster"
            ) from None
    else:
        cluster = LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",
            silence_logs=logging.CRITICAL,  # task errors reach us through the futures
        )
        client = Client(cluster)
    try:
        # numba's compile (or cache load) is paid once per worker, before any case is timed
        client.run(warm_up, *warm, folder)
        futures = [
            client.submit(
                run_task, cube, spec_json, folder, group, run_id, pure=False, key=f"ftsweep-task-{i}-{run_id}"
            )
            for i, group in enumerate(tasks)
        ]
        lookup = {f.key: group for f, group in zip(futures, tasks, strict=True)}
        for future in as_completed(futures):
            try:
                rows = future.result()
            except Exception as exc:  # the task itself broke (not a case): its cases stay pending
                rows = task_failure(spec_json, lookup[future.key], exc)
            on_result(rows)
            future.release()
    finally:
        # workers still heartbeating while the scheduler stops log tracebacks that mean
        # nothing here: quieten distributed for the shutdown only
        quiet = [
            logging.getLogger(n)
            for n in (
                "distributed",
                "distributed.worker",
                "distributed.nanny",
                "distributed.core",
                "distributed.comm",
            )
        ]
        levels = [lg.level for lg in quiet]
        for lg in quiet:
            lg.setLevel(logging.CRITICAL)
        try:
            client.close()
            if cluster is not None:
                cluster.close()
        finally:
            for lg, level in zip(quiet, levels, strict=True):
                lg.setLevel(level)


def task_failure(spec_json: str, indices: Iterable[int], exc: BaseException) -> list[dict]:
    """Summaries of the cases of a task that broke outside any case (the cube could not be
    written, the worker died, ...): each names the case and the cause; the cases stay pending."""
    spec = SweepSpec.model_validate_json(spec_json)
    text = " ".join("".join(traceback.format_exception_only(type(exc), exc)).split())[:300]
    rows = []
    for i in indices:
        case = case_at(spec, i)
        rows.append(
            {
                "index": i,
                "status": "error",
                "points": case.layout.points,
                "aspect": case.layout.aspect,
                "message": f"task error, case left pending: {text}",
            }
        )
    return rows


def _run_synchronous(
    tasks: list[list[int]], task_args: tuple, on_result: Callable[[list[dict]], None]
) -> None:
    # one compute per task, so a task that breaks is reported like on a cluster and the rest run on
    for group in tasks:
        task = dask.delayed(run_task, pure=False)(*task_args[:3], group, task_args[3])
        try:
            (rows,) = dask.compute(task, scheduler=SYNCHRONOUS)
        except Exception as exc:
            rows = task_failure(task_args[1], group, exc)
        on_result(rows)
