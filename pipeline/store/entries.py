"""Entries of a local store read as untrusted: opened without blocking or following a
symbolic link and judged by ``fstat`` of the open descriptor, so a FIFO, device, socket or
link placed in a cube can neither block nor redirect a reader (docs/architecture.md "Bounds
on every input"). No zarr here: the workers that log cases import this too."""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path
from typing import Optional


class SpecialEntry(ValueError):
    """An entry of a local store that is not a regular file (a FIFO, device, socket or
    symbolic link): never opened to read, so it can neither block nor redirect a reader."""


def regular_bytes(path: str, cap: Optional[int] = None) -> bytes:
    """The bytes of the regular file ``path`` inside a store, opened without following a
    symbolic link and without blocking (``O_NOFOLLOW | O_NONBLOCK``) and judged by ``fstat`` of
    the open descriptor: a FIFO, device, socket or link raises :class:`SpecialEntry` at once;
    more than ``cap`` bytes a ValueError naming both sizes; FileNotFoundError if absent."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW | getattr(os, "O_NOCTTY", 0))
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise SpecialEntry(
                f"{path} is a symbolic link, not a file ftsweep writes; it was not followed"
            ) from None
        if exc.errno == errno.ENXIO:  # a socket cannot be opened as a file
            raise SpecialEntry(f"{path} is a socket, not a file ftsweep writes; nothing was read") from None
        raise
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            kind = "a directory" if stat.S_ISDIR(info.st_mode) else "a FIFO, device or socket"
            raise SpecialEntry(f"{path} is {kind}, not a file ftsweep writes; nothing was read")
        if cap is not None and info.st_size > cap:
            raise ValueError(f"it holds {info.st_size:,} bytes, more than {cap:,}; it was not read")
        with os.fdopen(fd, "rb") as fh:
            fd = -1
            data = fh.read() if cap is None else fh.read(cap + 1)
    finally:
        if fd >= 0:
            os.close(fd)
    if cap is not None and len(data) > cap:  # grew while it was read
        raise ValueError(f"it grew past {cap:,} bytes while it was read; it was not used")
    return data


def check_entry(path: Path) -> None:
    """Refuse (:class:`SpecialEntry`) an entry that is not a regular file, without blocking on
    it or following it; an absent one is left to the store (zarr reads it as missing)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW | getattr(os, "O_NOCTTY", 0))
    except FileNotFoundError:
        return
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise SpecialEntry(f"{path} is a symbolic link, not a block ftsweep writes") from None
        if exc.errno == errno.ENXIO:
            raise SpecialEntry(f"{path} is a socket, not a block ftsweep writes") from None
        if exc.errno in (errno.EISDIR, errno.ENOTDIR):
            return
        raise
    try:
        mode = os.fstat(fd).st_mode
    finally:
        os.close(fd)
    if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        raise SpecialEntry(f"{path} is a FIFO, device or socket, not a block ftsweep writes")
