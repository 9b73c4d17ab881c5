"""Tables: the ring and mesh layouts an independent FTS controller interpolates bilinearly
(model §2-§3, [1]). Planned from a target point count and aspect ratio (or pitches), their
commands compensated over the whole table by the line engine (:mod:`ftsweep.engine.simulator`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ftsweep.engine.case import Case, CaseError
from ftsweep.engine.contract import Planning
from ftsweep.engine.cost import angular_samples, check_capacity
from ftsweep.inputs import catalogs
from ftsweep.kinds.table.layout import build_layout
from ftsweep.kinds.table.names import AXES, NOUNS, PITCHES
from ftsweep.kinds.table.request import TableRequest
from ftsweep.options import flag
from ftsweep.stages.layouts import grids as layouts
from ftsweep.stages.layouts.grids import Layout


def request_at(spec: Any, value: dict[str, float]) -> TableRequest:
    return TableRequest(kind=spec.layout, points=value["points"], aspect=value["aspect"])


def plan(p: Planning) -> tuple[Layout, dict[str, Any]]:
    try:
        return build_layout(p.surface_spec, p.case.layout), {}
    except ValueError as exc:
        raise CaseError(f"layout: {exc}") from None


def record_fields(rcase: Any) -> dict[str, Any]:
    layout = rcase.layout
    pitch_names = PITCHES[layout.kind]
    return {
        "table_rows": layout.shape[0],
        "table_cols": layout.shape[1],
        pitch_names[0]: layout.pitch[0],
        pitch_names[1]: layout.pitch[1],
    }


def cost(case: Case, surface: Any, catalog_folder: Any, feed: float) -> tuple[float, Any]:
    """Control points plus simulated nodes; cases of equal angular samples, feed and nose
    radius simulate the same lines and share them (:class:`ftsweep.engine.lines.LineCache`). A case
    whose layout cannot be built, or holds more points than the machine's controller, is
    refused (CaseError), as its planning would refuse it."""
    try:
        layout = build_layout(surface, case.layout)
    except ValueError as exc:
        raise CaseError(f"layout: {exc}") from None
    machine = catalogs.entry("machines", case.machine, catalog_folder)
    check_capacity(case, NOUNS[case.layout.kind], layout.n_points, machine.capacity_points)
    rho0 = catalogs.aperture_of(surface).outer_radius_um
    cutting = catalogs.entry("cutting", case.cutting, catalog_folder)
    cells = ring_cells if case.layout.kind == "ring" else mesh_cells
    n_theta = angular_samples(cells, layout, rho0, case.resolution)
    nodes = n_theta * rho0 / feed * case.resolution.points_per_feed
    return 8.0 * layout.n_points + nodes, (n_theta, feed, case.nose_radius_of(cutting))


def ring_point(layout: Layout, flat: int) -> str:
    i, j = np.unravel_index(flat, layout.shape)
    rho = layout.origin[0] + i * layout.pitch[0]
    theta = layout.origin[1] + j * layout.pitch[1]
    return f"control point [{i}, {j}] (ρ = {rho:.6g} µm, θ = {theta:.6g}°)"


def mesh_point(layout: Layout, flat: int) -> str:
    i, j = np.unravel_index(flat, layout.shape)
    x, y = layout.origin[0] + i * layout.pitch[0], layout.origin[1] + j * layout.pitch[1]
    return f"control point [{i}, {j}] (x = {x:.6g} µm, y = {y:.6g} µm)"


def ring_cells(layout: Layout, rho0_um: float) -> float:
    """Np cells: one per point of a ring."""
    return layout.shape[1]


def mesh_cells(layout: Layout, rho0_um: float) -> float:
    """2πρ0/max(Δx, Δy): bilinear error grows as the pitch squared, so the coarse
    direction's cells carry the error that must be resolved."""
    return math.ceil(2.0 * math.pi * rho0_um / max(layout.pitch))


def describe(r: dict[str, Any]) -> list[str]:
    """The table's points, shape and pitches (``predict``)."""
    if r["layout"] == "ring":
        pitches = (
            f"Δρ = {r['drho_um']:.4g} µm, Δθ = {r['dtheta_deg']:.7g}°  (α = {r['aspect_actual']:.4g} µm/deg)"
        )
    else:
        pitches = f"Δx = {r['dx_um']:.4g} µm, Δy = {r['dy_um']:.4g} µm  (α = {r['aspect_actual']:.4g})"
    shape = f"{r['table_rows']} × {r['table_cols']}"
    return [
        f"layout       {r['layout']}: {r['n_points']:,} control points ({shape})",
        f"pitches      {pitches}",
    ]


def check_sweep(spec: Any) -> None:
    for name in AXES:
        if spec.axes.get(name) is None:
            raise ValueError(f"axes.{name}: required key is missing for a {spec.layout} sweep")


def table_from_options(kind: str, opts: dict[str, Any]) -> tuple[dict[str, Any], list[str]]:
    own = PITCHES[kind]
    given = [k for k in own if opts.get(k) is not None]
    points, aspect = opts.get("points"), opts.get("aspect")
    if given and (points is not None or aspect is not None):
        raise ValueError("give either explicit pitches or --points with --aspect, not both")
    if len(given) == 1:
        missing = [k for k in own if opts.get(k) is None][0]
        raise ValueError(f"{flag(missing)} is missing: a {kind} layout needs both pitches")
    if not given and (points is None or aspect is None):
        raise ValueError(f"give the layout: {flag(own[0])} and {flag(own[1])}, or --points N with --aspect A")
    if not given:
        return {"kind": kind, "points": points, "aspect": aspect}, []
    first, second, notices = opts[own[0]], opts[own[1]], []
    if kind == "ring" and not opts.get("strict") and math.isfinite(second) and second > 0:
        realised, n_per_ring = layouts.nearest_ring_dtheta(second)
        # the notice prints Δθ to 7 digits: that printed value, given back, is taken silently
        if not math.isclose(realised, second, rel_tol=1e-6):
            notices.append(
                f"notice: Δθ = {second:g}° does not divide 360°; using the nearest realisable "
                f"Δθ = {realised:.7g}° ({n_per_ring} points per ring; --strict refuses instead)"
            )
        second = realised
    return {"kind": kind, "pitch": (first, second)}, notices
