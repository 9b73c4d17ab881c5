"""A writer's lock beside a cube: one process writes a cube at a time.

On a local file system the lock is a small JSON file ``NAME.zarr.lock`` next to the cube,
created atomically and whole (written aside, then hard-linked into place) with the holder's
pid, host and start time. It is removed when the writer finishes or raises. A lock left by a
killed writer is stale: when its host is this machine and its pid no longer runs, the next
writer removes it and goes on. A lock held by a live process, or by another host (whose
processes cannot be seen from here), refuses the second writer with a message naming the
holder.

On object storage (``s3://``; ``memory://`` in one process) no pid can be checked, so the lock
object ``NAME.zarr.lock`` is a lease: created with a conditional write (If-None-Match: only
if absent), it names its owner and holds until ``lease_until``; the holder renews it every
:data:`LEASE_S`/3 seconds by compare-and-swap (If-Match on the tag it wrote). A second
writer is refused while the lease runs; once it expired (its holder was killed, or lost its
network for :data:`LEASE_S`), the next writer takes it over by the same compare-and-swap,
so of two that saw it expire exactly one wins. A holder whose renewal finds the lease taken
stops before it writes again (:class:`LockError`). Stores without such conditional writes
(``gs://``, ``abfs://`` through fsspec today) are refused for writing, naming why.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Optional

from ftsweep.store.storage import PathLike, Place, place


class LockError(RuntimeError):
    """Another live process writes the cube; the message names it."""


class LeaseLost(LockError):
    """This writer no longer holds its lease (taken over, or not confirmed in time): it
    must not write; the message says why."""


def lock_path(cube: PathLike) -> Path:
    """``NAME.zarr.lock`` beside a local ``NAME.zarr``."""
    at = place(cube)
    return at.path.with_name(at.path.name + ".lock")


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    return True


def read_holder(path: Path) -> dict[str, Any] | None:
    """The holder recorded in a lock file, or None if it is unreadable (being written or torn)."""
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _is_stale(holder: dict[str, Any] | None, path: Path) -> bool:
    if holder is None:
        # a lock file is written in one small write right after creation: if it is still
        # unreadable a few seconds later, its writer died in between
        try:
            return time.time() - path.stat().st_mtime > 5.0
        except OSError:
            return True
    if holder.get("host") != socket.gethostname():
        return False
    return not holder_alive(holder)


def holder_alive(holder: dict[str, Any]) -> bool:
    """Whether the process a lock's holder names runs on this machine (a holder without a
    usable pid does not)."""
    try:
        return _pid_alive(int(holder["pid"]))
    except (KeyError, TypeError, ValueError):
        return False


def _describe(holder: dict[str, Any] | None) -> str:
    if holder is None:
        return "a process that is starting"
    return (
        f"pid {holder.get('pid')} on {holder.get('host')} since {holder.get('started')} "
        f"({str(holder.get('command', ''))[:120]})"
    )


def _what_to_do(holder: dict[str, Any] | None, path: Path) -> str:
    """What the refused writer can do: a holder on this machine is alive (a dead one's lock is
    taken over), so wait; one on another host cannot be checked from here."""
    if holder is not None and holder.get("host") not in (None, socket.gethostname()):
        return (
            f"this machine cannot see {holder.get('host')}'s processes: wait for it to finish, or, if "
            f"that process is gone, delete {path}"
        )
    return "wait for it to finish (a lock whose process has ended is taken over by the next run)"


def _create(path: Path, text: str) -> None:
    """Put a lock file with ``text`` at ``path``, or raise FileExistsError if one is there.

    The record is written under a private name and hard-linked into place, so a second writer
    always reads a whole holder, never an empty file; a file system without hard links gets
    ``O_CREAT | O_EXCL`` and one small write instead."""
    spare = path.with_name(f"{path.name}.new-{os.getpid()}-{uuid.uuid4().hex[:8]}")
    _write_new(spare, text)
    try:
        os.link(spare, path)
    except FileExistsError:
        raise
    except OSError:
        _write_new(path, text)
    finally:
        spare.unlink(missing_ok=True)


def _write_new(path: Path, text: str) -> None:
    """Create ``path`` (FileExistsError if it is there) holding ``text``, readable by all and
    written by its owner (0o644, less what the umask takes), the lock's mode either way."""
    fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
    with os.fdopen(fd, "w") as fh:
        fh.write(text)


def acquire(cube: PathLike, command: str = "") -> Path:
    """Create the lock of a local ``cube`` or raise :class:`LockError`; a stale lock is
    replaced."""
    path = lock_path(cube)
    path.parent.mkdir(parents=True, exist_ok=True)
    record = {
        "pid": os.getpid(),
        "host": socket.gethostname(),
        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "command": command,
    }
    for _ in range(3):
        try:
            _create(path, json.dumps(record))
        except FileExistsError:
            holder = read_holder(path)
            if _is_stale(holder, path):
                # rename first so two processes that both saw the stale lock cannot both take it
                grave = path.with_name(f"{path.name}.stale-{os.getpid()}")
                try:
                    os.replace(path, grave)
                except FileNotFoundError:
                    continue
                if read_holder(grave) != holder:
                    # another process replaced the stale lock in between: put its live lock back
                    try:
                        os.link(grave, path)
                    except FileExistsError:
                        pass
                grave.unlink(missing_ok=True)
                continue
            raise LockError(
                f"{cube} is being written by {_describe(holder)}; {_what_to_do(holder, path)}"
            ) from None
        return path
    raise LockError(f"could not take the lock {path}: it keeps changing hands")


def release(path: Path) -> None:
    """Remove a lock this process holds (a lock taken over by another process is left alone)."""
    holder = read_holder(path)
    if holder is not None and holder.get("pid") == os.getpid() and holder.get("host") == socket.gethostname():
        path.unlink(missing_ok=True)


# how long a lease on object storage holds without renewal [s]; FTSWEEP_LOCK_LEASE_S sets
# another (shorter: a killed run's cube is free sooner; longer: slow networks)
LEASE_S = 60.0


# a block is written only within this fraction of the lease after its last confirmation: the
# rest of the term is the margin for clocks, the write itself and a slow store
FENCE_FRACTION = 0.5


def lease_seconds() -> float:
    """The lease: ``FTSWEEP_LOCK_LEASE_S`` if set (a positive number of seconds), else :data:`LEASE_S`."""
    text = os.environ.get("FTSWEEP_LOCK_LEASE_S")
    if text is None:
        return LEASE_S
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0 or value == float("inf"):
        raise LockError(f"FTSWEEP_LOCK_LEASE_S must be a positive number of seconds, got {text!r}")
    return value


class Lease:
    """The writer's lease on a cube in object storage (see the module's description)."""

    def __init__(
        self,
        cube: PathLike,
        command: str = "",
        lease_s: Optional[float] = None,
        run_id: str = "",
        fence_run: Optional[Callable[[str], frozenset[str]]] = None,
    ) -> None:
        self.cube = place(cube)
        self.run_id = run_id
        self.fence_run = fence_run
        # the case logs of the run this writer took the cube over from, as they were before
        # the takeover: the only ones of that run ever read (ftsweep.store.caselog)
        self.inherited: frozenset[str] = frozenset()
        self.lock = self.cube.sibling(".lock")
        if self.lock.protocol not in Place.CONDITIONAL:
            raise LockError(
                f"ftsweep cannot lock a cube on {self.lock.protocol}:// (its fsspec driver offers no "
                "conditional writes to build a writer's lock on); write the cube to a local or shared "
                "folder or to s3://, then copy it"
            )
        self.lease_s = lease_s or lease_seconds()
        self.token = uuid.uuid4().hex
        self.command = command
        self.tag = ""
        self.lost: Optional[str] = None
        # when the lease was last confirmed by a conditional write [time.monotonic() s]
        self.confirmed = 0.0
        self._mutex = threading.Lock()  # one conditional write at a time (renewer, confirm)
        self._stop = threading.Event()
        self._renewer: Optional[threading.Thread] = None

    def _record(self) -> bytes:
        return json.dumps(
            {
                "owner": self.token,
                "pid": os.getpid(),
                "host": socket.gethostname(),
                "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
                "command": self.command,
                "run_id": self.run_id,
                "lease_until": time.time() + self.lease_s,
            }
        ).encode()

    def acquire(self) -> None:
        """Take the lease, or raise :class:`LockError` naming the holder of a running one."""
        for _ in range(3):
            try:
                self.tag = self.lock.create("", self._record())
                break
            except FileExistsError:
                pass
            try:
                data, tag = self.lock.read_tagged("")
            except FileNotFoundError:
                continue  # released in between: try again
            holder = _parse(data)
            until = float(holder.get("lease_until", 0)) if holder else 0.0
            if until > time.time():
                raise LockError(
                    f"{self.cube} is being written by {_describe(holder)} (lease until "
                    f"{time.strftime('%H:%M:%S', time.localtime(until))}); wait for it to finish, or, "
                    f"if that run is gone, for its lease to expire (at most {self.lease_s:g} s)"
                )
            inherited = self._fence_run(holder)
            try:
                self.tag = self.lock.replace_if("", self._record(), tag)
                self.inherited = inherited
                break
            except FileExistsError:
                continue  # another writer took the expired lease first
        else:
            raise LockError(f"could not take the lock {self.lock}: it keeps changing hands")
        self.confirmed = time.monotonic()
        self._renewer = threading.Thread(target=self._renew, name="ftsweep-lease", daemon=True)
        self._renewer.start()

    def _fence_run(self, holder: Optional[dict[str, Any]]) -> frozenset[str]:
        """Before taking over an expired lease: ``fence_run`` of the run its holder names,
        which lists the case logs that run wrote so far (the only ones of it this writer will
        read) and marks it fenced, so that no log it writes from now on is ever read
        (:func:`ftsweep.store.caselog.fence_run`)."""
        run = str((holder or {}).get("run_id") or "")
        return self.fence_run(run) if run and self.fence_run is not None else frozenset()

    def _swap(self) -> None:
        """Renew the lease by compare-and-swap on the tag this writer last wrote (the lock
        object's ETag): it succeeds only if nobody wrote the lock since. FileExistsError when
        another writer did, or deleted the lock (``lost`` is set)."""
        with self._mutex:
            if self.lost:
                raise FileExistsError(self.lost)
            # the new term counts from before the request: a slow request only shortens it
            sent = time.monotonic()
            try:
                self.tag = self.lock.replace_if("", self._record(), self.tag)
            except FileExistsError:
                self.lost = f"the lease on {self.cube} was taken over by another writer"
                raise
            except FileNotFoundError:  # another writer took it over and has released it since
                self.lost = f"the lease on {self.cube} was taken over (its lock object is gone)"
                raise FileExistsError(self.lost) from None
            self.confirmed = sent

    def _renew(self) -> None:
        while not self._stop.wait(self.lease_s / 3.0):
            try:
                self._swap()
            except FileExistsError:
                return
            except Exception as exc:  # noqa: BLE001 - a network error: try again next period
                if time.monotonic() - self.confirmed >= self.lease_s:  # it may have expired
                    self.lost = (
                        f"the lease on {self.cube} could not be renewed for {self.lease_s:g} s ({exc})"
                    )
                    return

    def check(self) -> None:
        """Raise :class:`LeaseLost` if this writer is known to have lost the lease."""
        if self.lost:
            raise LeaseLost(f"{self.lost}; this run stops and writes nothing more (finished cases are kept)")

    def confirm(self) -> None:
        """Confirm the lease now by a conditional write on the lock object (before a merge):
        :class:`LeaseLost` if another writer holds it, or if the write fails (this writer
        cannot know that it still holds it)."""
        self.check()
        try:
            self._swap()
        except FileExistsError:
            self.check()
        except Exception as exc:  # noqa: BLE001 - a network error: not confirmed, so no write
            raise LeaseLost(
                f"the lease on {self.cube} could not be confirmed ({str(exc)[:120]}); this run stops and "
                "writes nothing more (finished cases are kept)"
            ) from None

    def fence(self) -> None:
        """Raise :class:`LeaseLost` unless the lease was confirmed well inside its term
        (within :data:`FENCE_FRACTION` of it): called right before each block write, so a
        writer paused (stopped, swapped out) after its confirmation never writes on an
        expired lease another writer may hold."""
        self.check()
        age = time.monotonic() - self.confirmed
        if age > FENCE_FRACTION * self.lease_s:
            raise LeaseLost(
                f"the lease on {self.cube} was last confirmed {age:.1f} s ago, more than "
                f"{FENCE_FRACTION:g} of its {self.lease_s:g} s term: another writer may hold it now; this "
                "run stops and writes nothing more (finished cases are kept)"
            )

    def release(self) -> None:
        """Stop renewing and delete the lease if it is still this writer's."""
        self._stop.set()
        if self._renewer is not None:
            self._renewer.join(timeout=10)
        try:
            data, _ = self.lock.read_tagged("")
        except FileNotFoundError:
            return
        holder = _parse(data)
        if holder is not None and holder.get("owner") == self.token:
            self.lock.remove("")


def _parse(data: bytes) -> Optional[dict[str, Any]]:
    try:
        holder = json.loads(data)
    except ValueError:
        return None
    return holder if isinstance(holder, dict) else None


@contextmanager
def cube_lock(
    cube: PathLike,
    command: str = "",
    run_id: str = "",
    fence_run: Optional[Callable[[str], frozenset[str]]] = None,
) -> Iterator[Optional[Lease]]:
    """Hold the writer's lock of ``cube`` (a local folder: a lock file; object storage: a
    :class:`Lease`, yielded so the writer can :meth:`Lease.check` it) for the ``with`` block,
    released on any exit, and on SIGTERM, which batch schedulers send to end a job
    (:func:`terminate_as_exit`)."""
    at = place(cube)
    if at.local:
        path = acquire(at.path, command)
        try:
            with terminate_as_exit():
                yield None
        finally:
            release(path)
        return
    lease = Lease(at, command, run_id=run_id, fence_run=fence_run)
    lease.acquire()
    try:
        with terminate_as_exit():
            yield lease
    finally:
        lease.release()


@contextmanager
def terminate_as_exit() -> Iterator[None]:
    """Within the block, SIGTERM (and SIGHUP) raise :class:`SystemExit` with status 128 + the
    signal, as SIGINT raises KeyboardInterrupt, so that every ``finally`` runs: the lock is
    released and the cluster closed. Python's default ends the process at once, leaving the
    lock behind. Only in the main thread (where Python delivers signals); elsewhere a no-op."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def leave(signum: int, frame: Any) -> None:
        raise SystemExit(128 + signum)

    previous = {sig: signal.signal(sig, leave) for sig in (signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
