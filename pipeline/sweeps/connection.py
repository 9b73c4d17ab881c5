"""Opening a sweep's cluster (a LocalCluster, or a running scheduler's), checking its workers
and closing it; and a cluster opened on a thread of its own while the driver sets up the cube.

A sweep's driver spends its first seconds on the cube (its template, its status) and a local
cluster's first seconds are its workers' start and warm-up (imports, numba's kernels loaded):
neither needs the other, so :class:`EarlyCluster` opens the cluster, waits for its workers and
warms them while the driver works, and :func:`ftsweep.sweeps.executor.execute` takes what it
opened. Reference sweep on 2 workers: docs/performance.md ("Where a run's wall goes").
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Optional

import dask

from ftsweep.version import __version__

# a scheduler that does not answer within this many seconds is reported, not waited for
CONNECT_TIMEOUT_S = 5


class ExecutorError(RuntimeError):
    """The sweep could not be run on the asked scheduler; the message says why."""


@dataclass(frozen=True)
class Cluster:
    """The cluster a run got: its workers and threads (tasks are planned for the threads) and
    the dashboard's address (None for the synchronous scheduler or without a dashboard)."""

    workers: int
    threads: int
    dashboard: Optional[str] = None


def _cluster_of(client: Any, scheduler: Optional[str], wait_s: float) -> Cluster:
    """The connected cluster, once a worker joined (within ``wait_s``) and every worker can
    import ftsweep (a worker that cannot is named, not left to fail each task obscurely)."""
    where = scheduler or "the local cluster"
    try:
        client.wait_for_workers(1, timeout=wait_s)
    except TimeoutError:
        raise ExecutorError(
            f"no worker joined the scheduler at {where} within {wait_s:g} s; start workers "
            "(dask worker ADDRESS) and run again"
        ) from None
    # exec is a builtin: it reaches a worker that has no ftsweep, which then says so
    answers = client.run(exec, "import ftsweep", on_error="return")
    lacking = {w: a for w, a in answers.items() if isinstance(a, BaseException)}
    if lacking:
        names = ", ".join(sorted(lacking)[:5])
        first = next(iter(lacking.values()))
        raise ExecutorError(
            f"{len(lacking)} worker(s) of {where} cannot import ftsweep ({names}: "
            f"{type(first).__name__}: {str(first)[:200]}); install ftsweep {__version__} in every "
            "worker's environment"
        )
    threads = client.nthreads()
    return Cluster(
        workers=len(threads), threads=sum(threads.values()), dashboard=_dashboard(client, scheduler)
    )


def _dashboard(client: Any, scheduler: Optional[str] = None) -> Optional[str]:
    """The dashboard's address, or None when the scheduler runs none, or when the local
    cluster's would only say that Dask needs bokeh (not installed here)."""
    import importlib.util

    if scheduler is None and importlib.util.find_spec("bokeh") is None:
        return None
    try:
        link = client.dashboard_link
    except (KeyError, AttributeError):  # no "dashboard" among the scheduler's services
        return None
    return str(link) if link else None


@dataclass(frozen=True)
class Connection:
    """A client; the local cluster it talks to and that cluster's scratch folder (both None
    for a running scheduler's, which keeps its own)."""

    client: Any
    cluster: Any = None
    scratch: Optional[str] = None


def _connect(scheduler: Optional[str], workers: int) -> Connection:
    """A client of the scheduler at ``scheduler`` (checked within :data:`CONNECT_TIMEOUT_S`),
    or of a new LocalCluster of ``workers`` single-threaded processes whose scratch space
    (workers' spill folders, distributed's lock files) is a temporary folder of this run's,
    removed when it closes (:func:`_close_quietly`)."""
    import tempfile

    from distributed import Client, LocalCluster

    if scheduler:
        try:
            return Connection(Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s"))
        except (OSError, TimeoutError, ValueError) as exc:
            raise ExecutorError(
                f"no dask scheduler answered at {scheduler[:200]} within {CONNECT_TIMEOUT_S} s "
                f"({type(exc).__name__}); start one (dask scheduler) or omit --scheduler for a local cluster"
            ) from None
    # the workers inherit this process's environment: numpy reads its huge-page setting when
    # a worker imports it (ftsweep.engine.allocator)
    from ftsweep.engine import allocator

    allocator.no_hugepage_advice()
    scratch = tempfile.mkdtemp(prefix="ftsweep-cluster-")
    # the scheduler and the nannies live in this process and read their settings when made
    # the scheduler's and the nannies' work spaces too (their lock files) live in the scratch folder
    config = {**LOCAL_CLUSTER_CONFIG, "temporary-directory": scratch}
    with dask.config.set(config):
        cluster = LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            # a free port on this machine only: on ":0" it listened on every interface
            dashboard_address="127.0.0.1:0",
            silence_logs=logging.CRITICAL,  # task errors reach us through the futures
            config=config,
            local_directory=scratch,
        )
    return Connection(Client(cluster), cluster, scratch)


# the local cluster's Dask settings (an external cluster keeps its own). Every periodic callback
# of a worker's event loop takes the GIL from the case it runs, and those of the scheduler and
# the nannies take a core's share from the workers on a machine with as many workers as cores:
# - no statistical profiler, whose thread walked the stacks every 10 ms (reference sweep on 2
#   workers: wall 32.4 s on average with it, 31.2 s without, four runs each);
# - the loops' responsiveness tick every 1 s, not 20 ms; the system monitor (the dashboard's
#   CPU and memory plots) every 2 s, not 0.5 s; the nannies' memory check every 0.5 s, not
#   0.1 s (a worker still stops at its memory limit); no work stealing (tasks are queued on the
#   scheduler and handed to free workers, longest first, so there is nothing to steal).
#   Reference sweep on 2 workers, alternating runs (the memory check then every 1 s): wall
#   37.3 and 33.7 s against 41.0 and 40.7 s; the driver's CPU 7.4 and 6.4 s against 9.1 and
#   8.9 s; summed case time 56.8 and 53.8 s against 65.8 and 63.8 s (docs/performance.md)
LOCAL_CLUSTER_CONFIG = {  # dotted keys: the nanny merges a worker's config shallowly
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "500ms",
    "distributed.scheduler.work-stealing": False,
}


def _close_quietly(client: Any, cluster: Any, scratch: Optional[str] = None) -> None:
    # workers still heartbeating while the scheduler stops log tracebacks that mean nothing
    # here: quieten distributed for the shutdown only
    names = ("distributed", "distributed.worker", "distributed.nanny", "distributed.core", "distributed.comm")
    quiet = [logging.getLogger(n) for n in names]
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
        if scratch is not None:
            import shutil

            shutil.rmtree(scratch, ignore_errors=True)


@dataclass
class Opened:
    """A connected cluster: its client, the local cluster (None for an external scheduler's),
    what it has and the local cluster's scratch folder (:class:`Connection`)."""

    client: Any
    cluster: Any
    got: Cluster
    scratch: Optional[str] = None

    def close(self, meanwhile: Optional[Callable[[], None]] = None) -> None:
        """Close the client and the local cluster; with ``meanwhile``, run it in this thread
        while they close on another (a local cluster's workers take 0.2-0.6 s to stop: the
        driver's last merge of a sweep runs in that time), and return once both are done, with
        the first error of ``meanwhile`` or else of the close."""
        if meanwhile is None:
            _close_quietly(self.client, self.cluster, self.scratch)
            return
        with ThreadPoolExecutor(1, thread_name_prefix="ftsweep-close") as pool:
            closing = pool.submit(_close_quietly, self.client, self.cluster, self.scratch)
            try:
                meanwhile()
            finally:
                error = closing.exception()
        if error is not None:
            raise error


def open_cluster(
    scheduler: Optional[str], workers: int, wait_s: float, warm: Optional[Callable[[], Any]] = None
) -> Opened:
    """Connect (:func:`_connect`), wait for a worker that imports
    ftsweep (``wait_s`` seconds at most) and run ``warm`` once in every worker; a failure
    closes what was opened and raises."""
    conn = _connect(scheduler, workers)
    try:
        got = _cluster_of(conn.client, scheduler, wait_s)
        if warm is not None:
            conn.client.run(warm)
    except BaseException:
        _close_quietly(conn.client, conn.cluster, conn.scratch)
        raise
    return Opened(conn.client, conn.cluster, got, conn.scratch)


class EarlyCluster:
    """:func:`open_cluster` started now on a thread of its own. :meth:`take` waits for it and
    hands it over (its errors raise there, as they would have in the driver); :meth:`close`,
    also on leaving a ``with`` block, closes a cluster nobody took (a set-up that failed, or
    found nothing to compute) and does nothing to one taken."""

    def __init__(
        self, scheduler: Optional[str], workers: int, wait_s: float, warm: Optional[Callable[[], Any]]
    ) -> None:
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="ftsweep-cluster")
        self._future: Future[Opened] = self._pool.submit(open_cluster, scheduler, workers, wait_s, warm)
        self._taken = False

    def __enter__(self) -> EarlyCluster:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def take(self) -> Opened:
        try:
            opened = self._future.result()
        except BaseException:
            if not self._future.done():  # interrupted while it opens: closed once it has opened
                self.close()
            raise
        self._taken = True
        self._pool.shutdown(wait=False)
        return opened

    def close(self) -> None:
        if self._taken:
            return
        self._taken = True
        try:
            opened = self._future.result()
        except BaseException:  # noqa: BLE001 - nobody asked for it: its failure tells nothing
            return
        finally:
            self._pool.shutdown(wait=False)
        opened.close()
