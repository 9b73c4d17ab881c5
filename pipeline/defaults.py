"""Defaults and limits the command line shows in its help, in a module that imports nothing,
so that ``ftsweep --help`` and every command's ``--help`` answer at once; the modules that
apply them (:mod:`ftsweep.engine.cost`, :mod:`ftsweep.engine.lines`, :mod:`ftsweep.sweeps.spec`,
:mod:`ftsweep.engine.case`) take them from here."""

# the largest simulation a case may cost, in evaluation nodes: about two hours of one core
MAX_NODES = 2.0e10
# default memory [MiB] per sweep worker for shared lines: every kept batch is fresh memory the
# kernel must fault in (~10 µs per 4 KiB page with zeroing), about what computing it costs, so
# a cache pays only for lines read again soon. Measured on 2 workers (README "Work shared
# across cases"): 512 MiB is as fast as 2048 where most cases share lines (the angular ladder)
# and 4 s faster where few do (the reference sweep); it holds a 650k-point ring case's lines
LINE_CACHE_MB = 512.0
# every case costs seconds of a core: beyond this many cases a sweep is refused unless the
# caller raises the limit (CLI: --max-cases)
MAX_CASES = 100_000
# the simulation's resolution (model §5; converged, see ftsweep.engine.case.Resolution)
SAMPLES_PER_CELL = 3
POINTS_PER_FEED = 2


def usable_cores() -> int:
    """Cores this process may run on (its CPU affinity where the system reports one, else
    the machine's count): the default threads of a case and workers of a sweep."""
    import os

    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on every platform
        return max(1, os.cpu_count() or 1)


# how long a sweep waits for a worker [s]: for the first to join an external scheduler, and
# for one to come back after every worker left (``ftsweep sweep --worker-wait``)
WORKER_WAIT_S = 60.0
