"""Freeform Fresnel programs on an X-Y-Z-C lathe ([2]): the surface sliced into facets, the
quasi-spiral path along their edges and its 4-axis trajectory planned by
:func:`ftsweep.kinds.fresnel.program.plan`, timed adaptively
(:func:`ftsweep.kinds.fresnel.program.timesteps`), and
simulated by the one simulator along rays from the surface's lowest point
(:class:`ftsweep.kinds.fresnel.form.FresnelSimulation`). The case's feed is the feed Δr per turn;
its compensation selects [2]'s: exact (eq. 10), slope (the straight line of eq. 12) or none."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import numpy as np

from ftsweep.engine import result
from ftsweep.engine.case import Case, CaseError
from ftsweep.engine.contract import Planning
from ftsweep.inputs import catalogs
from ftsweep.kinds.fresnel.names import AXES
from ftsweep.kinds.fresnel.request import FresnelRequest

if TYPE_CHECKING:
    from ftsweep.kinds.fresnel import program as fresnel

# the planner (ftsweep.kinds.fresnel.program) and the engine (ftsweep.kinds.fresnel.form) are imported where a
# Fresnel program is planned or simulated, not by every command that lists the kinds

# the request's fields → the planner's option names (ftsweep.kinds.fresnel.program.DEFAULTS)
OPTION = {"control_points": "scheme"}


def option(request: Any, name: str) -> Any:
    """A Fresnel option of a request, or its default (:data:`ftsweep.kinds.fresnel.program.DEFAULTS`)."""
    from ftsweep.kinds.fresnel import program as fresnel

    value = getattr(request, name, None)
    return fresnel.DEFAULTS[OPTION.get(name, name)] if value is None else value


def request_at(spec: Any, value: dict[str, float]) -> FresnelRequest:
    return FresnelRequest(
        kind="fresnel",
        **{
            **(spec.options_of("fresnel") or {}),
            **{k: (int(round(v)) if k == "points_per_turn" else v) for k, v in value.items() if k in AXES},
        },
    )


def feed(case: Case, cutting: Any, rc: float, surface_spec: Any, folder: Any, program: Any) -> float:
    """The feed Δr per turn [µm]: a given program's, else the case's or the cutting entry's."""
    if program is not None:
        return float(program[0].plan.feed_um)
    return case.feed_of(cutting)


def plan(p: Planning) -> tuple[fresnel.FresnelProgram, dict[str, Any]]:
    """The program ([2] §2.1–2.5): planned, then timed at T0 = one turn at the spindle speed;
    or the given one as it stands (no gouge flags)."""
    from ftsweep.kinds.fresnel import program as fresnel
    from ftsweep.kinds.fresnel.form import COMPENSATION

    if p.machine.interpolation == "spline1":
        raise CaseError(
            f"machine '{p.case.machine}' interpolates spline1 (one segment time TA for every point); a "
            "Fresnel program runs at adaptive timesteps: a PVT or linear machine (docs/controllers.md)"
        )
    if p.program is not None:
        prog, values = p.program
        values = np.asarray(values, dtype=np.float64)
        return prog, {"values": values, "gouge": np.zeros(values.shape, dtype=bool)}
    t = time.perf_counter()
    req, case = p.case.layout, p.case
    k = int(option(req, "points_per_turn"))
    try:
        fplan = fresnel.plan(
            catalogs.base_callable(p.surface_spec, p.catalog_folder),
            catalogs.aperture_of(p.surface_spec),
            float(option(req, "facet_height_um")),
            p.feed_um,
            p.nose_radius_um,
            k,
            float(option(req, "deviation_deg")),
            COMPENSATION[case.compensation],
            str(option(req, "control_points")),
            p.machine.capacity_points,
        )
        limits = fresnel.limits_of(p.machine, case.machine)
        reference = 60.0 / (p.cutting.spindle_rpm * k)  # T0: one turn at the spindle speed
        safety, timing = float(option(req, "safety")), str(option(req, "timing"))
        steps = fresnel.timesteps(fplan, limits, safety, reference, p.progress, timing)
    except ValueError as exc:
        raise CaseError(f"Fresnel program: {exc}") from None
    prog = fresnel.FresnelProgram("fresnel", fplan, steps, fplan.path.xy)
    if p.machine.interpolation == "pvt":
        try:
            prog = fresnel.pvt_form(prog, fplan.tool_z_um, p.machine.controller)
        except ValueError as exc:
            raise CaseError(f"Fresnel program: {exc}") from None
    gouge = np.zeros(prog.n_points, dtype=bool)
    return prog, {"values": fplan.tool_z_um, "gouge": gouge, "plan_seconds": time.perf_counter() - t}


def record_fields(rcase: Any) -> dict[str, Any]:
    """The Fresnel fields of a case record (:func:`ftsweep.kinds.fresnel.form.record_fields`)."""
    from ftsweep.kinds.fresnel.form import record_fields as fields

    return fields(rcase)


def cost(case: Case, surface: Any, catalog_folder: Any, feed: float) -> tuple[float, Any]:
    """Its rays × nodes (3 rays per point of a turn, points_per_feed per feed over the part's
    radius) and the points it times; its lines are its own."""
    k = int(option(case.layout, "points_per_turn"))
    turns = catalogs.aperture_of(surface).outer_radius_um / feed
    return 3.0 * k * turns * case.resolution.points_per_feed + 50.0 * k * turns, None


def pitch_text(r: dict[str, Any]) -> str:
    return f"mean ΔC = {r['dphi_deg']:.4g}°, mean Δs = {r['ds_um']:.4g} µm"


def point_text(prog: Any, flat: int) -> str:
    x, y = prog.xy[flat]
    return f"Fresnel point {flat} (x = {x:.6g} µm, y = {y:.6g} µm in the part's frame)"


def describe(r: dict[str, Any]) -> list[str]:
    """The program's facets, path and timing (``predict``)."""
    verdict = "feasible" if r["feasible"] else f"INFEASIBLE: {r['infeasible_reason']}"
    return [
        f"program      Fresnel: {r['n_points']:,} points, {r['n_facets']} facet(s) of "
        f"{r['facet_height_um']:g} µm, {r['revolutions']:.4g} turns of {r['points_per_turn']:,.0f} points "
        f"(rake face {r['deviation_deg']:g}°)",
        f"tool edge    e_z up to {r['ez_exact_max_nm']:.1f} nm (eq. 10), {r['ez_straight_max_nm']:.1f} nm "
        "(eq. 12); metrics over the facets' interiors (walls excluded)",
        f"timing       {r['machining_s']:.1f} s adaptive, {r['time_constant_s']:.1f} s constant "
        f"({r['speedup']:.2f}×): {verdict}",
    ]


def check_sweep(spec: Any) -> None:
    """An axis of its own or of the compensation; the Fresnel options valid and not swept too."""
    if not any(spec.axes.get(n) is not None for n in (*AXES, "compensation")):
        raise ValueError(
            "a Fresnel sweep needs an axis: facet_height_um, points_per_turn, deviation_deg and/or "
            "compensation"
        )
    given = spec.options_of("fresnel") or {}
    for name in AXES:
        if name in given and spec.axes.get(name) is not None:
            raise ValueError(f"fresnel.{name} is also a sweep axis (axes.{name}): give one of them")
    for value in spec.axes.get("deviation_deg") or []:
        FresnelRequest(kind="fresnel", deviation_deg=value)  # names a deviation out of range
    FresnelRequest(kind="fresnel", **given)  # names a bad option


FIELDS = (
    *result.PATH,
    # its options are inputs (a Fresnel cube's axes)
    result.given("facet_height_um", "um", "height h of every Fresnel facet"),
    result.given("points_per_turn", "1", "control points K on every turn of the quasi-spiral"),
    result.given("deviation_deg", "deg", "rake face turned from the cutting direction"),
    result.count("n_facets", "Fresnel facets the surface is sliced into", "int32"),
    result.number("ez_exact_max_nm", "nm", "largest tool-edge compensation by [2] eq. 10 on the part"),
    result.number("ez_straight_max_nm", "nm", "largest tool-edge compensation by [2] eq. 12 on the part"),
    result.text("facets", "P-V and RMS of every facet's interior, outermost first (predict, not cubes)"),
    result.number("time_constant_s", "s", "machining time at the least constant timestep within the limits"),
    result.number("speedup", "1", "machining time at the constant timestep over that of the adaptive ones"),
)
