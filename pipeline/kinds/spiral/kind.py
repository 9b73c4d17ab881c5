"""Spiral path programs ([4]): points along the tool's spiral placed by a constant angle, a
constant arc length or a chord-error budget, the feed set by the case or by a residual
(cusp) budget, their commands compensated as a table's (model §4) and interpolated linearly
in spindle angle by the line engine (:mod:`ftsweep.engine.simulator`)."""

from __future__ import annotations

import functools
import math
import time
from pathlib import Path
from typing import Any, Optional

import numpy as np

from ftsweep.engine import result
from ftsweep.engine.case import Case, CaseError
from ftsweep.engine.contract import Planning, Simulating, Simulation
from ftsweep.engine.cost import check_capacity
from ftsweep.engine.lines import LineSimulation
from ftsweep.engine.planning import compensator
from ftsweep.engine.record import Timer
from ftsweep.engine.threads import compensate_in_parts
from ftsweep.inputs import catalogs
from ftsweep.kinds.spiral.names import AXES
from ftsweep.kinds.spiral.request import SpiralRequest, request_of
from ftsweep.stages.interpolation import segments, spiral_program
from ftsweep.stages.paths import cusp_budget, spiral
from ftsweep.stages.paths.commanded import CommandedPath


def plan_spiral(
    case: Case,
    surface_spec: Any,
    surface: Any,
    feed_um: float,
    rc: float,
    bound: float,
    program: Optional[tuple[spiral_program.SpiralPath, np.ndarray]] = None,
    machine: Any = None,
    rpm: float = 0.0,
) -> tuple[spiral_program.SpiralPath, dict[str, Any]]:
    """The spiral program of a case ([4]): its points by the request's rule from the
    aperture's circumscribed radius to the centre, and their commands compensated as a
    table's (model §4), with the segments ``machine``'s controller forms between them at
    ``rpm`` (:func:`controller_form`); or the given ``program`` as it stands (no gouge flags)."""
    rho0 = float(catalogs.aperture_of(surface_spec).outer_radius_um)
    if program is not None:
        path, values = program
        values = np.asarray(values, dtype=np.float64)
        if isinstance(path, CommandedPath):  # any program read from a file: cut where it cuts
            return path, {"values": values, "gouge": np.zeros(values.shape, dtype=bool)}
        if path.rho0_um < rho0 * (1.0 - 1e-9):
            raise CaseError(
                f"the program's spiral starts at radius {path.rho0_um / 1e3:.6g} mm, inside the part's "
                f"circumscribed radius {rho0 / 1e3:.6g} mm: its outer ring is never cut"
            )
        return path, {"values": values, "gouge": np.zeros(values.shape, dtype=bool)}

    solve = compensator(case, surface_spec, surface, rc, bound)

    def compensated(phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return compensate_in_parts(
            solve, spiral_program.spiral_radius(phi, rho0, feed_um), np.mod(phi, 2.0 * math.pi)
        )

    rule, value = request_of(case).spiral_rule()
    extra: dict[str, Any] = {}
    mode = machine.interpolation if machine is not None else "linear"
    try:
        if rule == "angle":
            path = spiral.constant_angle(rho0, feed_um, int(value))
        elif rule == "arc":
            path = spiral.constant_arc(rho0, feed_um, value)
        else:
            path, _, errors = spiral.chord_budget(
                rho0, feed_um, value, lambda phi: compensated(phi)[0], cubic=mode != "linear"
            )
            extra["chord_error_um"] = float(errors.max()) if errors.size else 0.0
        if mode == "pvt":
            path = path._replace(phi=_on_time_steps(path, machine.controller, rpm))
        path = _whole_last_block(path, machine, rpm)
    except ValueError as exc:
        raise CaseError(f"spiral program: {exc}") from None
    values, gouge = compensated(path.phi)
    if mode != "linear":
        path, values = controller_form(path, values, machine, rpm)
    return path, {"values": values, "gouge": gouge, **extra}


def _whole_last_block(path: spiral_program.SpiralPath, machine: Any, rpm: float) -> spiral_program.SpiralPath:
    """The path with a last block into the centre shorter than the controller's servo period
    merged into the one before it (:func:`ftsweep.stages.paths.spiral.merged_short_end`), so
    that an export never refuses its own plan; SPLINE1 runs every segment in one time, the
    last too, so its path is left as it is."""
    controller = machine.controller if machine is not None else None
    if controller is None or not controller.servo_period_s or controller.interpolation == "spline1":
        return path
    step = controller.servo_period_s * spiral_program.angular_speed(rpm)
    return path._replace(phi=spiral.merged_short_end(path.phi, step))


def _on_time_steps(path: spiral_program.SpiralPath, controller: Any, rpm: float) -> np.ndarray:
    """The points' angles [rad] on whole time steps of a PVT controller (its time quantum at
    the spindle's angular speed), so every segment's time is a whole number of steps
    (docs/controllers.md); the last point never passes the centre."""
    step = controller.time_quantum_s * spiral_program.angular_speed(rpm)
    phi = segments.quantised(path.phi[:-1], step)
    last = math.floor(float(path.phi[-1]) / step) * step
    if phi.size and not last > phi[-1]:
        raise ValueError("the last two points fall within one controller time step: a slower spindle")
    return np.append(phi, last)


def controller_form(
    path: spiral_program.SpiralPath, values: np.ndarray, machine: Any, rpm: float
) -> tuple[spiral_program.SpiralPath, np.ndarray]:
    """The path with the segments the machine's controller forms between its points
    (docs/controllers.md) and the commands [µm] it passes through: PVT the natural spline
    through the points (the velocities export writes), SPLINE1 the uniform B-spline whose
    way-points are the points (its control points are what export writes). Refuses (CaseError)
    a segment time the controller cannot run (its profile's rule,
    :meth:`ftsweep.inputs.controllers.Controller.segment_refusal`)."""
    ctrl = machine.controller
    if ctrl.one_segment_time and path.rule != "angle":
        raise CaseError(
            f"SPLINE1 segments all take one time, so its points are evenly spaced in C: the {path.rule} "
            "rule's are not; use the points_per_rev rule with 60000/(rpm·T) points per revolution"
        )
    why = ctrl.segment_refusal(np.diff(path.phi) / spiral_program.angular_speed(rpm))
    if why and ctrl.one_segment_time:
        why += " (use the points_per_rev rule with 60000/(rpm·T) points per revolution, T in ms)"
    if why:
        raise CaseError(why)
    if ctrl.interpolation == "pvt":
        d0, d1 = segments.natural_spline(path.phi, values)
        return path._replace(interpolation="pvt", d0=d0, d1=d1), values
    way, d0, d1 = segments.bspline_segments(segments.control_points(values))
    return path._replace(interpolation="spline1", d0=d0, d1=d1), way


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
    slope, second = cusp_budget.section_curvature(surface, rho, ct, st, 0.25 * step)
    inside = aperture.contains_polar(rho, ct, st)
    radius = cusp_budget.signed_radius_um(slope, second)
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
    over the part of :func:`ftsweep.stages.paths.cusp_budget.feed_for_cusp`. Refuses a part with a
    concave section tighter than the nose radius, where no feed meets the budget."""
    radius, slope, x, y = sections
    if not residual_um < rc:
        raise CaseError(f"the residual budget {residual_um:g} µm must be below the nose radius {rc:g} µm")
    feeds = cusp_budget.feed_for_cusp(residual_um, rc, radius, slope)
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
    curvature (the inverse of [4] eq. 2, :func:`ftsweep.stages.paths.cusp_budget.cusp_for_feed`)."""
    radius, slope, _, _ = sections
    cusp = cusp_budget.cusp_for_feed(feed_um, rc, radius, slope)
    return float(np.nanmax(cusp)) if np.isfinite(cusp).any() else math.nan


def request_at(spec: Any, value: dict[str, float]) -> SpiralRequest:
    return SpiralRequest(
        kind="spiral",
        **{k: (int(round(v)) if k == "points_per_rev" else v) for k, v in value.items() if k in AXES},
    )


def feed(case: Case, cutting: Any, rc: float, surface_spec: Any, folder: Any, program: Any) -> float:
    """A given program's feed, else the one the residual budget sets ([4] eq. 1), else the
    case's or the cutting entry's [µm/rev]."""
    if program is not None:
        return float(program[0].feed_um)
    residual_um = request_of(case).residual_um
    if residual_um is not None:
        if case.feed_um is not None:
            raise CaseError("give either a feed or a residual budget (which sets the feed), not both")
        sections = section_samples(surface_spec, folder)
        return residual_feed_um(sections, residual_um, rc, case.surface)
    return case.feed_of(cutting)


def spiral_points(case: Case, surface_spec: Any, feed_um: float) -> float:
    """Points a spiral request's rule gives, estimated before planning ([4]): Np per
    revolution times ρ0/F for the angle rule, the path length over the step for the arc
    rule; 0 for the chord rule (known only once sampled;
    :func:`ftsweep.stages.paths.spiral.chord_budget` bounds its own sampling)."""
    rho0 = float(catalogs.aperture_of(surface_spec).outer_radius_um)
    rule, value = request_of(case).spiral_rule()
    if rule == "angle":
        return float(value * rho0 / feed_um)
    if rule == "arc":
        return float(spiral_program.path_length_um(rho0, feed_um) / value)
    curvature = catalogs.curvature_bound(surface_spec)
    if curvature is not None and math.isfinite(curvature):
        # a chord of length s on a curve of curvature ≤ K deviates by ≤ K·s²/8 ([4] eq. 4), so
        # the budget needs points no closer than sqrt(8Δ/K): an upper estimate of the count,
        # refused only when even a tenth of it is over the capacity
        estimate = spiral_program.path_length_um(rho0, feed_um) * math.sqrt(curvature / (8.0 * value))
        return estimate / CHORD_ESTIMATE_MARGIN
    return 0.0


# the chord rule's up-front count (an upper estimate) is divided by this before the capacity check
CHORD_ESTIMATE_MARGIN = 10.0


def _check_estimate(case: Case, surface_spec: Any, feed_um: float, capacity: int) -> None:
    """Refuse a spiral whose rule's estimated point count is over the controller's capacity."""
    chord = request_of(case).chord_um
    note = " (estimated: a tenth of the count the curvature bound allows)" if chord else ""
    estimate = spiral_points(case, surface_spec, feed_um)
    check_capacity(case, "spiral program", estimate, capacity, note)


def plan(p: Planning) -> tuple[spiral_program.SpiralPath, dict[str, Any]]:
    """The points and commands, refused up front when the rule's estimated count is over the
    controller's capacity; the residual error the feed leaves."""
    t = time.perf_counter()
    case = p.case
    _check_estimate(case, p.surface_spec, p.feed_um, p.machine.capacity_points)
    path, extra = plan_spiral(
        case,
        p.surface_spec,
        p.surface,
        p.feed_um,
        p.nose_radius_um,
        p.gradient_bound,
        p.program,
        p.machine,
        p.cutting.spindle_rpm,
    )
    sections = section_samples(p.surface_spec, p.catalog_folder)
    extra["residual_error_um"] = residual_error_um(sections, p.feed_um, p.nose_radius_um)
    extra["plan_seconds"] = time.perf_counter() - t
    return path, extra


def record_fields(rcase: Any) -> dict[str, Any]:
    case, layout = rcase.case, rcase.layout
    # a program read from a file follows no rule of its own request's
    rule, value = ("program", math.nan) if isinstance(layout, CommandedPath) else case.layout.spiral_rule()
    return {
        "spiral_rule": rule,
        "points_per_rev": value if rule == "angle" else math.nan,
        "arc_um": value if rule == "arc" else math.nan,
        "chord_um": value if rule == "chord" else math.nan,
        "residual_um": case.layout.residual_um or math.nan,
        "revolutions": layout.revolutions,
        "dphi_deg": layout.dphi_deg,
        "ds_um": layout.ds_um,
        "chord_error_nm": rcase.chord_error_um * 1e3,
        "residual_error_nm": rcase.residual_error_um * 1e3,
    }


def cost(case: Case, surface: Any, catalog_folder: Any, feed: float) -> tuple[float, Any]:
    """A spiral's points (and with a chord budget its angular sampling) are only known once
    planned: its cost is its simulated nodes at the part's outer circumference, and its lines
    are its own. Refused (CaseError) when the rule's estimated count is over the controller's
    capacity, as its planning would refuse it."""
    machine = catalogs.entry("machines", case.machine, catalog_folder)
    _check_estimate(case, surface, feed, machine.capacity_points)
    rho0 = catalogs.aperture_of(surface).outer_radius_um
    return 3.0 * 2.0 * math.pi * rho0 * rho0 / feed, None


def pitch_text(r: dict[str, Any]) -> str:
    return f"mean Δφ = {r['dphi_deg']:.4g}°, mean Δs = {r['ds_um']:.4g} µm"


def point_text(path: spiral_program.SpiralPath, flat: int) -> str:
    rho, theta = float(path.rho[flat]), float(path.theta[flat])
    return f"spiral point {flat} (ρ = {rho:.6g} µm, C = {math.degrees(theta):.6g}°)"


def describe(r: dict[str, Any]) -> list[str]:
    """The spiral's points by its rule, its steps and its feed (``predict``)."""
    rule = {
        "angle": f"{r['points_per_rev']:g} points per revolution",
        "arc": f"a point every {r['arc_um']:g} µm of path",
        "chord": f"chord budget {r['chord_um']:g} µm (largest chord error {r['chord_error_nm']:.1f} nm)",
        "program": "as the program file places them",
    }[r["spiral_rule"]]
    budget = (
        f"from the residual budget {r['residual_um']:g} µm" if math.isfinite(r["residual_um"]) else "given"
    )
    return [
        f"program      spiral: {r['n_points']:,} points, {rule}",
        f"steps        mean Δφ = {r['dphi_deg']:.4g}°, mean Δs = {r['ds_um']:.4g} µm along the path, "
        f"{r['revolutions']:.4g} revolutions  (α = {r['aspect_actual']:.4g} µm/deg)",
        f"feed         {r['feed_um']:.4g} µm/rev ({budget if r['spiral_rule'] != 'program' else 'median'}); "
        "largest residual (cusp) "
        f"{r['residual_error_nm']:.1f} nm from the section curvature",
    ]


def check_sweep(spec: Any) -> None:
    """Exactly one rule axis; the residual budget sets the feed, so not both."""
    rules = [n for n in AXES[:3] if spec.axes.get(n) is not None]
    if len(rules) != 1:
        raise ValueError(
            "a spiral sweep needs exactly one rule axis: points_per_rev, arc_um or chord_um "
            f"(got {', '.join(rules) or 'none'})"
        )
    if spec.axes.get("residual_um") is not None and spec.axes.feed_um is not None:
        raise ValueError("axes.residual_um sets the feed: give it or axes.feed_um, not both")


def simulation(inputs: Simulating, timer: Timer) -> Simulation:
    """The line engine for a planned spiral; a program read from a file (a
    :class:`CommandedPath`) is sampled on rays by the passes it makes."""
    if isinstance(inputs.rcase.layout, CommandedPath):
        from ftsweep.kinds.spiral.commanded import CommandedSimulation

        return CommandedSimulation(inputs, timer)
    return LineSimulation(inputs, timer)


FIELDS = (
    result.text("spiral_rule", "spiral sampling rule: angle, arc or chord"),
    # the rule's parameters are inputs (a spiral cube's axes), not stored per case
    result.given("points_per_rev", "1", "points per revolution of the constant-angle rule"),
    result.given("arc_um", "um", "path length between points of the constant-arc rule"),
    result.given("chord_um", "um", "chord-error budget of the chord rule"),
    result.given("residual_um", "um", "residual (cusp) budget that set the feed"),
    *result.PATH,
    result.number("chord_error_nm", "nm", "largest chord deviation from the compensated path"),
    result.number(
        "residual_error_nm",
        "nm",
        "largest residual (cusp) height from the feed and the section curvature",
    ),
    result.aspect_actual("um/deg"),
    *result.SPINDLE,
)
