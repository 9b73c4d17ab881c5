"""A machine's first compile: whether numba's cache holds this install's kernels, and how long
the first run that compiled them took (docs/performance.md, "A first run's compile").

Kernels are compiled once per machine: numba's cache (``cache=True`` on every kernel of
:mod:`ftsweep.stages`, in the user's cache directory: :mod:`ftsweep.caches`) keeps them for
every later process. A sweep's workers that find the cache empty compile side by side, each
its own copy (numba writes its cache files atomically, so the last one written stands); the
time it took is recorded so that the next first run's notice can say what to expect.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from pathlib import Path


def kernels_cached() -> bool:
    """Whether numba's cache holds this install's compiled kernels already (a run then starts
    at once): the index files of the envelope stage (``ftsweep.stages.envelope.arcs``) in the
    folder numba's ``UserProvidedCacheLocator`` gives its source under ``NUMBA_CACHE_DIR``
    (:mod:`ftsweep.caches`), so another install's kernels in the same cache do not count."""
    from numba.core.caching import UserProvidedCacheLocator

    import ftsweep.stages
    from ftsweep.caches import numba_cache_dir

    source = Path(ftsweep.stages.__file__).resolve().parent / "envelope" / "arcs.py"
    root = numba_cache_dir() / UserProvidedCacheLocator.get_suitable_cache_subpath(str(source))
    return root.is_dir() and any(root.glob("arcs.*.nbi"))


@contextlib.contextmanager
def recorded_first_compile() -> Iterator[None]:
    """Around a process's first case: where numba's cache held no kernels of this install
    before it, the seconds the block took (the compile, then the case) are recorded as this
    machine's first compile (:func:`ftsweep.caches.record_compile_s`), the figure the next
    first run's notice gives; elsewhere nothing."""
    from ftsweep.caches import record_compile_s

    if kernels_cached():
        yield
        return
    started = time.perf_counter()
    yield
    record_compile_s(time.perf_counter() - started)
