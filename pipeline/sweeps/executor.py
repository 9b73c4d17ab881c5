"""Dask execution of sweep tasks: the synchronous scheduler, a LocalCluster, or an
existing ``dask.distributed`` scheduler, running the same task function.

:func:`execute` knows nothing of numerics: it is given a :class:`TaskSpec` (what every task of
a run shares), the groups of case indices, the task function (:func:`run_task` for sweeps:
compute the cases and write each into the cube as soon as it finishes), an optional warm-up
run once per worker, and what to report when a task breaks outside any case. Each task
returns one small summary dict per case; :func:`run_task` also publishes each as soon as its
case is written (a distributed event on the run's topic, :func:`publish`), so the driver
streams every case into ``on_result`` once, when it finishes, not when its task does.
"""

from __future__ import annotations

import queue
import threading
import time
import traceback
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional

import dask

from ftsweep import registry
from ftsweep.defaults import WORKER_WAIT_S
from ftsweep.engine import allocator, compiling
from ftsweep.engine.case import Case, CaseError
from ftsweep.engine.lines import LineCache
from ftsweep.simulate import run_case
from ftsweep.store.caselog import CaseLog
from ftsweep.store.storage import Place
from ftsweep.sweeps.connection import CONNECT_TIMEOUT_S, Cluster, EarlyCluster, ExecutorError, open_cluster
from ftsweep.sweeps.spec import SweepSpec, case_at, case_lines


@dataclass(frozen=True)
class TaskSpec:
    """What every task of one run shares; plain strings, so it travels to any worker.

    cube : absolute path of the cube the tasks write.
    spec_json : the resolved sweep spec (:class:`ftsweep.sweeps.spec.SweepSpec` as JSON).
    catalog_folder : catalogs to read, or None for the default.
    run_id : identifier recorded with every case this run computes.
    line_cache_mb : memory [MiB] each worker may hold of the lines its cases share
        (:class:`ftsweep.engine.lines.LineCache`); 0 computes every case on its own.
    storage_options : the cube's explicit storage options (JSON; :mod:`ftsweep.store.storage`).
    """

    cube: str
    spec_json: str
    catalog_folder: Optional[str]
    run_id: str
    line_cache_mb: float = 0.0
    storage_options: str = "{}"


# the cache of the run this worker process serves (a new run releases the previous run's)
_LINE_CACHES: dict[str, LineCache] = {}


def line_cache(task: TaskSpec) -> Optional[LineCache]:
    """This worker's line cache for ``task``'s run, or None when the run asks for none."""
    if task.line_cache_mb <= 0:
        return None
    cache = _LINE_CACHES.get(task.run_id)
    if cache is None:
        _LINE_CACHES.clear()
        cache = _LINE_CACHES[task.run_id] = LineCache(task.line_cache_mb * 2**20)
    return cache


# where a task publishes its cases when it runs in this process (the synchronous scheduler)
_LOCAL = threading.local()


def progress_topic(run_id: str) -> str:
    """The distributed event topic a run's cases are published on."""
    return f"ftsweep-case-{run_id}"


def publish(task: TaskSpec, row: dict) -> None:
    """Tell the driver that a case is written, now: an event on the run's topic on a
    distributed worker, or the in-process sink of the synchronous scheduler; nothing if
    neither listens (the task's return value carries the row anyway)."""
    sink = getattr(_LOCAL, "sink", None)
    if sink is not None:
        sink(row)
        return
    try:
        from distributed import get_worker

        worker = get_worker()
    except (ImportError, ValueError):  # not on a distributed worker
        return
    worker.log_event(progress_topic(task.run_id), row)


class Deliveries:
    """Hands every case's row to ``on_result`` exactly once, whichever comes first: its
    published event or its task's return value (which also carries the rows of a task that
    broke, or of a task function that publishes nothing). Thread-safe: events arrive on the
    client's event-loop thread and are delivered from the driver's."""

    def __init__(self, on_result: Callable[[list[dict]], None]) -> None:
        self.on_result = on_result
        self.seen: set[int] = set()
        self.events: queue.SimpleQueue[dict] = queue.SimpleQueue()

    def event(self, row: dict) -> None:
        self.events.put(row)

    def drain(self) -> None:
        rows = []
        while True:
            try:
                rows.append(self.events.get_nowait())
            except queue.Empty:
                break
        self.deliver(rows)

    def deliver(self, rows: list[dict]) -> None:
        fresh = [r for r in rows if r.get("index") not in self.seen]
        self.seen.update(int(r["index"]) for r in fresh if r.get("index") is not None)
        if fresh:
            self.on_result(fresh)


TaskFn = Callable[[TaskSpec, list[int]], list[dict]]
ErrorFn = Callable[[TaskSpec, list[int], BaseException], list[dict]]
# told the cluster, the warm-up, and what runs once every task delivered (:func:`execute`)
Hooks = tuple[Optional[Callable[[Cluster], None]], Optional[Callable[[], Any]], Optional[Callable[[], None]]]

SYNCHRONOUS = "synchronous"
# how often the driver looks for published cases while no task finishes [s]
EVENT_POLL_S = 0.25
# how long reading a finished task's summaries may take before it counts as lost with its
# worker [s] (they are a few kB)
RESULT_WAIT_S = 5.0


def _sharing(spec: SweepSpec, indices: list[int], folder: Optional[Path]) -> set[int]:
    """The cases of a task whose lines another case of the task simulates too
    (:func:`ftsweep.sweeps.spec.case_lines`): only theirs are worth keeping. Keeping lines no case
    reads again costs fresh memory for every batch (measured on the reference sweep, 2
    workers: 2 GiB of caches took 1.4 M page faults, 14 s of system time, and the wall time
    from 33.5 to 38.7 s, for 11 of 84 cases reusing lines)."""
    keys = {i: case_lines(spec, i, folder)[1] for i in indices}
    counts = Counter(k for k in keys.values() if k is not None)
    return {i for i, k in keys.items() if k is not None and counts[k] > 1}


def run_task(task: TaskSpec, indices: list[int]) -> list[dict]:
    """Compute the cases ``indices`` of a sweep and write each into the cube (worker side)."""
    spec = SweepSpec.model_validate_json(task.spec_json)
    folder = Path(task.catalog_folder) if task.catalog_folder else None
    # each task logs its cases; the driver merges them into the cube's blocks (ftsweep.store.caselog)
    writer = CaseLog(Place(task.cube, task.storage_options), task.run_id)
    run_id = task.run_id
    cache = line_cache(task)
    sharing = _sharing(spec, indices, folder) if cache is not None else set()
    out = []
    for index in indices:
        case = case_at(spec, index)
        hits = cache.hits if cache is not None else 0
        try:
            record = run_case(case, folder, lines=cache if index in sharing else None)
        except Exception as exc:  # a failing case is recorded and the rest run on
            # a case its planning refuses fails the same way every time: refused, which a plain
            # re-run leaves (--retry-failed reconsiders it, the driver's own check first)
            refused = isinstance(exc, CaseError)
            message = str(exc) if refused else f"{type(exc).__name__}: {exc}"
            (writer.write_refused if refused else writer.write_failed)(index, message, run_id)
            status = "refused" if refused else "failed"
            out.append({"index": index, "status": status, "message": message, "request": case.layout.label()})
            publish(task, out[-1])
            continue
        writer.write_done(index, record, run_id)
        out.append(
            {
                "index": index,
                "status": "done",
                "pv_nm": record["pv_nm"],
                "n_points": record["n_points"],
                "request": case.layout.label(),
                "seconds": record["seconds"],
                "reused_batches": (cache.hits - hits) if cache is not None else 0,
            }
        )
        publish(task, out[-1])
    return out


def warm_up(surface: str, kind: str, catalog_folder: Optional[str] = None) -> float:
    """Compile (or load from numba's cache) every kernel once in this process, after tuning its
    allocator (:mod:`ftsweep.engine.allocator`: Dask's nanny starts workers with settings that make
    every batch page-fault its arrays afresh); returns seconds. On a machine's first run the
    time is recorded as its first compile (:func:`ftsweep.engine.compiling.recorded_first_compile`)."""
    t = time.perf_counter()
    allocator.tune()
    folder = Path(catalog_folder) if catalog_folder else None
    case = Case(surface=surface, layout=registry.kind(kind).warm_request())
    try:
        with compiling.recorded_first_compile():
            run_case(case, folder)
    except Exception:  # noqa: BLE001
        # a coarse pitch may not fit every surface, and a user's plug-in may raise: the
        # kernels compiled anyway, and each case then records its own failure with its message
        pass
    return time.perf_counter() - t


Plan = list[list[int]] | Callable[[int], list[list[int]]]


def execute(
    plan: Plan,
    spec: TaskSpec,
    scheduler: Optional[str],
    workers: int,
    on_result: Callable[[list[dict]], None],
    task: TaskFn = run_task,
    warm: Optional[Callable[[], Any]] = None,
    on_error: Optional[ErrorFn] = None,
    on_cluster: Optional[Callable[[Cluster], None]] = None,
    worker_wait_s: float = WORKER_WAIT_S,
    check_reach: bool = False,
    early: Optional[EarlyCluster] = None,
    finish: Optional[Callable[[], None]] = None,
) -> None:
    """Run ``task(spec, group)`` for every group of case indices and call ``on_result`` with
    each task's summaries as it finishes.

    plan : the groups, or a function of the cluster's thread count that makes them (asked
        once connected: an external cluster's, not this machine's); no groups start nothing.
    scheduler : ``"synchronous"`` for dask's synchronous scheduler in this process, an
        address (``tcp://host:port``) of a running ``dask scheduler``, or None for a
        ``LocalCluster`` with ``workers`` single-threaded worker processes.
    warm : run once in every worker (and here, for the synchronous scheduler) before any
        task, e.g. to pay numba's compile cost outside the timed cases.
    on_error : the summaries of a task that raised (default :func:`task_failure`); the
        other tasks run on.
    on_cluster : told the cluster's workers, threads and dashboard once connected.
    worker_wait_s : seconds to wait for a first worker, and for one to come back once every
        worker left; then :class:`ExecutorError` (finished cases are written already).
    check_reach : one worker opens ``spec.cube`` before any task is sent (a sweep's run).
    early : the cluster, opened and warmed while the caller set up, with this ``warm``
        (:class:`ftsweep.sweeps.connection.EarlyCluster`); None opens it here.
    finish : called once every task has delivered its cases, while the cluster closes (and
        after the last task on the synchronous scheduler); not after an error.
    """
    on_error = on_error or task_failure
    if scheduler == SYNCHRONOUS:
        groups = plan(1) if callable(plan) else plan
        if groups:
            _in_this_process(groups, spec, (task, on_error), on_result, (on_cluster, warm, finish))
        return
    if early is None and not callable(plan) and not plan:  # an early cluster is closed below
        return
    opened = early.take() if early is not None else open_cluster(scheduler, workers, worker_wait_s, warm)
    client = opened.client
    delivered = False
    try:
        groups = plan(opened.got.threads) if callable(plan) else plan
        if not groups:
            return
        if on_cluster is not None:
            on_cluster(opened.got)
        if check_reach:
            _check_reach(client, spec, scheduler)
        _run_distributed(client, groups, spec, (task, on_error), on_result, worker_wait_s)
        delivered = True
    finally:
        opened.close(finish if delivered else None)


def _in_this_process(
    groups: list[list[int]],
    spec: TaskSpec,
    fns: tuple[TaskFn, ErrorFn],
    on_result: Callable[[list[dict]], None],
    hooks: Hooks,
) -> None:
    """:func:`execute` on the synchronous scheduler: told as a cluster of one thread, warmed,
    every group in order, then ``finish`` (``hooks``: on_cluster, warm, finish)."""
    on_cluster, warm, finish = hooks
    if on_cluster is not None:
        on_cluster(Cluster(workers=1, threads=1))
    if warm is not None:
        warm()
    _run_synchronous(groups, spec, fns[0], fns[1], on_result)
    if finish is not None:
        finish()


def _check_reach(client: Any, spec: TaskSpec, scheduler: Optional[str]) -> None:
    """One worker opens the cube before any task is sent: a worker that cannot reach it (an
    endpoint or credentials it lacks, a folder it does not see) stops the run in one line."""
    from ftsweep.store.storage import Place, reach_error

    try:
        answer = client.submit(reach_error, Place(spec.cube, spec.storage_options), pure=False).result(
            timeout=CONNECT_TIMEOUT_S
        )
    except Exception as exc:  # the probe itself could not run or answer in time
        answer = f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}"
    if answer:
        raise ExecutorError(
            f"a worker of {scheduler or 'the local cluster'} cannot reach the cube {spec.cube} ({answer}); "
            "pass the store's options with --storage-option KEY=VALUE (they travel to the workers, "
            "credentials too), or give the workers the configuration this machine has"
        )


def _run_distributed(
    client: Any,
    groups: list[list[int]],
    spec: TaskSpec,
    fns: tuple[TaskFn, ErrorFn],
    on_result: Callable[[list[dict]], None],
    worker_wait_s: float,
) -> None:
    from distributed import wait

    task, on_error = fns
    deliveries = Deliveries(on_result)
    topic = progress_topic(spec.run_id)
    client.subscribe_topic(topic, lambda event: deliveries.event(event[1]))
    futures = [
        client.submit(task, spec, group, pure=False, key=f"ftsweep-task-{i}-{spec.run_id}")
        for i, group in enumerate(groups)
    ]
    lookup = {f.key: group for f, group in zip(futures, groups, strict=True)}
    pending = set(futures)
    watch = WorkerWatch(client, worker_wait_s)
    try:
        while pending:
            try:
                done, pending = wait(pending, timeout=EVENT_POLL_S, return_when="FIRST_COMPLETED")
            except TimeoutError:
                done = set()
            deliveries.drain()
            for future in done:
                rows = _task_rows(future, lookup[future.key], spec, on_error)
                if rows is None:  # lost with its worker before we read it: computed again
                    pending.add(future)
                    continue
                deliveries.deliver(rows)
                future.release()
            if pending:
                watch.check(len(deliveries.seen))
    finally:
        client.unsubscribe_topic(topic)


def _task_rows(future: Any, group: list[int], spec: TaskSpec, on_error: ErrorFn) -> Optional[list[dict]]:
    """The summaries a finished task returned, those of its failure (the task itself broke, not
    a case: its cases stay pending), or None when its result went with a worker that left
    before it was read. The result is then computed again; waiting for it without a time limit
    hung a run whose every worker had left (the watch never got its turn)."""
    if future.status == "error":
        return on_error(spec, group, future.exception())
    try:
        return future.result(timeout=RESULT_WAIT_S)
    except TimeoutError:
        if future.status == "error":  # broke meanwhile, raising a TimeoutError of its own
            return on_error(spec, group, future.exception())
        return None
    except Exception as exc:  # noqa: BLE001 - any failure of the task is reported with its cases
        return on_error(spec, group, exc)


class WorkerWatch:
    """Ends a run whose cluster has had no worker for ``wait_s`` seconds: its tasks would
    wait for one forever, silently (a batch system took back every node, say)."""

    # asking the scheduler for its workers costs a round trip: not at every poll
    EVERY_S = 1.0

    def __init__(self, client: Any, wait_s: float) -> None:
        self.client = client
        self.wait_s = wait_s
        self.asked = time.monotonic()
        self.none_since: Optional[float] = None

    def check(self, finished: int) -> None:
        now = time.monotonic()
        if now - self.asked < self.EVERY_S:
            return
        self.asked = now
        if self.client.nthreads():
            self.none_since = None
            return
        self.none_since = self.none_since or now
        if now - self.none_since >= self.wait_s:
            raise ExecutorError(
                f"every worker of the cluster left and none came back within {self.wait_s:g} s; "
                f"the {finished} case(s) finished this run are in the cube, the others stay pending: "
                "start workers and run the same command again to go on"
            )


def task_failure(task: TaskSpec, indices: Iterable[int], exc: BaseException) -> list[dict]:
    """Summaries of the cases of a task that broke outside any case (the cube could not be
    written, the worker died, ...): each names the case and the cause; the cases stay pending."""
    spec = SweepSpec.model_validate_json(task.spec_json)
    text = " ".join("".join(traceback.format_exception_only(type(exc), exc)).split())[:300]
    rows = []
    for i in indices:
        case = case_at(spec, i)
        rows.append(
            {
                "index": i,
                "status": "error",
                "request": case.layout.label(),
                "message": f"task error, case left pending: {text}",
            }
        )
    return rows


def _run_synchronous(
    groups: list[list[int]],
    spec: TaskSpec,
    task: TaskFn,
    on_error: ErrorFn,
    on_result: Callable[[list[dict]], None],
) -> None:
    # one compute per task, so a task that breaks is reported like on a cluster and the rest run on
    deliveries = Deliveries(on_result)
    _LOCAL.sink = lambda row: deliveries.deliver([row])
    try:
        for group in groups:
            delayed = dask.delayed(task, pure=False)(spec, group)
            try:
                (rows,) = dask.compute(delayed, scheduler=SYNCHRONOUS)
            except Exception as exc:
                rows = on_error(spec, group, exc)
            deliveries.deliver(rows)
    finally:
        _LOCAL.sink = None
