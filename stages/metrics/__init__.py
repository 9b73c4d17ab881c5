"""Metrics (model §6): the form error reduced batch by batch into running moments (P-V, RMS),
extrema and coarse error maps; the cusp height of a flat surface, F²/(8·Rc).
"""

from __future__ import annotations

from ftsweep.stages import face

_EXPORTS = {
    "moments": "moments",
    "empty_stats": "moments",
    "merge_stats": "moments",
    "accumulate": "moments",
    "accumulate_extrema": "moments",
    "accumulate_map_xy": "moments",
    "cusp_height_um": "moments",
    "finalize": "moments",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = face(__name__, _EXPORTS)
