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
# each) then stay in cache instead of streaming through memory. One thread, measured: ring-1M's
# table 0.27 -> 0.22 s; the 990k-point chord spiral's 28 M dense points 20.6 -> 13.5 s
MAX_PART_POINTS = 65_536


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
    solved on their own) over equal-shape arrays, in parts of at most
    :data:`MAX_PART_POINTS` on the context's threads; the same arrays as one call, bit for
    bit."""
    n = current(threads)
    n_parts = min(4 * n, rho.size // PART_POINTS) if n > 1 else 1
    n_parts = max(n_parts, -(-rho.size // MAX_PART_POINTS))
    if n_parts < 2:
        return solve(rho, theta)
    rho_parts = np.array_split(np.ravel(rho), n_parts)
    theta_parts = np.array_split(np.ravel(theta), n_parts)
    if n == 1:
        done = [solve(r, t) for r, t in zip(rho_parts, theta_parts, strict=True)]
    else:
        with ThreadPoolExecutor(n, thread_name_prefix="ftsweep-compensate") as pool:
            done = list(pool.map(solve, rho_parts, theta_parts))
    w = np.concatenate([d[0] for d in done]).reshape(np.shape(rho))
    return w, np.concatenate([d[1] for d in done]).reshape(np.shape(rho))
