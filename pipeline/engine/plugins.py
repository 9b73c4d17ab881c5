"""Where the program kinds are found (docs/architecture.md, "The program-kind contract").

Kinds are found the way xarray finds its backends: through the entry points of group
``ftsweep.kinds``, each naming one :class:`~ftsweep.engine.contract.ProgramKind` value
(``ring = "ftsweep.kinds.table.kind:RING"`` in ``pyproject.toml``), so a package outside this
repository adds a kind by declaring its own entry point; :func:`register` adds one at run time
(a notebook, a test). Loading an entry point is not an import of this module's: the kinds
import the engine, and the engine reaches them only here, by name, so every import still
points down. :mod:`ftsweep.registry` is the public face, with the vocabularies built from
every kind.
"""

from __future__ import annotations

import functools
from importlib.metadata import entry_points
from typing import Any

from ftsweep.engine.contract import ProgramKind

__all__ = [
    "GROUP",
    "RegistryError",
    "added",
    "kind",
    "kinds",
    "names",
    "noun",
    "owners",
    "register",
    "unregister",
]

GROUP = "ftsweep.kinds"
_added: dict[str, ProgramKind] = {}


class RegistryError(ValueError):
    """An entry point of group ``ftsweep.kinds`` that does not name a program kind."""


@functools.cache
def _points() -> dict[str, Any]:
    """The installed kinds' entry points by name, not loaded (the first of a name wins, as
    when every kind is loaded)."""
    found: dict[str, Any] = {}
    for point in entry_points(group=GROUP):
        found.setdefault(point.name, point)
    return found


@functools.cache
def _load(name: str) -> ProgramKind:
    """The installed kind ``name``, its entry point loaded and checked (RegistryError naming a
    broken one); loaded once per process, and only when asked for, so a case imports no other
    kind's planner, kernels or request model."""
    point = _points()[name]
    try:
        value = point.load()
    except Exception as exc:  # a broken plug-in names itself, not a bare ImportError
        raise RegistryError(f"program kind {point.name!r} ({point.value}) cannot be loaded: {exc}") from exc
    if not isinstance(value, ProgramKind):
        raise RegistryError(f"entry point {point.name!r} ({point.value}) is not a ProgramKind")
    if value.name != point.name:
        raise RegistryError(f"entry point {point.name!r} names the kind {value.name!r}")
    return value


def _installed() -> dict[str, ProgramKind]:
    return {name: _load(name) for name in _points()}


def kinds() -> dict[str, ProgramKind]:
    """Every program kind by name: the installed ones (in their entry points' order), then
    those registered."""
    return {**_installed(), **_added}


def register(kind: ProgramKind) -> ProgramKind:
    """Add ``kind`` for this process (ValueError if its name is taken by another value)."""
    known = kinds().get(kind.name)
    if known is not None and known is not kind:
        raise ValueError(f"a program kind named {kind.name!r} is registered already")
    _added[kind.name] = kind
    return kind


def added() -> dict[str, ProgramKind]:
    """The kinds :func:`register` added in this process (not the installed ones)."""
    return dict(_added)


def unregister(name: str) -> None:
    """Remove a kind :func:`register` added (installed kinds stay)."""
    _added.pop(name, None)


def kind(name: Any) -> ProgramKind:
    """The registered kind ``name`` (ValueError naming the known ones); of the installed kinds,
    only that one is loaded."""
    if name in _added:
        return _added[name]
    if isinstance(name, str) and name in _points():
        return _load(name)
    raise ValueError(f"unknown program kind {name!r}; known: {', '.join(names())}")


def names() -> tuple[str, ...]:
    """The registered kinds' names, for command-line choices and messages: read from the
    entry points without loading them (the command line starts without the kinds' kernels)."""
    return tuple(dict.fromkeys([*(p.name for p in entry_points(group=GROUP)), *_added]))


def noun(name: Any) -> str:
    """What a program of kind ``name`` is called in messages (``ring layout``)."""
    known = kinds()
    return known[name].noun if name in known else f"{name} program"


def owners(field: str) -> str:
    """Which kinds' requests have ``field``, for the message refusing it elsewhere."""
    found = [k for k in kinds().values() if field in k.request.model_fields]  # type: ignore[attr-defined]
    if not found:
        return "no program kind has it"
    return f"{field} belongs to " + " or ".join(f"{k.noun}s" for k in found)
