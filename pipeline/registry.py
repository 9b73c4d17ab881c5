"""The registry of program kinds (docs/architecture.md, "The program-kind contract").

Kinds are found the way xarray finds its backends: through the entry points of group
``ftsweep.kinds``, each naming one :class:`~ftsweep.engine.contract.ProgramKind` value
(``ring = "ftsweep.kinds.table.kind:RING"`` in ``pyproject.toml``), so a package outside this
repository adds a kind by declaring its own entry point. :func:`register` adds one at run
time (a notebook, a test). This module imports no kind: the kinds import the engine, and
the registry reaches them only through the entry points, so no import circle runs through it.

Generic code asks :func:`kind` for a case's kind and builds its vocabularies (sweep axes,
result fields, command-line choices) from :func:`kinds`.
"""

from __future__ import annotations

import functools
from importlib.metadata import entry_points
from typing import Any, Optional

from ftsweep.engine.contract import ProgramKind

GROUP = "ftsweep.kinds"
_added: dict[str, ProgramKind] = {}


class RegistryError(ValueError):
    """An entry point of group ``ftsweep.kinds`` that does not name a program kind."""


@functools.cache
def _installed() -> dict[str, ProgramKind]:
    found: dict[str, ProgramKind] = {}
    for point in entry_points(group=GROUP):
        try:
            value = point.load()
        except Exception as exc:  # a broken plug-in names itself, not a bare ImportError
            raise RegistryError(
                f"program kind {point.name!r} ({point.value}) cannot be loaded: {exc}"
            ) from exc
        if not isinstance(value, ProgramKind):
            raise RegistryError(f"entry point {point.name!r} ({point.value}) is not a ProgramKind")
        if value.name != point.name:
            raise RegistryError(f"entry point {point.name!r} names the kind {value.name!r}")
        found[value.name] = value
    return found


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


def unregister(name: str) -> None:
    """Remove a kind :func:`register` added (installed kinds stay)."""
    _added.pop(name, None)


def kind(name: Any) -> ProgramKind:
    """The registered kind ``name`` (ValueError naming the known ones)."""
    known = kinds()
    if name not in known:
        raise ValueError(f"unknown program kind {name!r}; known: {', '.join(known)}")
    return known[name]


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


def check_sweep_axes(spec: Any) -> None:
    """A sweep spec's program axes belong to its kind, and its kind's own rules hold
    (ValueError naming the key)."""
    own = kind(spec.layout)
    for other in kinds().values():
        foreign = [n for n in other.axis_names if n not in own.axis_names and spec.axes.get(n) is not None]
        if foreign:
            raise ValueError(f"axes.{foreign[0]} belongs to {other.sweeps}, not to a {own.name} sweep")
    check_options_keys(spec, own)
    own.check_sweep(spec)


def check_options_keys(spec: Any, own: Optional[ProgramKind] = None) -> None:
    """A sweep spec holds no options key of a kind other than ``own`` (its layout's; None for
    a spec without one): ValueError naming the key and its kind."""
    for other in kinds().values():
        key = other.options_key
        if key is not None and other is not own and spec.options_of(key):
            where = f", not to a {own.name} sweep" if own is not None else ""
            raise ValueError(f"{key} belongs to {other.sweeps} (layout: {other.name}){where}")


def flag(name: str) -> str:
    """The command-line option of a field: ``drho_um`` → ``--drho-um``."""
    return "--" + name.replace("_", "-")


def request_from_options(name: str, options: dict[str, Any]) -> tuple[dict[str, Any], list[str]]:
    """The request of kind ``name`` from command-line options (``predict``): options of another
    kind are refused naming their kind, the rest is the kind's own (ValueError naming the
    option); with the notices to show (e.g. a rounded pitch)."""
    own = kind(name)
    for key in (k for other in kinds().values() for k in other.options):
        if key not in own.options and options.get(key) is not None:
            holders = [o for o in kinds().values() if key in o.options]
            where = " or ".join(f"{o.noun}s (--layout {o.name})" for o in holders)
            raise ValueError(f"{flag(key)} belongs to {where}, not to a {own.noun}")
    return own.from_options(options)
