"""Catalog and sweep files read as untrusted text: a regular file within a size cap, UTF-8,
YAML by the safe loader; every way it can be unreadable a :class:`CatalogError` naming it."""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Any

import yaml


class CatalogError(ValueError):
    """A catalog file or entry is missing or invalid; the message says what to change."""


# the largest catalog or sweep file read: the shipped catalogs together are ~100 KB
MAX_YAML_BYTES = 16 * 2**20


def _read_capped(path: Path) -> bytes:
    """The bytes of a regular file of at most :data:`MAX_YAML_BYTES`, judged by ``fstat`` of
    the open descriptor before any read (a device or FIFO is never read)."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    with os.fdopen(fd, "rb") as fh:
        info = os.fstat(fh.fileno())
        if not stat.S_ISREG(info.st_mode):
            raise CatalogError(f"{path} is not a regular file; nothing was read")
        if info.st_size > MAX_YAML_BYTES:
            raise CatalogError(
                f"{path} holds {info.st_size:,} bytes, more than any catalog or sweep file "
                f"({MAX_YAML_BYTES:,}); nothing was read"
            )
        return fh.read(MAX_YAML_BYTES + 1)[:MAX_YAML_BYTES]


def read_yaml_file(path: Path) -> Any:
    """Parse a YAML file, turning every way it can be unreadable into a :class:`CatalogError`
    that names the file."""
    try:
        text = _read_capped(path).decode("utf-8")
    except UnicodeDecodeError as exc:
        raise CatalogError(f"{path}: not UTF-8 text (byte {exc.start}); save it as UTF-8") from None
    except OSError as exc:
        raise CatalogError(f"{path}: cannot be read ({exc.strerror})") from None
    try:
        # libyaml's parser when PyYAML was built with it: the same documents, 8× faster
        return yaml.load(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    except yaml.YAMLError as exc:
        raise CatalogError(f"{path}: not valid YAML: {' '.join(str(exc).split())[:300]}") from None
    except RecursionError:
        raise CatalogError(f"{path}: nested too deeply to be a catalog or sweep file") from None
