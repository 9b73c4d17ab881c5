"""Surface families from outside ftsweep, found as xarray finds its backends and ftsweep its
program kinds: a module that declares families with
:func:`ftsweep.stages.sampling.surface_family` is named

- by an entry point of group ``ftsweep.surfaces`` in an installed package's metadata
  (``[project.entry-points."ftsweep.surfaces"] tilted = "my_optics.surfaces"``): every
  ``ftsweep`` command, notebook and sweep worker then knows its families; or
- by ``FTSWEEP_SURFACE_MODULES``, module names separated by commas, for a notebook or a script
  that has not been packaged (a local cluster's workers inherit the variable).

Each is imported once per process, before a catalog's surfaces are validated
(:func:`load`). A plug-in that fails to import is warned about, naming it and what it raised,
and skipped: the families it would have declared stay unknown, and a catalog entry naming one
is refused saying how a family is registered. These modules are code the user installed or
named; nothing read from a file (a cube, a sidecar, a catalog) ever names one to import.
"""

from __future__ import annotations

import functools
import importlib
import os
import warnings
from collections.abc import Callable
from importlib import metadata
from typing import Any

GROUP = "ftsweep.surfaces"
ENV = "FTSWEEP_SURFACE_MODULES"
HOW = (
    "a family of your own is declared with ftsweep.stages.sampling.surface_family in a module named by "
    f"an entry point of group '{GROUP}' of an installed package, or in {ENV} (module names, "
    "comma-separated); `ftsweep catalogs` lists the families known and where each comes from"
)

_sources: dict[str, str] = {}
_loaded: list[str] = []  # the plug-ins imported (or tried) in this process, by source


def load() -> dict[str, str]:
    """Import every surface plug-in not imported yet in this process (entry points, then the
    modules ``FTSWEEP_SURFACE_MODULES`` names); returns each plug-in family's name with where
    it came from."""
    for ep in metadata.entry_points(group=GROUP):
        dist = getattr(ep.dist, "name", None) or "an installed package"
        _import(f"entry point '{ep.name}' ({ep.value}) of {dist}", ep.load)
    for name in (n.strip() for n in os.environ.get(ENV, "").split(",")):
        if name:
            _import(f"module {name} ({ENV})", functools.partial(importlib.import_module, name))
    return dict(_sources)


def _import(source: str, run: Callable[[], Any]) -> None:
    """Import one plug-in (once) and note the families it registered; warn and skip it where
    importing it raises."""
    if source in _loaded:
        return
    _loaded.append(source)
    from ftsweep.stages.sampling.surfaces import FAMILIES

    before = set(FAMILIES)
    try:
        run()
    except Exception as exc:  # a broken plug-in is reported and skipped, never fatal
        warnings.warn(
            f"surface plug-in {source} failed to load and is skipped: {type(exc).__name__}: {exc}",
            stacklevel=3,
        )
        return
    _sources.update(dict.fromkeys(sorted(set(FAMILIES) - before), source))


def source_of(family: str) -> str:
    """Where surface family ``family`` comes from: a plug-in (:func:`load`), the families users
    bring (height maps, plug-in functions of a catalog), or ftsweep's own."""
    if family in _sources:
        return _sources[family]
    if family in ("height_map", "plugin"):
        return "ftsweep (a user's height map or function, named by the catalog entry)"
    return "ftsweep (built in)"
