"""Fenced writes: every object a cube's writer puts on object storage is a conditional write.

A check of the lease before a write is not a fence: a writer paused between the check and
its upload (a GC or VM pause, a stalled request) would land its object after another run took
the cube over. So the writer of a cube on object storage writes through a
:class:`FencedStore`, a zarr store in which every ``set`` is a conditional PUT:

- ``If-Match`` on the ETag the object had when this writer last looked (a listing taken
  right after the lease was confirmed, then the ETag of each of its own writes), and
- ``If-None-Match: *`` for an object that did not exist then.

A PUT whose condition fails raises :class:`ObjectChanged` and writes nothing; the writer then
confirms its lease (:meth:`ftsweep.store.lock.Lease.confirm`): a writer that lost it stops with
:class:`~ftsweep.store.lock.LeaseLost`, one that holds it merges again from what is there now.
What this guarantees, whatever the timing: a writer never replaces an object that anybody
changed after it read it, so no run's merged cases are ever overwritten by a stale copy. A
stale writer's PUT can still land on an object nobody touched since its listing; it then
holds that object's cases as they were plus the stale writer's own finished cases, exactly
what the new writer's merge of the same logs writes (merging is idempotent), and the new
writer's next PUT of that object, conditional on the ETag it listed, fails and is redone
from the object as it is. ETags of S3 single-part objects are the MD5 of their bytes, so an
object rewritten with the same bytes keeps its tag: the condition then compares contents,
which is what a read-modify-write needs.

``memory://`` (one process) gets the same semantics from a lock and a SHA-256 of the bytes.
Local folders need none of this: their lock is held by a live process and is never taken
over while that process exists (:mod:`ftsweep.store.lock`), and zarr's local store writes
each chunk to a temporary file renamed into place.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Any, Optional, cast

from zarr.core.buffer import Buffer
from zarr.storage import FsspecStore

from ftsweep.store import faultpoints
from ftsweep.store.lock import LockError
from ftsweep.store.storage import _MEMORY_SWAP, Place, precondition_failed


class ObjectChanged(LockError):
    """An object changed after this writer last looked at it: its conditional write failed and
    nothing was written. The writer confirms its lease before it writes again."""


def object_tags(where: Place, prefix: str = "") -> dict[str, str]:
    """Every object under ``where`` (relative key → tag): S3's ETag from one listing, the
    SHA-256 of the bytes on ``memory://``."""
    fs, root = where.fs()
    fs.invalidate_cache()
    base = where.key(prefix)
    try:
        found = fs.find(base, detail=True)
    except FileNotFoundError:
        return {}
    start = len(root.rstrip("/")) + 1
    tags: dict[str, str] = {}
    for path, info in found.items():
        key = str(path)[start:]
        # memory:// keeps no ETag: the place's own tag (a SHA-256 of the bytes) stands in
        tags[key] = (
            where.tag(key) if where.protocol == "memory" else str(info.get("ETag") or info.get("etag") or "")
        )
    return tags


class FencedStore(FsspecStore):
    """A zarr store on object storage whose every write is conditional (module description).
    Made by :func:`fenced_store`; ``fence`` is called before each PUT (the lease's own check
    of its age, a first line that spares requests bound to fail)."""

    place: Place
    tags: dict[str, str]
    fence: Callable[[], None]

    async def set(self, key: str, value: Buffer, byte_range: Optional[tuple[int, int]] = None) -> None:
        if byte_range:
            raise NotImplementedError
        self.fence()
        # off zarr's event loop, so a test may run another writer there
        if faultpoints.WRITE_POINT is not None:
            await asyncio.to_thread(faultpoints.WRITE_POINT, "before-put", key)
        data = value.to_bytes()
        tag = self.tags.get(key)
        if self.place.protocol == "memory":
            self.tags[key] = self._swap_memory(key, data, tag)
        else:
            path = f"{self.path.rstrip('/')}/{key}"
            condition: dict[str, Any] = {"mode": "create"} if tag is None else {"IfMatch": tag}
            try:
                out = await self.fs._pipe_file(path, data, **condition)
            except OSError as exc:
                if precondition_failed(exc):
                    raise ObjectChanged(self._changed(key)) from None
                raise
            etag = out.get("ETag") if isinstance(out, dict) else None
            self.tags[key] = str(etag) if etag else (await self.fs._info(path)).get("ETag", "")
        if faultpoints.WRITE_POINT is not None:
            await asyncio.to_thread(faultpoints.WRITE_POINT, "after-put", key)

    def _swap_memory(self, key: str, data: bytes, tag: Optional[str]) -> str:
        with _MEMORY_SWAP:  # memory:// lives in this process: a lock makes the swap atomic
            try:
                now: Optional[str] = self.place.tag(key)
            except FileNotFoundError:
                now = None
            if now != tag:
                raise ObjectChanged(self._changed(key))
            fs, _ = self.place.fs()
            fs.pipe_file(self.place.key(key), data)
        return self.place.tag(key)

    def _changed(self, key: str) -> str:
        return (
            f"{self.place}/{key} changed after this writer read it (another writer wrote it): "
            "nothing was written"
        )

    def with_read_only(self, read_only: bool = False) -> FsspecStore:
        other = super().with_read_only(read_only)
        if not read_only:  # zarr asks for a writable copy when it opens a group to write
            assert isinstance(other, FencedStore)
            other.place, other.fence, other.tags = self.place, self.fence, self.tags
        return other

    async def delete(self, key: str) -> None:
        self.fence()
        await super().delete(key)
        self.tags.pop(key, None)


def fenced_store(where: Place, fence: Callable[[], None]) -> FencedStore:
    """A :class:`FencedStore` on the cube at ``where`` (object storage), its tags listed now:
    call it right after the lease was confirmed."""
    store = cast(FencedStore, FencedStore.from_url(where.url, storage_options=where.options, read_only=False))
    store.place = where
    store.fence = fence
    store.tags = object_tags(where)
    return store
