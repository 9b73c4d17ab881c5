"""Tables: the ring and mesh layouts an independent FTS controller interpolates bilinearly
(model §2-§3, [1]). Planned from a target point count and aspect ratio (or pitches), their
commands compensated over the whole table by the line engine (:mod:`ftsweep.engine.simulator`)."""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any

import numpy as np

from ftsweep.engine import result
from ftsweep.engine.case import Case, CaseError
from ftsweep.engine.contract import Axis, Planning, ProgramKind
from ftsweep.engine.cost import angular_samples, check_capacity
from ftsweep.engine.lines import LineSimulation
from ftsweep.inputs import catalogs
from ftsweep.kinds.table.layout import build_layout
from ftsweep.kinds.table.options import table_options
from ftsweep.kinds.table.request import TableRequest
from ftsweep.options import flag
from ftsweep.stages.layouts import grids as layouts
from ftsweep.stages.layouts.grids import Layout


def _request_at(spec: Any, value: dict[str, float]) -> TableRequest:
    return TableRequest(kind=spec.layout, points=value["points"], aspect=value["aspect"])


def _feed(case: Case, cutting: Any, rc: float, surface_spec: Any, folder: Any, program: Any) -> float:
    return case.feed_of(cutting)


def _plan(p: Planning) -> tuple[Layout, dict[str, Any]]:
    try:
        return build_layout(p.surface_spec, p.case.layout), {}
    except ValueError as exc:
        raise CaseError(f"layout: {exc}") from None


def _record_fields(rcase: Any) -> dict[str, Any]:
    layout = rcase.layout
    pitch_names = PITCHES[layout.kind]
    return {
        "table_rows": layout.shape[0],
        "table_cols": layout.shape[1],
        pitch_names[0]: layout.pitch[0],
        pitch_names[1]: layout.pitch[1],
    }


def _cost(case: Case, surface: Any, catalog_folder: Any, feed: float) -> tuple[float, Any]:
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
    cells = _ring_cells if case.layout.kind == "ring" else _mesh_cells
    n_theta = angular_samples(cells, layout, rho0, case.resolution)
    nodes = n_theta * rho0 / feed * case.resolution.points_per_feed
    return 8.0 * layout.n_points + nodes, (n_theta, feed, case.nose_radius_of(cutting))


def _ring_pitch(r: dict[str, Any]) -> str:
    return f"Δρ = {r['drho_um']:.4g} µm, Δθ = {r['dtheta_deg']:.4g}°"


def _mesh_pitch(r: dict[str, Any]) -> str:
    return f"Δx = {r['dx_um']:.4g} µm, Δy = {r['dy_um']:.4g} µm"


def _ring_point(layout: Layout, flat: int) -> str:
    i, j = np.unravel_index(flat, layout.shape)
    rho = layout.origin[0] + i * layout.pitch[0]
    theta = layout.origin[1] + j * layout.pitch[1]
    return f"control point [{i}, {j}] (ρ = {rho:.6g} µm, θ = {theta:.6g}°)"


def _mesh_point(layout: Layout, flat: int) -> str:
    i, j = np.unravel_index(flat, layout.shape)
    x, y = layout.origin[0] + i * layout.pitch[0], layout.origin[1] + j * layout.pitch[1]
    return f"control point [{i}, {j}] (x = {x:.6g} µm, y = {y:.6g} µm)"


def _ring_cells(layout: Layout, rho0_um: float) -> float:
    """Np cells: one per point of a ring."""
    return layout.shape[1]


def _mesh_cells(layout: Layout, rho0_um: float) -> float:
    """2πρ0/max(Δx, Δy): bilinear error grows as the pitch squared, so the coarse
    direction's cells carry the error that must be resolved."""
    return math.ceil(2.0 * math.pi * rho0_um / max(layout.pitch))


def _describe(r: dict[str, Any]) -> list[str]:
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


def _check_sweep(spec: Any) -> None:
    for name in AXES:
        if spec.axes.get(name) is None:
            raise ValueError(f"axes.{name}: required key is missing for a {spec.layout} sweep")


def _table_options(kind: str, opts: dict[str, Any]) -> tuple[dict[str, Any], list[str]]:
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


def _file_format() -> Any:
    from ftsweep.kinds.table.verify import header_format

    return header_format()


def _seed(kind: str, surface_spec: Any, *args: Any) -> tuple[float, float, float]:
    from ftsweep.kinds.table.sweep_estimate import seed_layout

    return seed_layout(surface_spec, kind, *args)


def _estimate(spec: Any, coords: Any, folder: Any) -> Any:
    from ftsweep.kinds.table.sweep_estimate import estimate_sweep

    return estimate_sweep(spec, coords, folder)


PITCHES = {"ring": ("drho_um", "dtheta_deg"), "mesh": ("dx_um", "dy_um")}
NOUNS = {"ring": "ring layout", "mesh": "mesh layout"}
AXES = ("points", "aspect")
POINTS = Axis("points", "1", "target number of control points", dumped_unset=True, count=True)


def _reference(rcase: Any) -> dict[str, Any]:
    """The brute-force evaluation of a table case (:mod:`ftsweep.kinds.table.reference`),
    imported when asked for: a case does not load it."""
    from ftsweep.kinds.table.reference import reference_case

    return reference_case(rcase)


def _aspect(units: str, long_name: str) -> Axis:
    return Axis("aspect", units, long_name, dumped_unset=True)


RING = ProgramKind(
    name="ring",
    noun=NOUNS["ring"],
    request=TableRequest,
    axes=(POINTS, _aspect("um/deg", "target aspect ratio Δρ/Δθ of the pitches")),
    fields=(
        *result.TABLE,
        result.number("drho_um", "um", "ring pitch Δρ"),
        result.number("dtheta_deg", "deg", "angular pitch Δθ"),
        result.aspect_actual("um/deg"),
        *result.SPINDLE,
    ),
    pitches=PITCHES["ring"],
    file_format=_file_format,
    estimate=_estimate,
    request_at=_request_at,
    feed=_feed,
    plan=_plan,
    record_fields=_record_fields,
    cost=_cost,
    simulation=LineSimulation,
    pitch_text=_ring_pitch,
    point_text=_ring_point,
    angular_cells=_ring_cells,
    seed=functools.partial(_seed, "ring"),
    warm_request=lambda: TableRequest(kind="ring", pitch=(50.0, 10.0)),
    bench_cases=lambda: {
        "ring-1M-a8": ("sinewave2d", TableRequest(kind="ring", points=1_000_000, aspect=8.0))
    },
    describe=_describe,
    check_sweep=_check_sweep,
    sweeps="table sweeps",
    options=("drho_um", "dtheta_deg", "points", "aspect"),
    click_options=table_options,
    from_options=lambda o: _table_options("ring", o),
    aspect_range=(0.3, 400.0),
    aspect_units="um/deg",
    reference=_reference,
)
# a mesh is a ring's kind in Cartesian coordinates: its own names, points, cells and options
MESH = dataclasses.replace(
    RING,
    name="mesh",
    noun=NOUNS["mesh"],
    axes=(POINTS, _aspect("1", "target aspect ratio Δx/Δy of the pitches")),
    fields=(
        *result.TABLE,
        result.number("dx_um", "um", "mesh pitch Δx"),
        result.number("dy_um", "um", "mesh pitch Δy"),
        result.aspect_actual("1"),
        *result.SPINDLE,
    ),
    pitches=PITCHES["mesh"],
    pitch_text=_mesh_pitch,
    point_text=_mesh_point,
    angular_cells=_mesh_cells,
    seed=functools.partial(_seed, "mesh"),
    warm_request=lambda: TableRequest(kind="mesh", pitch=(50.0, 50.0)),
    bench_cases=lambda: {
        "mesh-1M-a1": ("lens_array", TableRequest(kind="mesh", points=1_000_000, aspect=1.0))
    },
    options=("dx_um", "dy_um", "points", "aspect"),
    click_options=table_options,
    from_options=lambda o: _table_options("mesh", o),
    aspect_range=(0.08, 16.0),
    aspect_units="1",
)
