"""The three catalog entries a case names, travelling together: its surface, its machine and
its cutting conditions (:func:`ftsweep.engine.planning.resolve_specs` looks them up,
:func:`ftsweep.inputs.trust.specs_from_entries` reads them back from a file's record)."""

from __future__ import annotations

from typing import Any, NamedTuple

from ftsweep.inputs.catalogs import Cutting, Machine


class Entries(NamedTuple):
    """A case's catalog entries: the surface (a model of :mod:`ftsweep.inputs.catalogs`' union
    of families, hence ``Any``), the machine and the cutting conditions."""

    surface: Any
    machine: Machine
    cutting: Cutting
