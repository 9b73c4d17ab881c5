"""Threads of one case (``--threads``): how many the cases simulated in a context may use,
and the one way work is split over them.

The numba kernels release the GIL, so a case's independent parts (batches of lines, parts
of a table or a path to compensate) run side by side on threads of one process. Every split
keeps the order of the results, so a case's record is the same value for value whatever
the number of threads. A sweep's workers keep one thread per case: they run cases side by
side instead.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Optional

import numpy as np

# threads of every case run in this context that does not give its own (``run_case(threads=)``):
# the commands that simulate one case at a time (predict, verify, dpath, fresnel) set it
THREADS: ContextVar[int] = ContextVar("ftsweep_case_threads", default=1)

# fewest points per part when compensating on threads: smaller parts would spend more on
# numpy's per-call overhead than they gain
PART_POINTS = 50_000
# most points per part, on any number of threads: a part's dozen solver temporaries (0.5 MB
# each) then stay in cache instead of streaming through memory (docs/performance.md,
# "Tuned constants")
MAX_PART_POINTS = 65_536
# most points per part when threads share the work: with parts of MAX_PART_POINTS each thread
# runs Python between numpy calls so often that the threads queue for the GIL
THREAD_PART_POINTS = 1_048_576


def current(threads: Optional[int] = None) -> int:
    """``threads`` if given, else the context's (:func:`using_threads`); refuses fewer than one."""
    n = THREADS.get() if threads is None else threads
    if n < 1:
        raise ValueError(f"threads must be at least 1, got {n}")
    return n


@contextmanager
def using_threads(threads: int) -> Iterator[None]:
    """Run the cases simulated inside the ``with`` block on ``threads`` threads each."""
    token = THREADS.set(current(threads))
    try:
        yield
    finally:
        THREADS.reset(token)


def compensate_in_parts(
    solve: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
    rho: np.ndarray,
    theta: np.ndarray,
    threads: Optional[int] = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``solve(rho, theta) -> (w, gouge)`` (a compensation, model §4, whose points are each
    solved on their own) over equal-shape arrays: one share per thread of the context
    (shares of at least :data:`PART_POINTS`), each solved in parts of at most
    :data:`THREAD_PART_POINTS` (one thread: :data:`MAX_PART_POINTS`); the same arrays as one
    call, bit for bit."""
    n = current(threads)
    shares = max(1, min(n, rho.size // PART_POINTS))
    flat_rho, flat_theta = np.ravel(rho), np.ravel(theta)
    if shares == 1 and rho.size <= MAX_PART_POINTS:
        return solve(rho, theta)
    largest = MAX_PART_POINTS if shares == 1 else THREAD_PART_POINTS

    def share(bounds: tuple[int, int]) -> list[tuple[np.ndarray, np.ndarray]]:
        lo, hi = bounds
        cuts = np.linspace(lo, hi, -(-(hi - lo) // largest) + 1).astype(np.int64)
        return [solve(flat_rho[a:b], flat_theta[a:b]) for a, b in zip(cuts[:-1], cuts[1:], strict=True)]

    edges = np.linspace(0, rho.size, shares + 1).astype(np.int64)
    spans = list(zip(edges[:-1], edges[1:], strict=True))
    if shares == 1:
        done = share(spans[0])
    else:
        with ThreadPoolExecutor(shares, thread_name_prefix="ftsweep-compensate") as pool:
            done = [part for parts in pool.map(share, spans) for part in parts]
    w = np.concatenate([d[0] for d in done]).reshape(np.shape(rho))
    return w, np.concatenate([d[1] for d in done]).reshape(np.shape(rho))
