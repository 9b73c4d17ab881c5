"""Conformance suites a package outside ftsweep reuses, as zarr ships ``zarr.testing``:
:class:`KindTests` for a program kind (plan, simulate, export, verify, resume) and
:class:`LeaseTests` for a place that holds a sweep's writer lease. Subclass one in your own
tests; pytest runs every test of it. They need pytest (the ``test`` extra).
"""

from __future__ import annotations

from ftsweep.testing.kinds import KindTests
from ftsweep.testing.lease import LeaseTests

__all__ = ["KindTests", "LeaseTests"]
