"""D-shaped slow-tool-servo programs ([5]): straight parallel cuts over an off-axis part, one
per revolution, joined by transitions outside it; planned by :func:`ftsweep.kinds.dpath.program.plan`, the
cut points compensated as a table's (model §4), and simulated by the one simulator on rays
across the zone that the path's passes cross (:class:`ftsweep.kinds.dpath.program.DPathSimulation`)."""

from __future__ import annotations

import hashlib
import math
import time
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any, Optional

import numpy as np

from ftsweep.engine import result
from ftsweep.engine.case import Case, CaseError
from ftsweep.engine.contract import Planning
from ftsweep.engine.planning import compensator
from ftsweep.engine.threads import compensate_in_parts
from ftsweep.inputs import catalogs
from ftsweep.kinds.dpath.names import AXES
from ftsweep.kinds.dpath.request import DPathRequest, request_of

# compensated cut points kept for the plans made inside :func:`shared_cuts` (None: not kept)
_SHARED_CUTS: ContextVar[Optional[dict[tuple[Any, ...], tuple[np.ndarray, np.ndarray]]]] = ContextVar(
    "dpath_shared_cuts", default=None
)


@contextmanager
def shared_cuts() -> Iterator[None]:
    """Within the block, D-path plans whose cut points are the same points of the same part,
    compensated the same way, compensate them once: the traditional and the optimised path of
    one part differ only in their transitions (a D-path study plans both; [5]). The values are
    those a plan computes on its own; they are dropped when the block ends."""
    token = _SHARED_CUTS.set({})
    try:
        yield
    finally:
        _SHARED_CUTS.reset(token)


def _cuts_key(
    case: Case, surface_spec: Any, rc: float, bound: float, rho: np.ndarray, theta: np.ndarray
) -> tuple[Any, ...]:
    """Everything the compensated cut points depend on but the transition: the case (its
    request without the transition: the part's placement), the surface entry, the arc, the
    gradient bound and the points themselves (their bytes' digest)."""
    layout = case.layout.model_copy(update={"transition": None})
    points = hashlib.blake2b(np.ascontiguousarray(rho).tobytes(), digest_size=16)
    points.update(np.ascontiguousarray(theta).tobytes())
    return (
        case.model_copy(update={"layout": layout}).model_dump_json(),
        surface_spec.model_dump_json(),
        rc,
        bound,
        rho.size,
        points.hexdigest(),
    )


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
    """The D-path program of a case ([5], :func:`ftsweep.kinds.dpath.program.plan`): its cut points
    compensated as a table's (model §4), or the given ``program`` as it stands. A path of
    more than ``max_points`` points is refused before it is made."""

    from ftsweep.kinds.dpath import program as dpath_program

    def compensated(part: Any, rho: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        def solve() -> tuple[np.ndarray, np.ndarray]:
            return compensate_in_parts(compensator(case, surface_spec, part, rc, bound), rho, theta)

        kept = _SHARED_CUTS.get()
        if kept is None:
            return solve()
        key = _cuts_key(case, surface_spec, rc, bound, rho, theta)
        if key not in kept:
            kept[key] = solve()
        z, gouge = kept[key]
        return z.copy(), gouge.copy()

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


def request_at(spec: Any, value: dict[str, float]) -> DPathRequest:
    return DPathRequest(
        kind="dpath",
        **(spec.options_of("dpath") or {}),
        **{k: (int(round(v)) if k == "points_per_cut" else v) for k, v in value.items() if k in AXES},
    )


def feed(case: Case, cutting: Any, rc: float, surface_spec: Any, folder: Any, program: Any) -> float:
    """A D path's feed is its spacing between cuts [µm]: a given program's, else the request's,
    the case's or the cutting entry's."""
    if program is not None:
        return float(program[0].geometry.spacing_um)
    return float(request_of(case).spacing_um or case.feed_of(cutting))


def plan(p: Planning) -> tuple[Any, dict[str, Any]]:
    """The D path ([5]); on a PVT machine with the segments its controller forms (cubic in
    time, :func:`ftsweep.kinds.dpath.program.pvt_form`); refused on a SPLINE1 machine, whose
    one segment time TA a D path's points (closer on the cuts than in the transitions) do
    not keep."""
    from ftsweep.kinds.dpath import program as dpath_program

    if p.machine.interpolation == "spline1":
        raise CaseError(
            f"machine '{p.case.machine}' interpolates spline1 (one segment time TA for every point); a D "
            "path's points are not equally spaced in time: a PVT or linear machine (docs/controllers.md)"
        )
    t = time.perf_counter()
    path, extra = plan_dpath(
        p.case,
        p.surface_spec,
        p.surface,
        p.feed_um,
        p.nose_radius_um,
        p.gradient_bound,
        p.program,
        p.machine.capacity_points,
    )
    if p.machine.interpolation == "pvt" and p.program is None:
        try:
            path = dpath_program.pvt_form(path, extra["values"], p.cutting.spindle_rpm, p.machine.controller)
        except ValueError as exc:
            raise CaseError(f"D path (machine '{p.case.machine}'): {exc}") from None
    extra["plan_seconds"] = time.perf_counter() - t
    return path, extra


def record_fields(rcase: Any) -> dict[str, Any]:
    return {}  # the D-path engine writes its own fields (:func:`ftsweep.kinds.dpath.program.record_fields`)


def cost(case: Case, surface: Any, catalog_folder: Any, feed: float) -> tuple[float, Any]:
    """The evaluated nodes (rays × cuts × points per feed); its lines are its own."""
    from ftsweep.kinds.dpath import program as dpath_program

    ap = catalogs.aperture_of(surface)
    ppc = request_of(case).points_per_cut or dpath_program.DEFAULTS["points_per_cut"]
    # its feed is its spacing between cuts (feed)
    return 3.0 * ppc * 2.0 * ap.half_extent_um[0] / feed * case.resolution.points_per_feed, None


def pitch_text(r: dict[str, Any]) -> str:
    return f"mean Δφ = {r['dphi_deg']:.4g}°, mean Δs = {r['ds_um']:.4g} µm"


def point_text(path: Any, flat: int) -> str:
    x, c = float(path.rho[flat]), math.degrees(path.phi[flat])
    return f"D-path point {flat} (X = {x:.6g} µm, C = {c:.6g}°)"


def describe(r: dict[str, Any]) -> list[str]:
    """The D path's cuts, transition and X motion at the spindle speed (``predict``)."""
    verdict = "feasible" if r["feasible"] else f"INFEASIBLE: {r['infeasible_reason']}"
    return [
        f"program      D path: {r['n_points']:,} points, {r['n_cuts']:,} cuts of {r['points_per_cut']:,} "
        f"points ({r['transition']} transitions, {r['zones']:g} zone(s) per revolution)",
        f"zone         {r['cut_length_um'] / 1e3:.4g} × {r['cut_width_um'] / 1e3:.4g} mm, "
        f"{r['offaxis_um'] / 1e3:.4g} mm off-axis; spacing {r['spacing_um']:.4g} µm, "
        f"cut step {r['cut_step_um']:.4g} µm",
        f"X motion     {r['x_min_um'] / 1e3:.4g} … {r['x_max_um'] / 1e3:.4g} mm, peak feed "
        f"{r['x_feed_peak_mm_s']:.3g} mm/s, peak acceleration {r['x_accel_peak_m_s2']:.3g} m/s² "
        f"(cuts {r['x_accel_cut_m_s2']:.3g}, transitions {r['x_accel_transition_m_s2']:.3g}); "
        f"{r['machining_s']:.0f} s: {verdict}",
    ]


def check_sweep(spec: Any) -> None:
    """An axis of its own; the spacing is its feed, so not both; the D-path options valid."""
    if not any(spec.axes.get(n) is not None for n in AXES):
        raise ValueError("a D-path sweep needs an axis: spacing_um and/or points_per_cut")
    if spec.axes.get("spacing_um") is not None and spec.axes.feed_um is not None:
        raise ValueError("axes.spacing_um is the D path's feed: give it or axes.feed_um, not both")
    DPathRequest(kind="dpath", **(spec.options_of("dpath") or {}))  # names a bad option


# its command-line options: the request's fields, the off-axis distance in mm


FIELDS = (
    *result.PATH,
    # its options are inputs (a D-path cube's axes)
    result.given("spacing_um", "um", "spacing h between the D path's cuts"),
    result.given("points_per_cut", "1", "points on every cut of the D path"),
    result.given("transition", None, "turn-round between cuts: traditional (arc) or optimised (quintic)"),
    result.given("zones", "1", "cutting zones per revolution"),
    result.given("offaxis_um", "um", "distance of the part's centre from the C axis"),
    result.given("cut_angle_deg", "deg", "direction of the cuts in the part's frame"),
    result.count("n_cuts", "cuts over all zones"),
    result.number("cut_length_um", "um", "length l of the cuts (the zone along them)"),
    result.number("cut_width_um", "um", "width s of the cutting zone across the cuts"),
    result.number("cut_step_um", "um", "distance between consecutive points of a cut"),
    # the X axis at constant spindle speed ([5] eqs. 5-6)
    result.number("x_min_um", "um", "smallest X (polar radius) of the path"),
    result.number("x_max_um", "um", "largest X (polar radius) of the path, transitions included"),
    result.number("x_feed_peak_mm_s", "mm/s", "peak X feed-rate at the spindle speed"),
    result.number(
        "x_accel_peak_m_s2",
        "m/s^2",
        "peak X acceleration at the spindle speed, formed over the controller's command period",
    ),
    result.number(
        "accel_period_s", "s", "controller command period the D path's accelerations are formed over"
    ),
    result.number("accel_step_deg", "deg", "C step of one command period at the spindle speed"),
    result.number("x_accel_cut_m_s2", "m/s^2", "peak X acceleration on the cuts"),
    result.number("x_accel_transition_m_s2", "m/s^2", "peak X acceleration in the transitions"),
    result.number(
        "slope_jump_um_rad", "um/rad", "largest jump of d(rho)/d(theta) at a junction of cut and transition"
    ),
)
