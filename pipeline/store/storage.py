"""Where a cube lives: a local folder, or any fsspec URL (``s3://``, ``gs://``, ``abfs://``,
``memory://`` ...), behind one small set of operations the cube, its case logs and its lock
need: read, replace atomically, create only if absent, list, remove.

Storage options come from the usual places: the protocol's own (AWS_* variables and
``~/.aws`` for s3fs, ...), fsspec's configuration (``~/.config/fsspec/*.json`` and
``FSSPEC_<PROTOCOL>_<OPTION>`` variables, e.g. ``FSSPEC_S3_ENDPOINT_URL``), and options given
explicitly (``--storage-option KEY=VALUE``), which win. What the driver resolves travels with
a sweep's tasks to its workers (:func:`with_configured`: the endpoint, the region, fsspec's
configured options), credentials only when given explicitly: workers otherwise use their own.

Cubes are written where a writer's lock can be built (:data:`WRITABLE`): a folder, ``s3://``
(conditional writes) and ``memory://`` within one process; ``gs://`` and ``abfs://`` are read
but not written (their fsspec drivers expose no conditional write to build the lease on).
"""

from __future__ import annotations

import json
import os
import tempfile
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional, Union

from ftsweep.store.entries import regular_bytes

PathLike = Union[str, Path, "Place"]

_MEMORY_SWAP = threading.Lock()


class StorageError(ValueError):
    """A location cannot be used as asked; the message says what to do."""


# the protocols a sweep may write a cube to (a lock file, or a lease by conditional writes)
WRITABLE = ("file", "local", "s3", "s3a", "memory")
# option names that carry secrets: they travel to workers only when the user passed them
CREDENTIALS = frozenset(
    {
        "key",
        "secret",
        "token",
        "password",
        "account_key",
        "sas_token",
        "client_secret",
        "connection_string",
        "credentials",
        "anon_credentials",
    }
)


def is_url(text: Union[str, Path]) -> bool:
    """``scheme://...`` other than ``file://`` (those are plain paths)."""
    text = str(text)
    return "://" in text and not text.startswith("file://")


@dataclass(frozen=True)
class Place:
    """A cube's (or any stored object's) location: ``url`` is an absolute local path or a URL;
    ``options`` the explicit storage options (JSON text, so a Place travels to workers)."""

    url: str
    options_json: str = "{}"
    _cache: dict[str, Any] = field(default_factory=dict, compare=False, repr=False, hash=False)

    # ------------------------------------------------------------------ identity
    def __str__(self) -> str:
        return self.url

    @property
    def local(self) -> bool:
        return not is_url(self.url)

    @property
    def path(self) -> Path:
        """The local folder (only for a local place)."""
        if not self.local:
            raise StorageError(f"{self.url} is not a local path")
        return Path(self.url)

    @property
    def options(self) -> dict[str, Any]:
        return dict(json.loads(self.options_json))

    @property
    def protocol(self) -> str:
        return "file" if self.local else self.url.split("://", 1)[0]

    @property
    def name(self) -> str:
        return self.url.rstrip("/").rsplit("/", 1)[-1]

    def sibling(self, suffix: str) -> Place:
        """The place ``<this>`` + ``suffix`` beside it (a lock ``c.zarr.lock``)."""
        return Place(self.url.rstrip("/") + suffix, self.options_json)

    # ------------------------------------------------------------------ access
    def fs(self) -> tuple[Any, str]:
        """The fsspec filesystem and this place's path in it (cached per Place)."""
        if "fs" not in self._cache:
            import fsspec

            if self.local:
                self._cache["fs"] = (fsspec.filesystem("file"), self.url)
            else:
                try:
                    self._cache["fs"] = fsspec.core.url_to_fs(self.url, **self.options)
                except (ImportError, ValueError) as exc:
                    raise StorageError(
                        f"cannot reach {self.url}: {exc} (s3:// needs s3fs: pip install 'ftsweep[s3]')"
                    ) from None
        fs, root = self._cache["fs"]
        return fs, root

    def key(self, key: str) -> str:
        _, root = self.fs()
        return f"{root.rstrip('/')}/{key}" if key else root

    def zarr_store(self, read_only: bool = False) -> Any:
        """A zarr store on this place (zarr's own for a local folder, every entry checked to
        be a regular file before zarr reads it:
        :class:`ftsweep.store.regular.RegularLocalStore`)."""
        from zarr.storage import FsspecStore

        if self.local:
            from ftsweep.store.regular import RegularLocalStore

            return RegularLocalStore(self.url, read_only=read_only)
        # zarr runs its own event loop: it gets its own (asynchronous) filesystem instance,
        # never the one :meth:`fs` serves synchronous calls from
        return FsspecStore.from_url(self.url, storage_options=self.options, read_only=read_only)

    def exists(self, key: str = "") -> bool:
        fs, _ = self.fs()
        fs.invalidate_cache(self.key(key))  # another process may have written or deleted it
        return bool(fs.exists(self.key(key)))

    def read(self, key: str = "") -> bytes:
        """The object's bytes; FileNotFoundError if there is none (locally, a FIFO, device,
        socket or symbolic link is refused: :class:`~ftsweep.store.entries.SpecialEntry`, never read)."""
        if self.local:
            return regular_bytes(self.key(key))
        fs, _ = self.fs()
        return bytes(fs.cat_file(self.key(key)))

    def read_capped(self, key: str, cap: int) -> bytes:
        """The object's bytes if it holds at most ``cap`` (its size asked first, so a larger
        one is never downloaded); ValueError naming both sizes otherwise, and locally for a
        FIFO, device, socket or symbolic link (:class:`~ftsweep.store.entries.SpecialEntry`,
        never opened to read)."""
        if self.local:
            return regular_bytes(self.key(key), cap)
        fs, _ = self.fs()
        path = self.key(key)
        size = int(fs.size(path))
        if size > cap:
            raise ValueError(f"it holds {size:,} bytes, more than {cap:,}; it was not read")
        data = bytes(fs.cat_file(path))
        if len(data) > cap:  # replaced by a larger one in between
            raise ValueError(f"it grew past {cap:,} bytes while it was read; it was not used")
        return data

    def write(self, key: str, data: bytes) -> None:
        """Replace the object ``key`` whole: a reader sees the old bytes or the new, never a
        torn mix (a temporary file and a rename locally; one PUT on object storage)."""
        if self.local:
            target = Path(self.key(key))
            target.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", dir=target.parent)
            try:
                with os.fdopen(fd, "wb") as fh:
                    fh.write(data)
                os.replace(tmp, target)
            finally:
                Path(tmp).unlink(missing_ok=True)
            return
        fs, _ = self.fs()
        fs.pipe_file(self.key(key), data)

    def create(self, key: str, data: bytes) -> str:
        """Write ``key`` only if no object is there (FileExistsError otherwise), atomically:
        O_EXCL locally, a conditional PUT (If-None-Match) on object storage; returns its tag
        (:meth:`read_tagged`; empty locally). A store that cannot do that is refused by the
        caller (:mod:`ftsweep.store.lock`)."""
        if self.local:
            target = Path(self.key(key))
            target.parent.mkdir(parents=True, exist_ok=True)
            fd = os.open(target, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
            return ""
        fs, _ = self.fs()
        try:
            out = fs.pipe_file(self.key(key), data, mode="create")
        except OSError as exc:
            if precondition_failed(exc):
                raise FileExistsError(self.key(key)) from None
            raise
        etag = out.get("ETag") if isinstance(out, dict) else None
        return str(etag) if etag else self._tag(fs, self.key(key))

    # stores whose conditional writes a lock may rely on (create-if-absent and
    # compare-and-swap): S3 and its kin (If-None-Match / If-Match), and the in-process memory://
    CONDITIONAL = ("s3", "s3a", "memory")

    def read_tagged(self, key: str) -> tuple[bytes, str]:
        """The object's bytes and a tag that changes whenever it is replaced (S3's ETag).
        FileNotFoundError if there is none."""
        if self.local:
            return regular_bytes(self.key(key)), ""
        fs, _ = self.fs()
        path = self.key(key)
        for _ in range(5):
            before = self._tag(fs, path)
            data = bytes(fs.cat_file(path))
            if self._tag(fs, path) == before:  # not replaced while it was read
                return data, before
        raise StorageError(f"{self.url}/{key} keeps changing while it is read")

    def tag(self, key: str) -> str:
        """The tag of the object ``key`` (:meth:`read_tagged`); FileNotFoundError if there is none."""
        fs, _ = self.fs()
        return self._tag(fs, self.key(key))

    def _tag(self, fs: Any, path: str) -> str:
        if self.protocol == "memory":
            import hashlib

            return hashlib.sha256(bytes(fs.cat_file(path))).hexdigest()
        info = fs.info(path)
        return str(info.get("ETag") or info.get("etag") or info.get("LastModified"))

    def replace_if(self, key: str, data: bytes, tag: str) -> str:
        """Replace ``key`` only if it still carries ``tag`` (compare-and-swap: S3's If-Match);
        returns the new tag. FileExistsError if another writer replaced it first."""
        fs, _ = self.fs()
        path = self.key(key)
        if self.protocol == "memory":
            with _MEMORY_SWAP:  # memory:// lives in this process: a lock makes the swap atomic
                if self._tag(fs, path) != tag:
                    raise FileExistsError(path)
                fs.pipe_file(path, data)
                return self._tag(fs, path)
        try:
            out = fs.pipe_file(path, data, IfMatch=tag)
        except OSError as exc:
            if precondition_failed(exc):
                raise FileExistsError(path) from None
            raise
        etag = out.get("ETag") if isinstance(out, dict) else None
        return str(etag) if etag else self._tag(fs, path)

    def listing(self, prefix: str) -> list[str]:
        """Keys (relative to this place) of every object under ``prefix``."""
        fs, root = self.fs()
        base = self.key(prefix)
        # object stores' drivers cache listings (of every folder a find passed through):
        # other processes (workers) write here
        fs.invalidate_cache()
        try:
            found = fs.find(base)
        except FileNotFoundError:
            return []
        start = len(root.rstrip("/")) + 1
        return sorted(str(p)[start:] for p in found)

    def remove(self, key: str) -> None:
        """Delete one object (already gone is fine)."""
        fs, _ = self.fs()
        try:
            fs.rm_file(self.key(key))
        except FileNotFoundError:
            pass

    def remove_empty_folders(self, prefix: str) -> None:
        """Delete the empty folders under (and at) ``prefix`` of a local place (object
        storage has none)."""
        if not self.local:
            return
        top = Path(self.key(prefix))
        if not top.is_dir():
            return
        for folder in sorted((p for p in top.rglob("*") if p.is_dir()), reverse=True) + [top]:
            try:
                folder.rmdir()
            except OSError:  # not empty (a worker is logging into it)
                pass

    def remove_all(self) -> None:
        """Delete this place and everything under it."""
        fs, root = self.fs()
        try:
            fs.rm(root, recursive=True)
        except FileNotFoundError:
            pass


def precondition_failed(exc: BaseException) -> bool:
    """Whether a conditional write was refused because its condition failed (S3's 412
    Precondition Failed, which s3fs raises as an OSError naming it; FileExistsError from
    drivers that map it)."""
    text = str(exc).lower()
    return isinstance(exc, FileExistsError) or "pre-condition" in text or "precondition" in text


def place(where: PathLike, options: Optional[dict[str, Any]] = None) -> Place:
    """The :class:`Place` of a path or URL: local paths absolute (workers may run in another
    folder), ``file://`` URLs as paths, other URLs as given."""
    if isinstance(where, Place):
        return where if options is None else Place(where.url, json.dumps(options, sort_keys=True))
    text = str(where)
    if text.startswith("file://"):
        text = text[len("file://") :]
    if not is_url(text):
        text = str(Path(text).absolute())
    return Place(text, json.dumps(options or {}, sort_keys=True))


def parse_options(pairs: tuple[str, ...]) -> dict[str, Any]:
    """``KEY=VALUE`` pairs of ``--storage-option``: a value is JSON when it parses (numbers,
    true/false, objects), else the text itself."""
    options: dict[str, Any] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise StorageError(f"--storage-option takes KEY=VALUE, got {pair!r}")
        try:
            options[key] = json.loads(value)
        except ValueError:
            options[key] = value
    return options


def check_writable(where: Place) -> None:
    """Refuse, naming why, a place a sweep cannot write: a protocol without a writer's lock."""
    if where.protocol not in WRITABLE:
        raise StorageError(
            f"ftsweep writes cubes to a folder, s3:// or memory://, not {where.protocol}:// (its fsspec "
            "driver offers no conditional write to build a writer's lock on); write it to a folder or "
            "s3:// and copy it"
        )


def with_configured(where: Place) -> Place:
    """``where`` with what this process resolves for its protocol added to its options, so
    that workers elsewhere reach the same store: fsspec's configuration (files and
    ``FSSPEC_<PROTOCOL>_<OPTION>`` variables) and, for s3, the endpoint of
    ``AWS_ENDPOINT_URL_S3``/``AWS_ENDPOINT_URL`` and the region of ``AWS_REGION``/
    ``AWS_DEFAULT_REGION``. Explicit options win; credentials are never added (a worker uses
    its own unless they were passed explicitly)."""
    if where.local or where.protocol == "memory":
        return where
    import fsspec.config

    found = dict(fsspec.config.conf.get(where.protocol, {}))
    if where.protocol in ("s3", "s3a"):
        endpoint = os.environ.get("AWS_ENDPOINT_URL_S3") or os.environ.get("AWS_ENDPOINT_URL")
        region = os.environ.get("AWS_REGION") or os.environ.get("AWS_DEFAULT_REGION")
        if endpoint and "endpoint_url" not in found:
            found["endpoint_url"] = endpoint
        if region:
            kwargs = dict(found.get("client_kwargs") or {})
            kwargs.setdefault("region_name", region)
            found["client_kwargs"] = kwargs
    shared = {k: v for k, v in found.items() if k not in CREDENTIALS}
    return Place(where.url, json.dumps({**shared, **where.options}, sort_keys=True))


def reach_error(where: Place) -> Optional[str]:
    """None when this process reaches the cube at ``where`` (it exists and can be listed);
    else what went wrong, in one line. A worker runs it before any task is sent."""
    try:
        fs, path = where.fs()
        if not fs.exists(path):
            return f"{where.url} does not exist from this worker"
    except Exception as exc:  # any driver's error: it is reported, not raised on the worker
        return f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}"
    return None
