"""What a sweep run is given besides its spec (:func:`ftsweep.sweeps.run.run_sweep`): its
names, what it computes again and where its cases run, each a value that travels together."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional


@dataclass(frozen=True)
class RunNames:
    """The sweep's name (its cube's, as the spec names it) and this run's id (the case logs')."""

    sweep: str
    run_id: str


@dataclass(frozen=True)
class Rerun:
    """What a run computes again: failed cases (``retry_failed``), and the pruning factor of
    hopeless pending cases (``prune``; None: no pruning)."""

    retry_failed: bool
    prune: Optional[float]


@dataclass(frozen=True)
class Where:
    """Where a sweep's cases run: the scheduler (None: a local cluster of ``workers``), the
    line cache per worker [MiB] and the wait for workers [s] (:func:`run_sweep`)."""

    scheduler: Optional[str]
    workers: int
    line_cache_mb: float
    worker_wait_s: float
