"""Shared numerics: sine and cosine numba can vectorise, and fixed-point decimal text of
doubles at compiled speed (the data lines of path programs).
"""

from __future__ import annotations

from ftsweep.stages import face

_EXPORTS = {
    "decimals": "decimals",
    "Fixed": "decimals",
    "fixed": "decimals",
    "rows_bytes": "decimals",
    "rows_text": "decimals",
    "printed": "decimals",
    "parse_rows": "decimals",
    "fault": "decimals",
    "trig": "trig",
    "sincos": "trig",
    "within_reach": "trig",
    "cos_sin": "trig",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = face(__name__, _EXPORTS)
