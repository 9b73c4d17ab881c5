"""The conformance suite of a writer's lease (docs/architecture.md, "Trust": a writer holds
its lease at the moment it writes, or it does not write): on a place that supports
conditional writes, a second writer is refused while the first renews its lease, a lease
that runs out is taken over once, and the old holder's compare-and-swap then fails and its
next check says it was taken over. Subclass :class:`LeaseTests` with a ``url`` fixture naming
a fresh cube location of your store (``memory://``, ``s3://`` on a test server).
"""

from __future__ import annotations

import time

import pytest

from ftsweep.store.lock import Lease, LockError
from ftsweep.store.storage import place

__all__ = ["LeaseTests"]


class LeaseTests:
    """Every place a sweep may lock passes these; subclasses provide the ``url`` fixture."""

    # lease seconds (renewed every third of it): slack for a loaded 2-core machine
    lease_s = 1.5

    @pytest.fixture
    def url(self) -> str:  # pragma: no cover - every subclass names its own store
        raise NotImplementedError("a LeaseTests subclass provides the url fixture")

    def _stop(self, lease: Lease) -> None:
        """The holder pauses or dies without releasing: its renewals stop."""
        lease._stop.set()
        assert lease._renewer is not None
        lease._renewer.join()

    def test_a_second_writer_is_refused_while_the_first_renews(self, url: str) -> None:
        first = Lease(url, "first", lease_s=self.lease_s)
        first.acquire()
        try:
            with pytest.raises(LockError, match="is being written by pid .*lease until"):
                Lease(url, "second", lease_s=self.lease_s).acquire()
            time.sleep(self.lease_s + 0.5)  # past its first lease: held only because it was renewed
            with pytest.raises(LockError):
                Lease(url, "third", lease_s=self.lease_s).acquire()
            first.check()
        finally:
            first.release()
        assert not place(url + ".lock").exists()

    def test_a_lease_that_ran_out_is_taken_over_and_the_old_holder_cannot_write(self, url: str) -> None:
        first = Lease(url, "first", lease_s=self.lease_s)
        first.acquire()
        self._stop(first)
        time.sleep(self.lease_s + 0.2)
        taker = Lease(url, "after", lease_s=self.lease_s)
        taker.acquire()
        try:
            with pytest.raises(FileExistsError):  # the old holder's compare-and-swap now fails
                place(url + ".lock").replace_if("", b"{}", first.tag)
            with pytest.raises(LockError, match="taken over"):
                first.confirm()
        finally:
            taker.release()
        assert not place(url + ".lock").exists()
