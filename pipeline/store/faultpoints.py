"""The write points of a cube's writers and of its workers' case logs, where fault-injection
tests pause or kill a run (architecture.md, "Fault injection").

A module of its own, importing nothing, because workers reach it too: a worker logging a case
must not load the store's zarr machinery to offer a test its point.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Optional

# the hook, called with (event, key): "before-var"/"after-var" around each variable's blocks
# (ftsweep.store.cube.CubeWriter), "before-put"/"after-put" around each object a fenced store
# puts, "commit" once a merge's logs are deleted, and "logged" once a worker's case log holds
# one more case; None outside tests
WRITE_POINT: Optional[Callable[[str, str], None]] = None


def write_point(event: str, key: str) -> None:
    """Call :data:`WRITE_POINT`, if a test set one."""
    if WRITE_POINT is not None:
        WRITE_POINT(event, key)
