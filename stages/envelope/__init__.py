"""Envelope prediction (model §5): the lower envelope of the tool's nose arcs along feed-plane
lines and rows of crossings, the one envelope kernel every program kind uses.
"""

from __future__ import annotations

from ftsweep.stages import face

_EXPORTS = {
    "arcs": "arcs",
    "lower_envelope": "arcs",
    "envelope_lines": "arcs",
    "machined_lines": "arcs",
    "envelope_rows": "arcs",
    "machined_rows": "arcs",
    "interp_extrema_lines": "arcs",
    "interp_extrema_rows": "arcs",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = face(__name__, _EXPORTS)
