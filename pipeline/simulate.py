"""A case simulated as its kind says: the engine's :func:`~ftsweep.engine.simulator.run_case`
and :func:`~ftsweep.engine.planning.resolve_case` handed the kind the registry finds for the
case's request (docs/architecture.md, "The flow of a case"). The engine itself knows no kind
by name; this is where a case meets its kind.
"""

from __future__ import annotations

from typing import Any

from ftsweep.engine import planning, simulator
from ftsweep.engine import plugins as registry
from ftsweep.engine.case import Case
from ftsweep.engine.planning import ResolvedCase


def run_case(case: Case, *args: Any, **options: Any) -> dict[str, Any]:
    """Predict the form error of ``case`` (model §1–§6): the record of
    :func:`ftsweep.engine.simulator.run_case`, whose options it takes."""
    return simulator.run_case(case, registry.kind(case.layout.kind), *args, **options)


def resolve_case(case: Case, *args: Any, **options: Any) -> ResolvedCase:
    """``case`` with its entries looked up, every rule checked and its program planned
    (:func:`ftsweep.engine.planning.resolve_case`, whose options it takes)."""
    return planning.resolve_case(case, registry.kind(case.layout.kind), *args, **options)
