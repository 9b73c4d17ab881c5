"""A local cube as zarr reads it, every entry checked to be a regular file first: a FIFO,
device, socket or symbolic link among a cube's blocks is refused in an instant, naming it
(:class:`ftsweep.store.entries.SpecialEntry`), instead of blocking or redirecting the read.
Imported only where a zarr store is opened (workers that log cases never import zarr)."""

from __future__ import annotations

import asyncio
from typing import Any

from zarr.storage import LocalStore

from ftsweep.store.entries import check_entry


class RegularLocalStore(LocalStore):
    """zarr's :class:`~zarr.storage.LocalStore` whose reads check the entry first
    (:func:`ftsweep.store.entries.check_entry`: opened without blocking or following a link,
    judged by ``fstat``). Between the check and zarr's own open a swapped entry is not seen:
    the check guards against what lies in a cube, not against a race with a local attacker."""

    async def get(self, key: str, prototype: Any = None, byte_range: Any = None) -> Any:
        await asyncio.to_thread(check_entry, self.root / key)
        return await super().get(key, prototype, byte_range)
