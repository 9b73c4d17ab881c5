"""Layouts (model §2, §3): the table of control points an FTS controller holds, as ring or
mesh grids in index space, and the first-order estimate of a layout's form error.
"""

from __future__ import annotations

from ftsweep.stages import face

_EXPORTS = {
    "estimate": "estimate",
    "ring_second_derivatives": "estimate",
    "mesh_second_derivatives": "estimate",
    "extreme_samples": "estimate",
    "interp_span_nm": "estimate",
    "cusp_nm": "estimate",
    "grids": "grids",
    "Layout": "grids",
    "nearest_ring_dtheta": "grids",
    "ring_layout": "grids",
    "mesh_layout": "grids",
    "ring_layout_for": "grids",
    "mesh_layout_for": "grids",
    "layout_nodes": "grids",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = face(__name__, _EXPORTS)
