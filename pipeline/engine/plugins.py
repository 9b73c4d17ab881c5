"""Where the program kinds are found (docs/architecture.md, "The program-kind contract").

Kinds are found the way xarray finds its backends: through the entry points of group
``ftsweep.kinds``, each naming one subclass of :class:`~ftsweep.engine.contract.ProgramKind`
(``ring = "ftsweep.kinds.table:RingKind"`` in ``pyproject.toml``), of which one instance is
made, so a package outside this repository adds a kind by declaring its own entry point; a
broken one (it cannot be imported, is no kind, leaves a required attribute unset or names
another kind) is warned about and skipped, as xarray does with a broken backend.
:func:`register` adds a kind at run time (a notebook, a test). Loading an entry point is
not an import of this module's: the kinds import the engine, and the engine reaches them
only here, by name, so every import still points down. :mod:`ftsweep.registry` is the
public face, with the vocabularies built from every kind.
"""

from __future__ import annotations

import functools
import inspect
import warnings
from importlib.metadata import entry_points
from typing import Any, Optional

from ftsweep.engine.contract import ProgramKind, unset_attributes

__all__ = [
    "GROUP",
    "BrokenKindWarning",
    "RegistryError",
    "added",
    "checked",
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
    """An entry point of group ``ftsweep.kinds`` that does not name a usable program kind."""


class BrokenKindWarning(UserWarning):
    """An installed kind skipped: the warning says which entry point and why."""


@functools.cache
def _points() -> dict[str, Any]:
    """The installed kinds' entry points by name, not loaded (the first of a name wins, as
    when every kind is loaded)."""
    found: dict[str, Any] = {}
    for point in entry_points(group=GROUP):
        found.setdefault(point.name, point)
    return found


def checked(value: Any, name: Optional[str] = None) -> ProgramKind:
    """One instance of the kind class ``value`` (an entry point's object), checked: a subclass
    of ProgramKind with every abstract method and required attribute given, named ``name``
    when that is given (RegistryError saying what is wrong)."""
    if not isinstance(value, type) or not issubclass(value, ProgramKind):
        raise RegistryError(f"{value!r} is not a subclass of ProgramKind")
    if inspect.isabstract(value):
        missing = ", ".join(sorted(getattr(value, "__abstractmethods__", ())))
        raise RegistryError(f"{value.__qualname__} leaves abstract methods unimplemented: {missing}")
    unset = unset_attributes(value)
    if unset:
        raise RegistryError(f"{value.__qualname__} leaves required attributes unset: {', '.join(unset)}")
    if name is not None and value.name != name:
        raise RegistryError(f"its class names the kind {value.name!r}")
    return value()


@functools.cache
def _load(name: str) -> Optional[ProgramKind]:
    """The installed kind ``name``, its entry point loaded and checked, or None (with a
    :class:`BrokenKindWarning` naming it and why) for a broken one; loaded once per process,
    and only when asked for, so a case imports no other kind's planner, kernels or request
    model."""
    point = _points()[name]
    try:
        return checked(point.load(), point.name)
    except Exception as exc:  # noqa: BLE001 - a broken plug-in is skipped, saying why
        warnings.warn(
            f"program kind {point.name!r} ({point.value}) skipped: {type(exc).__name__}: {exc}",
            BrokenKindWarning,
            stacklevel=2,
        )
        return None


def _installed() -> dict[str, ProgramKind]:
    loaded = {name: _load(name) for name in _points()}
    return {name: k for name, k in loaded.items() if k is not None}


def kinds() -> dict[str, ProgramKind]:
    """Every program kind by name: the installed ones (in their entry points' order), then
    those registered."""
    return {**_installed(), **_added}


def register(kind: ProgramKind) -> ProgramKind:
    """Add ``kind`` (an instance of a subclass of ProgramKind, checked as an installed one is)
    for this process (ValueError if its name is taken by another value)."""
    if not isinstance(kind, ProgramKind):
        raise RegistryError(f"{kind!r} is not a ProgramKind")
    checked(type(kind))
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
    found = _load(name) if isinstance(name, str) and name in _points() else None
    if found is not None:
        return found
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
    found = [k for k in kinds().values() if field in k.request.model_fields]
    if not found:
        return "no program kind has it"
    return f"{field} belongs to " + " or ".join(f"{k.noun}s" for k in found)
