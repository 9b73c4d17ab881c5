"""The ``sweep`` command: run a sweep into its cube with progress lines, the cluster it got,
and an end-of-run summary."""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any, Optional

import click

from ftsweep.cli.common import (
    COUNT,
    NON_NEGATIVE,
    STORAGE_OPTIONS,
    FiniteRange,
    cube_place,
    first_compile_notice,
    one_line,
)
from ftsweep.defaults import LINE_CACHE_MB, MAX_CASES, WORKER_WAIT_S

if TYPE_CHECKING:
    from ftsweep.sweeps.spec import LoadedSweep

# exit statuses a scheduler can act on: 0 every case done; 1 cases failed or are pending, or
# the run could not go on (the message says why: re-run, or --retry-failed); 2 a usage error;
# 75 (EX_TEMPFAIL) another run holds the cube's lock: try again later
EXIT_DONE, EXIT_INCOMPLETE, EXIT_LOCKED = 0, 1, 75


@click.command()
@click.argument("sweep_name", metavar="NAME|PATH")
@click.option(
    "-o",
    "--out",
    metavar="PATH|URL",
    help="Cube to write: a Zarr folder every worker sees, or s3://bucket/c.zarr (the endpoint, "
    "region and fsspec options this machine has travel to the workers), or memory:// with "
    "--scheduler synchronous. Default: outputs/<sweep>.zarr.",
)
@click.option(
    "--scheduler",
    metavar="ADDRESS",
    help="Address of a running dask scheduler (tcp://host:port); also read from "
    "$DASK_SCHEDULER_ADDRESS. 'synchronous' runs in this process. Default: a local cluster.",
)
@click.option("--workers", type=COUNT, help="Worker processes of the local cluster. Default: one per core.")
@click.option(
    "--restart",
    is_flag=True,
    help="Discard an existing cube and start over (required when the spec changed).",
)
@click.option(
    "--retry-failed",
    is_flag=True,
    help=(
        "Also recompute cases recorded as failed, and reconsider refused ones (those the "
        "machine or layout rules out are refused again, at once)."
    ),
)
@click.option(
    "--max-cases",
    type=COUNT,
    default=MAX_CASES,
    show_default=True,
    help="Refuse sweeps of more cases than this (each takes seconds of a core).",
)
@click.option(
    "--prune",
    type=FiniteRange(min=1.0, min_open=True),
    metavar="FACTOR",
    help="Leave out cases whose estimated P-V (`ftsweep estimate`) exceeds FACTOR times the best "
    "estimate of their point count; they are marked pruned, and a run without --prune computes "
    "them. The estimate was within 0.62-1.23 of the simulation on the reference sweeps, so 3 is safe.",
)
@click.option(
    "--line-cache-mb",
    type=NON_NEGATIVE,
    default=LINE_CACHE_MB,
    show_default=True,
    help="Memory [MiB] each worker may keep of the lines (surface samples and exact commands) "
    "that cases on the same angular sampling share; 0 computes every case on its "
    "own. Results are the same either way. resolution.angular_ladder in the spec makes cases share.",
)
@click.option(
    "--worker-wait",
    type=FiniteRange(min=0.0, min_open=True),
    default=WORKER_WAIT_S,
    show_default=True,
    metavar="SECONDS",
    help="How long to wait for a first worker of --scheduler, and for one to come back after "
    "every worker left; then the run ends with exit status 1 (finished cases are in the cube).",
)
@STORAGE_OPTIONS
def sweep(
    sweep_name: str,
    out: Optional[str],
    scheduler: Optional[str],
    workers: Optional[int],
    restart: bool,
    retry_failed: bool,
    max_cases: int,
    prune: Optional[float],
    line_cache_mb: float,
    worker_wait: float,
    storage_options: tuple[str, ...],
) -> None:
    """Run a sweep of point counts and aspect ratios into a Zarr result cube.

    NAME is a spec in the catalog's sweeps/ (e.g. sinewave-ring, lens-array-mesh: `ftsweep
    catalogs` lists them and the folder), or give a
    path to a YAML file. Every case is logged as soon as it finishes (`ftsweep status` counts
    it at once) and merged into the cube's blocks within 5-30 s. Re-running the same command
    computes only what is missing, so an interrupted or killed run loses nothing already
    written; done cases whose data files are missing or unreadable are recomputed. A cube
    made from a different spec is refused unless --restart, which discards the cube and
    starts over — except a spec that only adds values to its axes: the cube grows and only
    the new cases are computed. One process writes a cube at a time: a second sweep on the
    same cube (also with --restart) is refused while the first runs.

    \b
    Exit status: 0 every case done; 1 cases failed, refused or pending, or the run could not go
    on (the message says why); 2 a usage error; 75 another run holds the cube's lock (try later).

    \b
    Examples:
      ftsweep sweep sinewave-ring
      ftsweep sweep my-sweep.yaml --out outputs/my.zarr --workers 2
      ftsweep sweep lens-array-mesh --scheduler tcp://127.0.0.1:8786
    """
    started = time.perf_counter()
    sweep, where = _prepare(sweep_name, out, storage_options, scheduler)
    from ftsweep.sweeps.run import run_sweep

    progress = SweepProgress(started)
    with _run_errors(progress):
        report = run_sweep(
            sweep,
            where,
            scheduler,
            workers,
            restart,
            retry_failed,
            progress=progress,
            announce=_announce_cluster,
            max_cases=max_cases,
            prune=prune,
            line_cache_mb=line_cache_mb,
            worker_wait_s=worker_wait,
        )
    _report_problems(report)
    counts = _print_sweep_summary(report, time.perf_counter() - started)
    if counts["pending"] or counts["failed"] or counts["refused"]:
        sys.exit(EXIT_INCOMPLETE)


def _prepare(
    sweep_name: str, out: Optional[str], storage_options: tuple[str, ...], scheduler: Optional[str]
) -> tuple[LoadedSweep, Any]:
    """Load the spec once (naming what is wrong with it), refuse a cube the sweep cannot write,
    and say what runs, and when the kernels compile first; returns the sweep read and the
    cube's place (None: the default)."""
    from ftsweep.inputs.catalogs import CatalogError
    from ftsweep.sweeps.cases import axis_summary
    from ftsweep.sweeps.spec import load_sweep

    try:
        sweep = load_sweep(sweep_name)
    except CatalogError as exc:
        raise click.ClickException(str(exc)) from None
    name, spec = sweep
    where = None if out is None else cube_place(out, storage_options)
    if where is not None:
        _check_destination(where, scheduler)
    click.echo(f"sweep {name}: {spec.surface}, {spec.layout} layouts, {axis_summary(spec)}", err=True)
    first_compile_notice()
    return sweep, where


def _check_destination(where: Any, scheduler: Optional[str]) -> None:
    """A cube the sweep cannot write is a usage error (exit 2), refused before anything runs."""
    from ftsweep.store.storage import StorageError
    from ftsweep.sweeps.run import check_destination

    try:
        check_destination(where, scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS") or None)
    except StorageError as exc:
        raise click.BadParameter(str(exc), param_hint="--out") from None


@contextlib.contextmanager
def _run_errors(progress: SweepProgress) -> Iterator[None]:
    """Around :func:`ftsweep.sweeps.run.run_sweep`: its errors as one-line messages, a word on
    stderr when a signal ends it (its lock is released on the way out), the progress closed."""
    from ftsweep.store.lock import LockError
    from ftsweep.sweeps.executor import ExecutorError

    try:
        yield
    except LockError as exc:  # another run writes the cube: a scheduler should try again later
        click.echo(f"Error: {exc}", err=True)
        sys.exit(EXIT_LOCKED)
    except (ValueError, ExecutorError) as exc:  # catalog, cube and case errors are ValueErrors
        raise click.ClickException(str(exc)) from None
    except SystemExit as exc:
        if exc.code in (128 + signal.SIGTERM, 128 + signal.SIGHUP):
            click.echo(
                "terminated by a signal: the cube's lock is released and finished cases are kept; "
                "run the same command to go on",
                err=True,
            )
        raise
    finally:
        progress.close()


def _announce_cluster(report: Any) -> None:
    """One line when the cluster is up: its workers and threads, and where its dashboard is."""
    board = report.dashboard or "none (pip install 'ftsweep[dashboard]' for one)"
    click.echo(
        f"cluster      {report.workers} worker(s), {report.threads} thread(s), {report.tasks} task(s); "
        f"dashboard {board}",
        err=True,
    )


def _report_problems(report: Any) -> None:
    """Say which done cases were recomputed (damaged) and refuse a run whose cases could not
    be started (they stay pending)."""
    for index, reason in sorted(report.damaged.items())[:5]:
        click.echo(f"recomputed   case {index}: it was done but {reason}", err=True)
    errors = [r for r in report.rows if r["status"] == "error"]
    if errors:
        first = errors[0]
        raise click.ClickException(
            f"{len(errors)} case(s) could not be run and stay pending; first: {_case_label(report, first)}: "
            f"{first['message']}"
        )


def _case_label(report: Any, row: dict[str, Any]) -> str:
    """A case of the run by its coordinates, with its layout as requested where known."""
    name = report.case_name(int(row["index"]))
    return f"case {name} ({row['request']})" if row.get("request") else f"case {name}"


class SweepProgress:
    """A sweep's progress on stderr, on the command's clock (``started``, as the summary's
    wall time): on a terminal one live bar (tqdm) with the cases done, failed, refused and
    pending and the time left; in a log or pipe one line at most every
    :data:`ftsweep.progress.LOG_INTERVAL_S` seconds, and the last."""

    def __init__(self, started: float) -> None:
        from ftsweep.progress import LOG_INTERVAL_S

        self.started = started
        self.tty = sys.stderr.isatty()
        self.interval_s = LOG_INTERVAL_S
        self.shown = 0.0  # the command's start: a first line after an interval, not at once
        self.bar: Any = None
        # counted as rows arrive: a sweep of 10⁵ cases must not rescan every row on each one
        self.failed = self.refused = 0
        self.eta = Eta()
        self.cost_total: Optional[float] = None  # the run's cases' summed cost, once

    def __call__(self, report: Any, rows: list[dict]) -> None:
        for r in rows:
            self.failed += r["status"] == "failed"
            self.refused += r["status"] == "refused"
            self.eta.finished(report.costs.get(r.get("index"), 0.0), r.get("seconds"))
        done, total = len(report.rows), report.queued
        elapsed = time.perf_counter() - self.started
        if not self.tty and elapsed - self.shown < self.interval_s and done < total:
            return
        refused = len(report.refused) + self.refused
        state = f"{self.failed} failed, {refused} refused, {total - done} pending"
        if self.cost_total is None:  # the cases this run computes are known before the first arrives
            self.cost_total = sum(report.costs.values())
        eta = self.eta.text(self.cost_total, total - done, max(report.threads, report.workers, 1))
        if self.tty:
            self._draw(len(rows), total, len(report.refused), f"{elapsed:6.1f} s, {eta}")
            return
        self.shown = elapsed
        last = rows[-1]
        what = f"{_case_label(report, last)}: " + (
            f"P-V {last['pv_nm']:.2f} nm" if last["status"] == "done" else one_line(last["message"], 300)
        )
        width = len(str(total))
        click.echo(f"[{done:>{width}}/{total}] {state} | {elapsed:6.1f} s, {eta} | {what}", err=True)

    def _draw(self, new: int, queued: int, upfront: int, clock: str) -> None:
        """One bar: ftsweep's counts, clock and ETA after it, none of tqdm's own (its rate, ETA
        and clock disagreed with ftsweep's), the counts from the bar's own so that they add up
        to its total, and a text of fixed width so that the bar does not jump."""
        total = queued + upfront
        if self.bar is None:
            import shutil

            from tqdm import tqdm

            # a terminal that reports no size (0 × 0, as a fresh pseudo-terminal) gets 100 × 24:
            # tqdm would hide a bar below a screen of no rows
            size = shutil.get_terminal_size((100, 24))
            # the cases refused before dispatch count as finished: the counts add up to the total
            self.bar = tqdm(
                total=total,
                initial=upfront,
                file=sys.stderr,
                unit="case",
                desc="sweep:",
                ncols=size.columns,
                nrows=size.lines,
                bar_format=self._format(upfront, total, upfront, clock),
            )
        # one snapshot: the text is made for the count the bar is about to show, and set before
        # the update draws it (set after, the line drawn held the new count and the old text)
        self.bar.bar_format = self._format(self.bar.n + new, total, upfront, clock)
        self.bar.update(new)
        self.bar.refresh()

    def _format(self, n: int, total: int, upfront: int, clock: str) -> str:
        """tqdm's bar format for ``n`` of ``total`` cases finished: the bar, then ftsweep's own
        text (not tqdm's postfix, which it prefixes with ", ")."""
        refused, width = upfront + self.refused, len(str(total))
        counts = (
            f"{n - self.failed - refused:>{width}} done, {self.failed:>{width}} failed, "
            f"{refused:>{width}} refused, {total - n:>{width}} pending"
        )
        return "{desc} {n_fmt}/{total_fmt} |{bar}| " + f"{counts} | {clock:<20s}"

    def close(self) -> None:
        """End the bar (on a terminal), so the summary starts on its own line."""
        if self.bar is not None:
            self.bar.close()
            self.bar = None


class Eta:
    """A sweep's time left from its kinds' cost estimate, corrected by the cases measured: the
    cost of the cases not finished (``SweepReport.costs``, work units proportional to a case's
    seconds) times the seconds measured per unit of the cases finished so far, over the
    cluster's threads. Tasks run the costliest cases first, so a mean of seconds per case
    would count every early case as costly as the first (5-7 times the time left at case 5
    of the reference sweep); per unit of cost it is not. The wall time is not used: it holds
    the cluster's start and the kernels' compilation."""

    def __init__(self) -> None:
        self.cost_done = 0.0  # every finished case's cost, timed or not
        self.timed_cost = 0.0
        self.timed_s = 0.0

    def finished(self, cost: float, seconds: Optional[float]) -> None:
        self.cost_done += cost
        if seconds and cost > 0:
            self.timed_cost += cost
            self.timed_s += float(seconds)

    def seconds_left(self, cost_total: float, threads: int) -> Optional[float]:
        """Seconds left [s], or None before a case was measured."""
        if self.timed_cost <= 0:
            return None
        left = max(cost_total - self.cost_done, 0.0)
        return left * (self.timed_s / self.timed_cost) / max(threads, 1)

    def text(self, cost_total: float, remaining: int, threads: int) -> str:
        if remaining <= 0:
            return "ETA 0 s"
        seconds = self.seconds_left(cost_total, threads)
        return "ETA –" if seconds is None else f"ETA {seconds:6.0f} s"


def _print_refused(report: Any) -> None:
    """This run's refused cases, grouped by reason (as ``ftsweep status`` groups them)."""
    from ftsweep.tools.status import grouped_reasons

    reasons = [*report.refused.values(), *(r["message"] for r in report.rows if r["status"] == "refused")]
    for group in grouped_reasons(reasons):
        click.echo(f"refused      {group['count']} case(s), e.g. {one_line(group['example'], 300)}")


def _print_sweep_summary(report: Any, wall_s: float) -> dict[str, int]:
    """The end-of-run summary on stdout: counts, throughput, failures, best per point count;
    ``wall_s`` the command's time so far (the clock progress shows)."""
    from ftsweep.store.values import value_text
    from ftsweep.sweeps.cases import cube_counts
    from ftsweep.tools.query import best_per_point_count

    counts = cube_counts(report.cube)
    click.echo(f"cube         {report.cube}")
    if report.note:
        click.echo(f"spec         {report.note}")
    click.echo(
        f"cases        {report.total} in all: {counts['done']} done, {counts['failed']} failed, "
        f"{counts['refused']} refused, {counts['pending']} pending, {counts['pruned']} pruned "
        f"({report.skipped} were done already, {len(report.rows)} run now)"
    )
    if not report.queued:
        click.echo(f"nothing to do: no case is pending (wall time {wall_s:.1f} s; no cluster was started)")
    else:
        busy = sum(r.get("seconds", 0.0) for r in report.rows)
        rate = len(report.rows) / report.wall_s if report.wall_s > 0 else float("nan")
        click.echo(
            f"wall time    {wall_s:.1f} s ({report.wall_s:.1f} s on {report.workers} worker(s), "
            f"{report.threads} thread(s)): {rate:.3g} cases/s; summed case time {busy:.1f} s"
        )
    reused = [r.get("reused_batches", 0) for r in report.rows if r["status"] == "done"]
    if any(reused):
        click.echo(
            f"shared lines {sum(1 for n in reused if n)} case(s) reused {sum(reused):,} batches of lines "
            "computed by an earlier case on the same worker"
        )
    for r in [r for r in report.rows if r["status"] == "failed"][:5]:
        click.echo(f"failed       {_case_label(report, r)}: {one_line(r['message'], 300)}")
    _print_refused(report)
    rows = best_per_point_count(report.cube)
    axis = rows[0]["axis"] if rows else "points"
    # tables are swept over aspect ratios; a path program's best is named by its case number
    tables = any(r["swept_aspect"] for r in rows)
    third = "best α" if tables else "case"
    label = "target N" if axis == "points" else axis
    click.echo(
        f"best P-V per {'point count' if axis == 'points' else axis} (among the cases select may choose):"
    )
    click.echo(f"  {label:>10s} {'actual N':>10s} {third:>8s} {'P-V nm':>9s}")
    for row in rows:
        # a count with thousands separators; a rule's value (a chord [µm], ...) as it is swept
        target = f"{row['points']:10,.0f}" if axis == "points" else f"{value_text(row['points']):>10s}"
        if row["pv_nm"] is None:
            click.echo(f"  {target} {'–':>10s} {'–':>8s} {'–':>9s}")
            continue
        which = f"{row['aspect']:8.3g}" if tables else f"{row['index']:8d}"
        click.echo(f"  {target} {row['n_points']:10,d} {which} {row['pv_nm']:9.2f}")
    return counts
