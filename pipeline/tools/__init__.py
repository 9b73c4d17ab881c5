"""Tools on result cubes and exported files: choose, query, compare, report, optimize, bench, and
the ``ds.ftsweep`` accessor.
"""

from __future__ import annotations

from ftsweep.stages import face

# the public names, each loaded from its module on first use (importing the face loads none)
_EXPORTS = {
    "SelectError": "select",
    "agreement": "query",
    "best_per_point_count": "query",
    "describe": "query",
    "open_cube": "select",
    "recorded_case": "select",
    "run_benchmark": "bench",
    "verify": "export",
    "whole_process": "bench",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = face(__name__, _EXPORTS)
