"""The one simulator (model §3–§6): a case's spec, its planning, its cost, the line sampling, the
record, and the threads and allocator it runs with. It knows no kind by name: each function is
handed the kind's :class:`ftsweep.engine.contract.ProgramKind`.
"""

from __future__ import annotations

from ftsweep.stages import face

# the public names, each loaded from its module on first use (importing the face loads none)
_EXPORTS = {
    "Axis": "contract",
    "BenchRow": "contract",
    "Case": "case",
    "CaseError": "case",
    "Planning": "contract",
    "ProgramKind": "contract",
    "Request": "case",
    "Resolution": "case",
    "ResolvedCase": "planning",
    "STAGE_TIMERS": "simulator",
    "Simulating": "contract",
    "program_request": "case",
    "resolve_case": "planning",
    "run_case": "simulator",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = face(__name__, _EXPORTS)
