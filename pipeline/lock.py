"""A writer's lock beside a cube: one process writes a cube at a time.

The lock is a small JSON file ``NAME.zarr.lock`` next to the cube, created atomically
(``O_CREAT | O_EXCL``) with the holder's pid, host and start time. It is removed when the
writer finishes or raises. A lock left by a killed writer is stale: when its host is this
machine and its pid no longer runs, the next writer removes it and goes on. A lock held by a
live process, or by another host (whose processes cannot be seen from here), refuses the
second writer with a message naming the holder.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any


class LockError(RuntimeError):
    """Another live process writes the cube; the message names it."""


def lock_path(cube: Path) -> Path:
    """``NAME.zarr.lock`` beside ``NAME.zarr``."""
    cube = Path(cube)
    return cube.with_name(cube.name + ".lock")


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
    try:
        return not _pid_alive(int(holder["pid"]))
    except (KeyError, TypeError, ValueError):
        return True


def _describe(holder: dict[str, Any] | None) -> str:
    if holder is None:
        return "a process that is starting"
    return (
        f"pid {holder.get('pid')} on {holder.get('host')} since {holder.get('started')} "
        f"({str(holder.get('command', ''))[:120]})"
    )


def acquire(cube: Path, command: str = "") -> Path:
    """Create the lock of ``cube`` or raise :class:`LockError`; a stale lock is replaced."""
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
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
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
                f"{cube} is being written by {_describe(holder)}; wait for it to finish, or, if "
                f"that process is gone, delete {path}"
            ) from None
        with os.fdopen(fd, "w") as fh:
            fh.write(json.dumps(record))
        return path
    raise LockError(f"could not take the lock {path}: it keeps changing hands")


def release(path: Path) -> None:
    """Remove a lock this process holds (a lock taken over by another process is left alone)."""
    holder = read_holder(path)
    if holder is not None and holder.get("pid") == os.getpid() and holder.get("host") == socket.gethostname():
        path.unlink(missing_ok=True)


@contextmanager
def cube_lock(cube: Path, command: str = "") -> Iterator[Path]:
    """Hold the writer's lock of ``cube`` for the ``with`` block (released on any exit, and on
    SIGTERM, which batch schedulers send to end a job: :func:`terminate_as_exit`)."""
    path = acquire(cube, command)
    try:
        with terminate_as_exit():
            yield path
    finally:
        release(path)


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
