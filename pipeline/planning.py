"""Planning a case: its catalog entries looked up (or the recorded ones taken), every
refusal that needs them, and its program made: a ring or mesh layout, a spiral's points by
its rule and budgets ([4]), a D path ([5]), the compensated commands (model §4), the layered
plan of a program deeper than the stroke ([3]).
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional

import numpy as np

from ftsweep import catalogs
from ftsweep import dpath as dpath_program
from ftsweep.cost import check_capacity, check_cost, ray_nodes, spiral_points
from ftsweep.spec import Case, CaseError, LayoutRequest
from ftsweep.stages import compensation, dynamics, layers, layouts, spiral
from ftsweep.stages.layouts import Layout


def build_layout(surface: Any, request: LayoutRequest) -> Layout:
    """The control-point table of ``request`` covering the surface's aperture (model §2).

    Rings cover the aperture's circumscribed radius; meshes its bounding box.
    """
    if request.kind in ("spiral", "dpath"):
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


@dataclass(frozen=True)
class ResolvedCase:
    """A case with its catalog entries looked up and every rule checked: all the stages need
    (lengths µm). Built by :func:`resolve_case`. For a spiral program, ``layout`` is its
    :class:`~ftsweep.stages.spiral.SpiralPath` and ``values``/``gouge`` its compensated
    commands [µm] and their gouge flags, planned with it (``plan_seconds``)."""

    case: Case
    surface_spec: Any
    machine: Any
    cutting: Any
    layout: Any  # a table (Layout), a SpiralPath or a DPath
    surface: Any  # the surface callable fn(x, y) -> (f, ∂f/∂x, ∂f/∂y)
    aperture: Any
    feed_um: float
    nose_radius_um: float
    gradient_bound: float
    lines: Any = None  # the family's line evaluator (catalogs.line_sampler), or None
    values: Optional[np.ndarray] = None
    gouge: Optional[np.ndarray] = None
    chord_error_um: float = math.nan
    residual_error_um: float = math.nan
    plan_seconds: float = 0.0

    @property
    def rho0_um(self) -> float:
        """Start radius of the spiral: the aperture's circumscribed radius [µm] (model §1)."""
        return float(self.aperture.outer_radius_um)


def resolve_case(
    case: Case,
    catalog_folder: Any = None,
    specs: Optional[tuple[Any, Any, Any]] = None,
    program: Optional[tuple[Any, np.ndarray]] = None,
) -> ResolvedCase:
    """Look up a case's entries (or take ``specs``) and refuse what cannot be simulated: a
    feed not below 2·Rc (model §5), a layout the aperture or the
    controller's capacity rules out, a surface without a finite slope bound.

    A spiral case is planned here ([4]): its feed from the residual budget if it has
    one, its points by its rule, their compensated commands; a given ``program`` (path,
    commands [µm]), e.g. read back from an exported file, is taken as it stands instead."""
    surface_spec, machine, cutting = specs or resolve_specs(case, catalog_folder)
    rc = case.nose_radius_um or cutting.nose_radius_um
    request = case.layout
    sections = section_samples(surface_spec, catalog_folder) if request.kind == "spiral" else None
    feed = _feed_of(case, cutting, rc, sections, program)
    bound = _checked_bounds(case, surface_spec, catalog_folder, feed, rc)
    surface = catalogs.surface_callable(surface_spec, catalog_folder)
    layout, extra = _program_of(case, (surface_spec, machine), surface, feed, rc, bound, sections, program)
    what = f"{layout.kind} {'layout' if layout.kind in ('ring', 'mesh') else 'program'}"
    check_capacity(case, what, layout.n_points, machine.capacity_points)
    return ResolvedCase(
        case=case,
        surface_spec=surface_spec,
        machine=machine,
        cutting=cutting,
        layout=layout,
        surface=surface,
        aperture=catalogs.aperture_of(surface_spec),
        feed_um=feed,
        nose_radius_um=rc,
        gradient_bound=bound,
        lines=catalogs.line_sampler(surface_spec),
        **extra,
    )


def _checked_bounds(case: Case, surface_spec: Any, catalog_folder: Any, feed: float, rc: float) -> float:
    """The surface's slope bound, after refusing a feed not below 2·Rc (model §5), a surface
    without a finite slope bound, and a feed-plane line too large for memory (known before
    anything is planned or compensated)."""
    try:
        catalogs.check_feed(feed, rc)
    except ValueError as exc:
        raise CaseError(str(exc)) from None
    bound = catalogs.gradient_bound(surface_spec, catalog_folder)
    if not math.isfinite(bound):
        raise CaseError(
            f"the slope bound of surface '{case.surface}' is not finite: the surface gives no finite "
            "slope on its aperture"
        )
    margin = compensation.contact_window_um(bound, rc) + 2.0 * feed
    rho0 = float(catalogs.aperture_of(surface_spec).outer_radius_um)
    check_cost(ray_nodes(rho0, margin, case.resolution.points_per_feed, feed), 2, math.inf)
    return bound


def _program_of(
    case: Case,
    entries: tuple[Any, Any],
    surface: Any,
    feed: float,
    rc: float,
    bound: float,
    sections: Optional[tuple[np.ndarray, ...]],
    program: Optional[tuple[Any, np.ndarray]],
) -> tuple[Any, dict[str, Any]]:
    """The program of a case and what its planning adds to the resolved case: a spiral's
    points and commands ([4]), a D path ([5]), or a table's layout (model §2)."""
    surface_spec, machine = entries
    request = case.layout
    extra: dict[str, Any] = {}
    t = time.perf_counter()
    if request.kind == "spiral":
        note = " (estimated: a tenth of the count the curvature bound allows)" if request.chord_um else ""
        estimate = spiral_points(case, surface_spec, feed)
        check_capacity(case, "spiral program", estimate, machine.capacity_points, note)
        layout, extra = plan_spiral(case, surface_spec, surface, feed, rc, bound, program)
        assert sections is not None
        extra["residual_error_um"] = residual_error_um(sections, feed, rc)
        extra["plan_seconds"] = time.perf_counter() - t
    elif request.kind == "dpath":
        layout, extra = plan_dpath(
            case, surface_spec, surface, feed, rc, bound, program, machine.capacity_points
        )
        extra["plan_seconds"] = time.perf_counter() - t
    else:
        try:
            layout = build_layout(surface_spec, request)
        except ValueError as exc:
            raise CaseError(f"layout: {exc}") from None
    return layout, extra


def _feed_of(
    case: Case, cutting: Any, rc: float, sections: Optional[tuple[np.ndarray, ...]], program: Any
) -> float:
    """The feed per revolution [µm/rev] of a case: a D path's spacing between cuts, a given
    program's, a spiral's from its residual budget, else the case's or the cutting entry's."""
    request = case.layout
    if request.kind == "dpath":
        if program is not None:
            return float(program[0].geometry.spacing_um)
        return float(request.spacing_um or case.feed_um or cutting.feed_um)
    if program is not None:
        return float(program[0].feed_um)
    if request.residual_um is not None and sections is not None:
        if case.feed_um is not None:
            raise CaseError("give either a feed or a residual budget (which sets the feed), not both")
        return residual_feed_um(sections, request.residual_um, rc, case.surface)
    return float(case.feed_um or cutting.feed_um)


def plan_spiral(
    case: Case,
    surface_spec: Any,
    surface: Any,
    feed_um: float,
    rc: float,
    bound: float,
    program: Optional[tuple[spiral.SpiralPath, np.ndarray]] = None,
) -> tuple[spiral.SpiralPath, dict[str, Any]]:
    """The spiral program of a case ([4]): its points by the request's rule from the
    aperture's circumscribed radius to the centre, and their commands compensated as a
    table's (model §4); or the given ``program`` as it stands (no gouge flags)."""
    rho0 = float(catalogs.aperture_of(surface_spec).outer_radius_um)
    if program is not None:
        path, values = program
        values = np.asarray(values, dtype=np.float64)
        return path, {"values": values, "gouge": np.zeros(values.shape, dtype=bool)}

    def compensated(phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return compensation.compensate(
            surface,
            spiral.spiral_radius(phi, rho0, feed_um),
            np.mod(phi, 2.0 * math.pi),
            rc,
            case.compensation,
            bound,
            n_scan=case.resolution.compensation_scan,
            curvature_bound=catalogs.curvature_bound(surface_spec),
        )

    rule, value = case.layout.spiral_rule()
    extra: dict[str, Any] = {}
    try:
        if rule == "angle":
            path = spiral.constant_angle(rho0, feed_um, int(value))
        elif rule == "arc":
            path = spiral.constant_arc(rho0, feed_um, value)
        else:
            path, _, errors = spiral.chord_budget(rho0, feed_um, value, lambda phi: compensated(phi)[0])
            extra["chord_error_um"] = float(errors.max()) if errors.size else 0.0
    except ValueError as exc:
        raise CaseError(f"spiral program: {exc}") from None
    values, gouge = compensated(path.phi)
    return path, {"values": values, "gouge": gouge, **extra}


def plan_dpath(
    case: Case,
    surface_spec: Any,
    surface: Any,
    spacing_um: float,
    rc: float,
    bound: float,
    program: Optional[tuple[Any, np.ndarray]] = None,
    max_points: float = math.inf,
) -> tuple[Any, dict[str, Any]]:
    """The D-path program of a case ([5], :func:`ftsweep.dpath.plan`): its cut points
    compensated as a table's (model §4), or the given ``program`` as it stands. A path of
    more than ``max_points`` points is refused before it is made."""

    def compensated(part: Any, rho: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return compensation.compensate(
            part,
            rho,
            theta,
            rc,
            case.compensation,
            bound,
            n_scan=case.resolution.compensation_scan,
            curvature_bound=catalogs.curvature_bound(surface_spec),
        )

    try:
        return dpath_program.plan(
            case.layout,
            catalogs.aperture_of(surface_spec),
            surface,
            spacing_um,
            rc,
            compensated,
            program,
            max_points,
        )
    except ValueError as exc:
        raise CaseError(f"D path (machine '{case.machine}'): {exc}") from None


# residual-budget sampling of the radial sections ([4] eq. 1): radii × angles over the
# circumscribed circle; the feed is the smallest over these samples inside the aperture
SECTION_RADII = 2001
SECTION_ANGLES = 720


@functools.lru_cache(maxsize=16)
def _section_samples(spec_json: str, folder: Optional[str]) -> tuple[np.ndarray, ...]:
    from pydantic import TypeAdapter

    spec = TypeAdapter(catalogs.surface_spec()).validate_json(spec_json)
    path = None if folder is None else Path(folder)
    surface = catalogs.surface_callable(spec, path)
    aperture = catalogs.aperture_of(spec)
    step = aperture.outer_radius_um / (SECTION_RADII - 1)
    # r = 0 is left out: sections of umbrella-like surfaces have no curvature at the apex
    theta = (np.arange(SECTION_ANGLES) * (2.0 * math.pi / SECTION_ANGLES))[:, None]
    rho = np.repeat((np.arange(1, SECTION_RADII) * step)[None, :], SECTION_ANGLES, axis=0)
    ct, st = np.cos(theta), np.sin(theta)
    slope, second = spiral.section_curvature(surface, rho, ct, st, 0.25 * step)
    inside = aperture.contains_polar(rho, ct, st)
    radius = spiral.signed_radius_um(slope, second)
    x, y = rho * ct, rho * st
    return radius[inside], slope[inside], x[inside], y[inside]


def section_samples(surface_spec: Any, catalog_folder: Any = None) -> tuple[np.ndarray, ...]:
    """Signed radius of curvature [µm], slope [-] and place (x, y [µm]) of the radial
    sections of the surface on a polar grid of :data:`SECTION_RADII` radii by
    :data:`SECTION_ANGLES` angles inside the aperture ([4] eq. 1; cached per entry)."""
    folder = None if catalog_folder is None else str(catalog_folder)
    return _section_samples(surface_spec.model_dump_json(), folder)


def residual_feed_um(sections: tuple[np.ndarray, ...], residual_um: float, rc: float, name: str) -> float:
    """The feed [µm/rev] of a residual budget Δres [µm] ([4] eqs. 2–3): the smallest
    over the part of :func:`ftsweep.stages.spiral.feed_for_cusp`. Refuses a part with a
    concave section tighter than the nose radius, where no feed meets the budget."""
    radius, slope, x, y = sections
    if not residual_um < rc:
        raise CaseError(f"the residual budget {residual_um:g} µm must be below the nose radius {rc:g} µm")
    feeds = spiral.feed_for_cusp(residual_um, rc, radius, slope)
    worst = int(np.argmin(feeds))
    if not feeds[worst] > 0.0:
        raise CaseError(
            f"surface '{name}' has a concave section of radius {radius[worst]:.4g} µm at x = "
            f"{x[worst]:.6g} µm, y = {y[worst]:.6g} µm, tighter than the nose radius {rc:g} µm: no "
            "feed meets a residual budget there; use a smaller nose radius"
        )
    return float(feeds[worst])


def residual_error_um(sections: tuple[np.ndarray, ...], feed_um: float, rc: float) -> float:
    """Largest residual (cusp) height [µm] the feed leaves over the part, from each section's
    curvature (the inverse of [4] eq. 2, :func:`ftsweep.stages.spiral.cusp_for_feed`)."""
    radius, slope, _, _ = sections
    cusp = spiral.cusp_for_feed(feed_um, rc, radius, slope)
    return float(np.nanmax(cusp)) if np.isfinite(cusp).any() else math.nan


def z_error_of(rcase: ResolvedCase) -> float:
    """Z positioning error per retraction [µm]: the case's, else the machine's."""
    z_error = rcase.case.z_error_um
    return float(rcase.machine.z_error_um if z_error is None else z_error)


def layer_plan(rcase: ResolvedCase, table: np.ndarray) -> Optional[layers.LayerPlan]:
    """The layered plan ([3], :mod:`ftsweep.stages.layers`) of a case whose commands span
    more than the machine's travel (the table's range bounds every interpolated command),
    planned on the commands the controller executes along the spiral; None for a single
    pass (the commands fit the travel, or the case asks ``layers: off``)."""
    machine = rcase.machine
    span = float(np.max(table) - np.min(table))
    if rcase.case.layers == "off" or span <= machine.travel_um:
        return None
    k = dynamics.commands_per_revolution(machine.command_rate_hz, rcase.cutting.spindle_rpm)

    def chunks() -> Any:
        return layers.command_stream(rcase.layout, table, rcase.rho0_um, rcase.feed_um, k)

    phi_end = spiral.spiral_end_rad(rcase.rho0_um, rcase.feed_um)
    try:
        return layers.plan_layers(chunks, machine.travel_um, machine.layer_margin_um, phi_end)
    except ValueError as exc:
        raise CaseError(f"layered plan: {exc}") from None


def resolve_specs(case: Case, catalog_folder: Any = None) -> tuple[Any, Any, Any]:
    """The (surface, machine, cutting) catalog entries a case names."""
    return (
        catalogs.entry("surfaces", case.surface, catalog_folder),
        catalogs.entry("machines", case.machine, catalog_folder),
        catalogs.entry("cutting", case.cutting, catalog_folder),
    )


def control_table(
    case: Case, layout: Layout, surface_spec: Any, nose_radius_um: float, catalog_folder: Any = None
) -> tuple[np.ndarray, np.ndarray]:
    """The compensated control table [µm] of ``layout`` and its gouge flags (model §4)."""
    node_rho, node_theta = layouts.layout_nodes(layout)
    return compensation.compensate(
        catalogs.surface_callable(surface_spec, catalog_folder),
        node_rho,
        node_theta,
        nose_radius_um,
        case.compensation,
        catalogs.gradient_bound(surface_spec, catalog_folder),
        n_scan=case.resolution.compensation_scan,
        curvature_bound=catalogs.curvature_bound(surface_spec),
    )
