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


# the longest list a catalog or sweep file holds: a sweep's axis (its values, checked again
# against the spec's own bound) or a catalog's table of parameters
MAX_LIST_ITEMS = 100_000


def _check_lists(text: str, path: Path, loader: Any) -> None:
    """Refuse a list of more than :data:`MAX_LIST_ITEMS` items from the YAML event stream,
    before any object is built: the parser stops at the item past the bound."""
    open_lists: list[int] = []  # items so far of every open list, innermost last; -1: a mapping
    for event in yaml.parse(text, Loader=loader):
        if isinstance(event, (yaml.ScalarEvent, yaml.SequenceStartEvent, yaml.MappingStartEvent)):
            if open_lists and open_lists[-1] >= 0:
                open_lists[-1] += 1
                if open_lists[-1] > MAX_LIST_ITEMS:
                    where = f"line {event.start_mark.line + 1}: " if event.start_mark is not None else ""
                    raise CatalogError(
                        f"{path}: {where}a list of more than {MAX_LIST_ITEMS:,} "
                        "items, more than any catalog or sweep holds (give an axis as start, stop, num); "
                        "nothing was built from it"
                    )
        if isinstance(event, yaml.SequenceStartEvent):
            open_lists.append(0)
        elif isinstance(event, yaml.MappingStartEvent):
            open_lists.append(-1)
        elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
            open_lists.pop()


def read_yaml_file(path: Path) -> Any:
    """Parse a YAML file, turning every way it can be unreadable into a :class:`CatalogError`
    that names the file; its size is checked before it is read and its lists' lengths before
    any object is built (:func:`_check_lists`)."""
    try:
        text = _read_capped(path).decode("utf-8")
    except UnicodeDecodeError as exc:
        raise CatalogError(f"{path}: not UTF-8 text (byte {exc.start}); save it as UTF-8") from None
    except OSError as exc:
        raise CatalogError(f"{path}: cannot be read ({exc.strerror})") from None
    # libyaml's parser when PyYAML was built with it: the same documents, 8× faster
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    try:
        _check_lists(text, path, loader)
        return yaml.load(text, Loader=loader)
    except yaml.YAMLError as exc:
        raise CatalogError(f"{path}: not valid YAML: {' '.join(str(exc).split())[:300]}") from None
    except RecursionError:
        raise CatalogError(f"{path}: nested too deeply to be a catalog or sweep file") from None
