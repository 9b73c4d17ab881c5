"""Running a sweep into its cube: resume, refuse a changed spec, progress and summary."""

from __future__ import annotations

import contextlib
import functools
import json
import math
import os
import time
import uuid
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

import numpy as np

from ftsweep import registry
from ftsweep.defaults import LINE_CACHE_MB, MAX_CASES, WORKER_WAIT_S, usable_cores
from ftsweep.engine.case import CaseError
from ftsweep.inputs import catalogs
from ftsweep.store import caselog, cube
from ftsweep.store.cube import CubeError
from ftsweep.store.lock import Lease, LeaseLost, cube_lock
from ftsweep.store.storage import PathLike, Place, StorageError, check_writable, place, with_configured
from ftsweep.sweeps import grow
from ftsweep.sweeps.cases import prune_cases, refuse_cases
from ftsweep.sweeps.connection import EarlyCluster
from ftsweep.sweeps.executor import SYNCHRONOUS, Cluster, TaskSpec, execute, run_task, warm_up
from ftsweep.sweeps.given import Rerun, RunNames, Where
from ftsweep.sweeps.spec import (
    Costs,
    LoadedSweep,
    SweepSpec,
    coordinates,
    load_sweep,
    n_cases,
    plan_tasks,
)
from ftsweep.sweeps.template import template
from ftsweep.version import git_revision


def default_cube_path(name: str) -> Path:
    """``outputs/<sweep>.zarr`` in the current folder."""
    return Path("outputs") / f"{name}.zarr"


# the driver merges its workers' case logs into the cube every MERGE_EVERY_S at the soonest [s],
# and later when its merges take longer: each waits its predecessor's duration over MERGE_SHARE,
# so merging keeps at most that share of a core from the workers, and at most MERGE_MAX_S [s]
# (besides at each case of the tail but the last, whose merge runs while the cluster closes).
# Readers of a running sweep's blocks see its cases this late at most; `status` and the other
# readers lay the logs over them anyway.
# A merge of the reference cube takes 0.2-0.6 s: every 5 s it was 2 s of the driver's CPU in a
# 33 s sweep on 2 cores (docs/performance.md, "Tuned constants")
MERGE_EVERY_S = 5.0
MERGE_SHARE = 0.03
MERGE_MAX_S = 30.0


def merge_interval(merge_s: float) -> float:
    """Seconds until the next periodic merge after one that took ``merge_s`` seconds."""
    return min(MERGE_MAX_S, max(MERGE_EVERY_S, merge_s / MERGE_SHARE))


# a cube's template is built in memory: beyond this it would not fit
TEMPLATE_BYTES_LIMIT = 4 * 2**30
# typical wall seconds of one converged case on one core (ftsweep bench), for cost estimates
SECONDS_PER_CASE = 2.5


def check_sweep_size(spec: SweepSpec, max_cases: int = MAX_CASES) -> None:
    """Refuse a sweep whose cube would not fit in memory or that would run for days, naming
    its size and the option that overrides the limit."""
    sizes = [v.size for v in coordinates(spec).values()]
    count = math.prod(sizes)
    bins = spec.resolution.error_map_bins or 0
    per_case = 8 * (len(cube.metrics_for(str(spec.layout))) + 4) + 16 * bins * bins
    nbytes = count * per_case
    hours = count * SECONDS_PER_CASE / 3600.0
    if count > max_cases:
        raise CubeError(
            f"the sweep has {count:,} cases ({' × '.join(map(str, sizes))}): about {hours:,.0f} core-hours "
            f"at {SECONDS_PER_CASE:g} s a case, over the limit of {max_cases:,} cases; narrow the axes, "
            "or raise the limit with --max-cases"
        )
    if nbytes > TEMPLATE_BYTES_LIMIT:
        raise CubeError(
            f"the sweep has {count:,} cases ({' × '.join(map(str, sizes))}): its cube would take about "
            f"{nbytes / 2**30:,.3g} GiB of memory to create, over the {TEMPLATE_BYTES_LIMIT / 2**30:g} GiB "
            "limit; narrow the axes or lower resolution.error_map_bins"
        )


def default_workers() -> int:
    """One worker process per core this process may use."""
    return usable_cores()


@dataclass
class SweepReport:
    """What a sweep run did; ``rows`` are the per-case summaries of this run."""

    cube: Place
    total: int
    skipped: int
    rows: list[dict] = field(default_factory=list)
    wall_s: float = 0.0
    workers: int = 1
    threads: int = 1  # the cluster's, which tasks are planned for
    dashboard: Optional[str] = None
    tasks: int = 0
    damaged: dict[int, str] = field(default_factory=dict)
    pruned: int = 0  # cases left out by --prune (this run's and earlier ones kept)
    refused: dict[int, str] = field(default_factory=dict)  # refused before dispatch, by reason
    queued: int = 0  # cases this run computes
    # the kinds' cost estimate of each case this run computes (work units, proportional to a
    # case's seconds: the progress's ETA scales it by the seconds measured per unit)
    costs: dict[int, float] = field(default_factory=dict)
    # the cube's axes as this run holds them (its spec's coordinates): a case's name
    axes: dict[str, Any] = field(default_factory=dict)
    note: str = ""  # what the run changed in the cube beyond its cases (it grew)
    connected: bool = False  # the run got its cluster (workers may have logged cases)
    # where the wall went: seconds from the run's start (its lock taken) to the cube set up
    # (set_up_s), to the cluster connected (connected_s: opened and warmed during the set-up
    # for a new cube) and to the first and the last case delivered (first_case_s,
    # last_case_s); the rest of ``wall_s``, which counts from the same start, is the last merge
    timeline: dict[str, float] = field(default_factory=dict)

    def case_name(self, index: int) -> str:
        """The case at flat index ``index`` of this run's cube named by its coordinates
        (``points=950000 aspect=16``), as select and export name it."""
        from ftsweep.store.values import case_name_at

        return case_name_at(self.axes, index)

    @property
    def done(self) -> int:
        return sum(r["status"] == "done" for r in self.rows)

    @property
    def failed(self) -> int:
        return sum(r["status"] == "failed" for r in self.rows)

    @property
    def refused_now(self) -> int:
        """Cases refused this run: before dispatch, and by their planning on a worker."""
        return len(self.refused) + sum(r["status"] == "refused" for r in self.rows)


@dataclass(frozen=True)
class Watchers:
    """What a run tells as it goes: each finished case (``progress``), the cluster once
    connected (``announce``); and the lease it writes under on object storage (None: a local
    lock)."""

    progress: Optional[Callable[[SweepReport, list[dict]], None]]
    announce: Optional[Callable[[SweepReport], None]]
    lease: Optional[Lease]


def _changed_keys(old_json: str, new: SweepSpec) -> list[str]:
    old = json.loads(old_json)
    now = new.model_dump(mode="json")
    return sorted(k for k in set(old) | set(now) if old.get(k) != now.get(k))


def prepare_cube(
    name: str,
    spec: SweepSpec,
    where: PathLike,
    restart: bool,
    catalog_folder: Optional[Path],
    lease: Optional[Lease] = None,
) -> tuple[int, str]:
    """Create the cube, or check an existing one belongs to ``spec`` (or grows into it,
    :mod:`ftsweep.sweeps.grow`) and merge the case logs a killed run left; returns the cases already
    done and a note on what changed (empty if nothing). The caller holds the cube's lock.

    An existing cube from another spec is refused unless ``restart``, which discards any
    existing cube and starts over. An unfinished template (a run killed while creating it)
    is replaced. ``lease``: the writer's lease on object storage (its fence guards each write).
    """
    out = place(where)
    grow.finish_interrupted(out)
    if cube.unfinished(out):
        out.remove_all()
    note = ""
    if out.exists():
        attrs = cube.read_attrs(out, check_schema=not restart)
        if restart:
            out.remove_all()
        else:
            _merge_fenced(out, lease)
            _same_catalog(out, spec, attrs, catalog_folder)
            if attrs["sweep_spec_hash"] != spec.spec_hash():
                note = _grow_or_refuse(name, spec, out, attrs)
            _warn_other_revision(out, attrs)
            return int(np.count_nonzero(cube.read_status(out) == cube.DONE)), note
    entries = catalogs.recorded_entries(spec.surface, spec.machine, spec.cutting, catalog_folder)
    cube.create(out, template(spec, name, entries))
    return 0, note


def _same_catalog(out: Place, spec: SweepSpec, attrs: dict[str, Any], folder: Optional[Path]) -> None:
    """Refuse to resume or grow a cube whose recorded catalog entries differ from the catalog
    as it is now (its new cases would use the edited entries, its record the old ones),
    naming the first field that differs."""
    from ftsweep.inputs.trust import first_difference

    try:
        recorded = json.loads(attrs["catalog_entries"])
    except (KeyError, TypeError, ValueError):
        raise CubeError(f"{out} records no readable catalog entries; re-run with --restart") from None
    now = json.loads(json.dumps(catalogs.recorded_entries(spec.surface, spec.machine, spec.cutting, folder)))
    for key in ("surface", "machine", "cutting"):
        name = next(iter(now[key]))
        if name not in (recorded.get(key) or {}):
            continue  # another entry: the spec changed, which the spec's own check names
        found = first_difference(recorded[key][name], now[key][name], f"{key} '{name}'")
        if found:
            raise CubeError(
                f"{out} was computed with other catalog entries than the catalog's now ({found}); its "
                "cases would mix the two. Re-run with --restart to recompute every case with the catalog "
                "as it is, or restore the entry."
            )


def _grow_or_refuse(name: str, spec: SweepSpec, out: Place, attrs: dict[str, Any]) -> str:
    """Extend the cube when ``spec`` only adds axis values; refuse any other change."""
    plan = grow.growth(attrs["sweep_spec"], spec)
    if plan is None:
        changed = ", ".join(_changed_keys(attrs["sweep_spec"], spec)) or "the spec"
        raise CubeError(
            f"{out} was created from a different spec of sweep '{attrs.get('sweep_name')}' "
            f"(changed: {changed}; a spec may only add values to its axes). Re-run with --restart "
            "to discard it and start over, or give another --out."
        )
    before = int(np.prod([len(p) for p in plan["positions"].values()]))
    grow.grow(out, spec, name, plan)
    return f"grown: {grow.describe(plan)} values; {n_cases(spec) - before} new case(s), {before} kept"


def _warn_other_revision(out: Place, attrs: dict[str, Any]) -> None:
    now = git_revision()
    if attrs.get("git_revision") not in (now, "unknown") and now != "unknown":
        warnings.warn(
            f"{out} was started by code revision {str(attrs.get('git_revision'))[:10]}, this is "
            f"{now[:10]}; resuming mixes their results (use --restart to recompute all)",
            stacklevel=3,
        )


def run_sweep(
    sweep: str | LoadedSweep,
    out: Optional[PathLike] = None,
    scheduler: Optional[str] = None,
    workers: Optional[int] = None,
    restart: bool = False,
    retry_failed: bool = False,
    catalog_folder: Optional[Path] = None,
    progress: Optional[Callable[[SweepReport, list[dict]], None]] = None,
    max_cases: int = MAX_CASES,
    prune: Optional[float] = None,
    line_cache_mb: float = LINE_CACHE_MB,
    announce: Optional[Callable[[SweepReport], None]] = None,
    worker_wait_s: float = WORKER_WAIT_S,
    storage_options: Optional[dict[str, Any]] = None,
) -> SweepReport:
    """Run (or resume) a sweep; cases already done in the cube are skipped.

    sweep : a sweep's name in the catalog or the path of its YAML file, or one already read
        (:func:`ftsweep.sweeps.spec.load_sweep`, so a caller that checked it reads it once).

    The cube is locked for the whole run (:mod:`ftsweep.store.lock`): a second writer, or a
    ``restart`` while another run writes, is refused. Done cases whose data chunks are
    missing or unreadable are recomputed (``report.damaged`` names them).

    scheduler : None (a LocalCluster of ``workers`` processes), ``"synchronous"``, or the
        address of a running dask scheduler (also read from ``DASK_SCHEDULER_ADDRESS``).
    retry_failed : also recompute cases recorded as failed.
    prune : leave out (status ``pruned``, not computed) every pending case whose estimated
        P-V (its kind's ``estimate``) exceeds ``prune`` times the best estimate among the
        aspect ratios of its point count. A run without ``prune`` computes earlier pruned cases.
    line_cache_mb : memory [MiB] per worker for the lines that cases share (0: none); the
        results are the same either way.
    announce : told the report once the cluster is connected (its workers, threads and
        dashboard), before any case runs.
    worker_wait_s : seconds to wait for a first worker of an external scheduler, and for one
        to come back after every worker left; then :class:`~ftsweep.sweeps.executor.ExecutorError`.
    out : a local folder or an fsspec URL (:mod:`ftsweep.store.storage`), with ``storage_options``
        for it beyond fsspec's configuration (they travel to the workers).
    """
    name, spec = load_sweep(sweep, catalog_folder) if isinstance(sweep, str) else sweep
    check_sweep_size(spec, max_cases)
    # workers may run in another folder (an external scheduler's): they get absolute paths
    out = place(out if out is not None else default_cube_path(name), storage_options)
    scheduler = scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS") or None
    check_destination(out, scheduler)
    out = with_configured(out)  # what this process resolved reaches the workers too
    workers = 1 if scheduler == "synchronous" else (workers or default_workers())
    run_id = f"{time.strftime('%Y%m%dT%H%M%S')}-{uuid.uuid4().hex[:8]}"
    fence_run = functools.partial(caselog.fence_run, out)  # a run whose lease is taken over
    command = f"ftsweep sweep {sweep if isinstance(sweep, str) else name}"
    with cube_lock(out, command, run_id, fence_run) as lease:
        return _run_locked(
            RunNames(name, run_id),
            spec,
            out,
            Where(scheduler, workers, line_cache_mb, worker_wait_s),
            restart,
            Rerun(retry_failed, prune),
            catalog_folder,
            Watchers(progress, announce, lease),
        )


def check_destination(out: Place, scheduler: Optional[str]) -> None:
    """Refuse before anything runs a cube a sweep cannot write (:func:`check_writable`), and a
    ``memory://`` cube with worker processes, which cannot see this process's memory."""
    check_writable(out)
    if out.protocol == "memory" and scheduler != "synchronous":
        raise StorageError(
            f"{out.url} lives in this process's memory, which the cluster's worker processes cannot "
            "reach; run with --scheduler synchronous, or write the cube to a folder or s3://"
        )


def _undamaged_status(out: Place, lease: Optional[Lease]) -> tuple[np.ndarray, dict[int, str]]:
    """The cube's case status after :func:`ftsweep.store.cube.repair` (unreadable chunks deleted,
    done cases with missing or unreadable data pending again), and those cases with the
    reason."""
    damaged = _fenced(lease, lambda fence: cube.repair(out, fence))
    return cube.read_status(out).ravel(), damaged


def _wanted_cases(
    spec: SweepSpec,
    out: Place,
    status: np.ndarray,
    rerun: Rerun,
    run_id: str,
    catalog_folder: Optional[Path],
    lease: Optional[Lease] = None,
) -> tuple[list[int], np.ndarray]:
    """The cases this run computes (after pruning, if asked) and the cube's status then."""
    retry_failed, prune = rerun.retry_failed, rerun.prune
    if prune is not None:
        if not registry.kind(spec.layout).estimates:
            raise CaseError(
                f"--prune needs a first-order estimate of the P-V (tables have one); a {spec.layout} "
                "sweep has none"
            )
        _fenced(lease, lambda fence: prune_cases(spec, out, status, prune, run_id, catalog_folder, fence))
        status = cube.read_status(out).ravel()
    # a refusal recorded by a worker's log is reconsidered by --retry-failed too: the driver's
    # own check (refuse_cases) refuses again what it refuses, so a forged one hides nothing
    wanted = (
        (status == cube.PENDING)
        | (retry_failed & ((status == cube.FAILED) | (status == cube.REFUSED)))
        | ((prune is None) & (status == cube.PRUNED))
    )
    return [int(i) for i in np.flatnonzero(wanted)], status


def _compute(
    report: SweepReport,
    spec: SweepSpec,
    costs: Costs,
    where: Where,
    run_id: str,
    catalog_folder: Optional[Path],
    watchers: Watchers,
    early: Optional[EarlyCluster],
    started: float,
) -> None:
    """Run the cases of ``costs`` (by index, with their costs) on the cluster ``where`` says,
    each case written as it finishes; the tasks are planned for the threads of the cluster the
    run got. ``early``: the cluster opened during the set-up (or None); ``started``: the run's
    start on :func:`time.perf_counter` (the timeline counts from it)."""
    if not costs:  # nothing to compute: no cluster is started (one opened early is closed by the caller)
        return
    plan, on_result, on_cluster = _callbacks(report, spec, costs, catalog_folder, watchers, started)
    execute(
        plan,
        TaskSpec(
            report.cube.url,
            spec.model_dump_json(),
            _worker_catalogs(catalog_folder),
            run_id,
            where.line_cache_mb,
            report.cube.options_json,
        ),
        where.scheduler,
        where.workers,
        on_result,
        task=run_task,
        warm=_warm(spec, catalog_folder, where),
        on_cluster=on_cluster,
        worker_wait_s=where.worker_wait_s,
        check_reach=True,
        early=early,
        finish=lambda: _merge_fenced(report.cube, watchers.lease),
    )


def _warm(spec: SweepSpec, catalog_folder: Optional[Path], where: Where) -> Callable[..., float]:
    """The warm-up every worker runs once before its first task (:func:`warm_up`)."""
    assert spec.layout is not None
    return functools.partial(warm_up, spec.surface, spec.layout, _worker_catalogs(catalog_folder))


def _worker_catalogs(catalog_folder: Optional[Path]) -> Optional[str]:
    """The catalog folder the workers read: this run's, or this process's ``FTSWEEP_CATALOGS``
    (a worker elsewhere may not have it set), or None for the installed catalogs."""
    return str(catalog_folder) if catalog_folder else os.environ.get("FTSWEEP_CATALOGS")


def _callbacks(
    report: SweepReport,
    spec: SweepSpec,
    costs: Costs,
    catalog_folder: Optional[Path],
    watchers: Watchers,
    started: float,
) -> tuple[Callable[[int], list[list[int]]], Callable[[list[dict]], None], Callable[[Cluster], None]]:
    """What the executor calls during a run: the planner of the tasks for the cluster's threads,
    the delivery of finished cases (merged as :func:`merge_interval` paces it, progress told) and the
    announcement of the cluster; each marks the report's timeline, in seconds from the run's
    start (``started``, on :func:`time.perf_counter`)."""
    progress, announce, lease = watchers.progress, watchers.announce, watchers.lease
    next_merge = [time.monotonic() + MERGE_EVERY_S]

    def plan(threads: int) -> list[list[int]]:
        tasks = plan_tasks(spec, list(costs), threads, catalog_folder, costs)
        report.tasks = len(tasks)
        return tasks

    def on_result(rows: list[dict]) -> None:
        report.timeline.setdefault("first_case_s", time.perf_counter() - started)
        report.timeline["last_case_s"] = time.perf_counter() - started
        report.rows.extend(rows)
        # in the tail (fewer cases left than threads) a core is free: merging now leaves the
        # last merge, after the last case, only that case's log; that one runs while the
        # cluster closes (execute's ``finish``)
        left = report.queued - len(report.rows)
        if 0 < left < report.threads or (left > 0 and time.monotonic() >= next_merge[0]):
            began = time.monotonic()
            _merge_fenced(report.cube, lease)  # a writer whose lease was taken over stops here
            ended = time.monotonic()
            next_merge[0] = ended + merge_interval(ended - began)
        if progress is not None:
            progress(report, rows)

    def on_cluster(got: Cluster) -> None:
        report.timeline["connected_s"] = time.perf_counter() - started
        report.connected = True
        report.workers, report.threads, report.dashboard = got.workers, got.threads, got.dashboard
        if announce is not None:
            announce(report)

    return plan, on_result, on_cluster


# a fenced write that finds an object changed (a stale writer's write landed on it) is redone
# from the object as it is now this many times before the run gives up
FENCED_TRIES = 3


def _fenced(lease: Optional[Lease], write: Callable[[Optional[Callable[[], None]]], Any]) -> Any:
    """Run ``write(fence)`` under the writer's lease: locally (no lease) at once; on object
    storage after confirming the lease by a conditional write on the lock object, with every
    block a conditional write (:mod:`ftsweep.store.fenced`). An object changed since this
    writer listed it: the lease is confirmed again, and a writer that still holds it writes
    again from what is there now (every write is idempotent); one that lost it stops with
    :class:`~ftsweep.store.lock.LeaseLost` and writes nothing more."""
    if lease is None:
        return write(None)
    from ftsweep.store.fenced import ObjectChanged

    for _ in range(FENCED_TRIES):
        lease.confirm()
        try:
            return write(lease.fence)
        except ObjectChanged:
            continue
    lease.confirm()
    raise LeaseLost(
        f"objects of {lease.cube} kept changing under this writer's conditional writes although it "
        "holds the lease: another process writes the cube without its lease; this run stops"
    )


def _merge_fenced(out: Place, lease: Optional[Lease]) -> None:
    """Merge the case logs into the blocks (:func:`_fenced`); the logs of a run this writer
    took the cube over from are read as they were before the takeover, never later ones."""
    keep = lease.inherited if lease is not None else frozenset()
    _fenced(lease, lambda fence: caselog.merge_logs(out, fence=fence, keep=keep))


def _run_locked(
    names: RunNames,
    spec: SweepSpec,
    out: Place,
    where: Where,
    restart: bool,
    rerun: Rerun,
    catalog_folder: Optional[Path],
    watchers: Watchers,
) -> SweepReport:
    lease = watchers.lease
    start = time.perf_counter()
    spec, name, held = (spec, names.sweep, "") if restart else grow.held_by(out, spec, names.sweep)
    names = RunNames(name, names.run_id)
    created = not out.exists()
    fresh = created or restart
    # a new cube, or one started over, has every case to compute: its cluster opens and warms
    # while the cube is made (ftsweep.sweeps.connection); leaving the block closes it unless
    # the run took it (a set-up that failed, nothing to compute, an error before it was needed)
    early: Optional[EarlyCluster] = None
    if fresh and where.scheduler != SYNCHRONOUS:
        early = EarlyCluster(
            where.scheduler, where.workers, where.worker_wait_s, _warm(spec, catalog_folder, where)
        )
    with early or contextlib.nullcontext():
        report, costs = _set_up(names, spec, out, restart, fresh, rerun, catalog_folder, lease, where.workers)
        report.timeline["set_up_s"] = time.perf_counter() - start
        report.note = "; ".join(n for n in (held, report.note) if n)
        try:
            _compute(report, spec, costs, where, names.run_id, catalog_folder, watchers, early, start)
        except BaseException:
            if created and not report.connected:
                # a cube this run made whose cluster never came (a wrong --scheduler): no task
                # ran, so nothing was computed, and nothing is left behind
                out.remove_all()
                raise
            # on an error or a signal too: what the workers finished goes into the blocks now,
            # unless another writer took over the lease (then the first error is the one told)
            try:
                _merge_fenced(out, lease)
            except LeaseLost:
                pass
            raise
        # the last merge ran as the executor's ``finish`` (while the cluster closed): a run that
        # computed nothing logged nothing
        if lease is not None:
            # a writer that lost its lease during its last merge says so (LeaseLost: exit status 75)
            lease.confirm()
        report.wall_s = time.perf_counter() - start
        return report


def _set_up(
    names: RunNames,
    spec: SweepSpec,
    out: Place,
    restart: bool,
    fresh: bool,
    rerun: Rerun,
    catalog_folder: Optional[Path],
    lease: Optional[Lease],
    workers: int,
) -> tuple[SweepReport, Costs]:
    """The cube made, grown or checked, and the cases this run computes with their costs (the
    others refused before dispatch, pruned or done already), in a report of the run.
    ``restart``: whether the run starts the cube over; ``fresh``: whether it makes it anew
    (over, or where there was none)."""
    name, run_id = names.sweep, names.run_id
    _, note = prepare_cube(name, spec, out, restart, catalog_folder, lease)
    # a cube made just now has nothing to repair (reading every chunk of it took 0.5 s)
    status, damaged = (cube.read_status(out).ravel(), {}) if fresh else _undamaged_status(out, lease)
    already = int(np.count_nonzero(status == cube.DONE))
    pending, status = _wanted_cases(spec, out, status, rerun, run_id, catalog_folder, lease)
    report = SweepReport(cube=out, total=n_cases(spec), skipped=already, workers=workers, damaged=damaged)
    report.pruned = int(np.sum(status == cube.PRUNED)) if rerun.prune is not None else 0
    # the cases sent: every wanted one not refused, with its cost for planning the tasks
    report.refused, costs = _fenced(
        lease, lambda fence: refuse_cases(spec, out, pending, run_id, catalog_folder, fence)
    )
    report.queued = len(costs)
    report.costs = {index: float(cost[0]) for index, cost in costs.items()}
    report.axes = coordinates(spec)
    report.note = note
    return report, costs
