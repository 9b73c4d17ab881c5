"""The control-point table of a ring or mesh request over a surface's aperture (model §2)."""

from __future__ import annotations

from typing import Any

from ftsweep.inputs import catalogs
from ftsweep.stages.layouts import grids as layouts
from ftsweep.stages.layouts.grids import Layout


def build_layout(surface: Any, request: Any) -> Layout:
    """The control-point table of ``request`` covering the surface's aperture (model §2).

    Rings cover the aperture's circumscribed radius; meshes its bounding box.
    """
    if request.kind not in ("ring", "mesh"):
        raise ValueError(f"a {request.kind} program is planned with its commands, not as a table")
    ap = catalogs.aperture_of(surface)
    if request.kind == "ring":
        radius = ap.outer_radius_um
        if request.pitch is not None:
            return layouts.ring_layout(radius, *request.pitch)
        return layouts.ring_layout_for(radius, *request.target())
    half_w, half_h = ap.half_extent_um
    width, height = 2.0 * half_w, 2.0 * half_h
    if request.pitch is not None:
        return layouts.mesh_layout(width, height, *request.pitch)
    return layouts.mesh_layout_for(width, height, *request.target())
