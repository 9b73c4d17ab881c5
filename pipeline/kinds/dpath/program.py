"""D-shaped slow-tool-servo programs ([5]): planning a case's path, its axis motion, and
its form error through the engine's envelope (model §4–§6).

The part is mounted off-axis in the cutting zone (its centre ``offaxis_um`` from the C axis,
turned so the cuts run along ``cut_angle_deg`` of the part's frame). The nose arc lies in
the XZ plane, the plane through the spindle axis and the tool: a point of the part is cut
only by tool positions on its own radial line. So the machined surface is still the lower
envelope of the arcs along rays from the axis (model §5); on a ray at θ the program passes
once per revolution, at φ = θ + 2πc, where it crosses the cut of that revolution (or, near
the zone's ends, its transition). Crossings are taken from the program as the machine
moves (X and Z linear between points), so the points per cut and the transitions act on the
result. The rays span the zone, the evaluation nodes lie between the cuts (``points_per_feed``
per spacing along d), and only the fully machined part is evaluated: an edge band (one
spacing plus the nose's contact window) off the first and last cut and off the cuts' ends
is excluded, as the spiral's outer edge is; in it the turn-round's arcs overhang the part.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any, NamedTuple, Optional

import numpy as np

from ftsweep.engine.case import CaseError
from ftsweep.engine.record import non_finite, simulated
from ftsweep.engine.simulator import ExactRows, Machined, exact_at_passes, require_finite
from ftsweep.inputs import catalogs
from ftsweep.stages.envelope import arcs as envelope
from ftsweep.stages.interpolation import compensation, rays, timed_path
from ftsweep.stages.kinematics import axes as kinematics
from ftsweep.stages.paths import dpath, dpath_motion

DEFAULTS: dict[str, Any] = {
    "points_per_cut": 201,
    "transition": "optimised",
    "zones": 1,
    "offaxis_um": 30000.0,
    "cut_angle_deg": 90.0,
    "transition_step_deg": 1.0,
    "timing": "spindle",
}
RAYS_PER_BATCH = 64


def option(request: Any, name: str) -> Any:
    """A D-path option of a layout request, or its default (:data:`DEFAULTS`)."""
    value = getattr(request, name, None)
    return DEFAULTS[name] if value is None else value


def rotation_of(request: Any) -> float:
    """Rotation [rad] of the part on the chuck that lays its ``cut_angle_deg`` along the cuts."""
    return math.radians(float(option(request, "cut_angle_deg")) - 90.0)


def geometry_of(request: Any, aperture: Any, spacing_um: float) -> dpath.DGeometry:
    """The zone of a part: its extent along and across the cuts (the part fills it, [5]),
    centred ``offaxis_um`` from the C axis."""
    half_w, half_h = aperture.half_extent_um
    along, across = dpath_motion.zone_of(half_w, half_h, rotation_of(request))
    return dpath.DGeometry(
        length_um=along,
        width_um=across,
        outer_um=float(option(request, "offaxis_um")) + 0.5 * across,
        spacing_um=float(spacing_um),
        zones=int(option(request, "zones")),
        transition=str(option(request, "transition")),
    )


def part_surface(request: Any, geometry: dpath.DGeometry, surface: Callable[..., Any]) -> Callable[..., Any]:
    """The part's surface callable in the spindle frame (zone 0)."""
    return dpath_motion.placed(surface, geometry.centre_um, rotation_of(request))


def plan(
    request: Any,
    aperture: Any,
    surface: Callable[..., Any],
    spacing_um: float,
    rc: float,
    compensate: Callable[[Callable[..., Any], np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
    program: Optional[tuple[dpath.DPath, np.ndarray]] = None,
    max_points: float = math.inf,
) -> tuple[dpath.DPath, dict[str, Any]]:
    """The D-path program of a request ([5]): the path, Z [µm] of every point (the cut
    points compensated as a table's, model §4, along the radial section at the tool; the
    transitions linear between cuts, [5] eq. 14) and the gouge flags; or ``program``
    (path, Z) as it stands, e.g. read back from an exported file."""
    if program is not None:
        path, values = program
        values = np.asarray(values, dtype=np.float64)
        return path, {"values": values, "gouge": np.zeros(values.shape, dtype=bool)}
    geometry = geometry_of(request, aperture, spacing_um)
    path = dpath.plan(
        geometry,
        int(option(request, "points_per_cut")),
        float(option(request, "transition_step_deg")),
        max_points,
    )
    on = path.cut >= 0
    # every zone holds the same part: a cut point is compensated in its zone's own frame
    local = path.phi[on] - path.cut_centre[path.cut[on]]
    z_cut, gouge_cut = compensate(part_surface(request, geometry, surface), path.rho[on], local)
    gouge = np.zeros(path.n_points, dtype=bool)
    gouge[on] = gouge_cut
    return path, {"values": dpath_motion.transition_z(path, z_cut), "gouge": gouge}


def times(
    path: dpath.DPath, z_um: np.ndarray, rpm: float, mode: str = "spindle", feed_mm_min: float = math.nan
) -> np.ndarray:
    """Time [s] of every point (:func:`ftsweep.stages.paths.dpath.point_times`)."""
    return dpath_motion.point_times(path.phi, path.rho, z_um, mode, rpm, feed_mm_min)


def run_times(path: dpath.DPath, z_um: np.ndarray, rpm: float) -> np.ndarray:
    """The times [s] a path's points run at: its own (a program file's lines, a PVT
    controller's whole steps) or those of the constant spindle speed (:func:`times`)."""
    return times(path, z_um, rpm) if path.t_s is None else path.t_s


def pvt_form(path: dpath.DPath, z_um: np.ndarray, rpm: float, controller: Any) -> dpath.DPath:
    """The D path as a PVT controller runs it (docs/controllers.md): its points where they
    were planned, their times at the spindle speed rounded to the controller's whole time
    steps, and each segment the cubic Hermite in time through C, X and Z with each point's
    local slope on its cut or transition as its velocity, a corner taking the cut's
    (:func:`corners`; the velocities export writes, :func:`ftsweep.stages.interpolation.timed_path.tangents`).
    Refuses (ValueError) two points within one step or a segment over the controller's longest."""
    t = timed_path.on_time_steps(times(path, z_um, rpm), controller.time_quantum_s, controller.max_segment_s)
    chan = np.column_stack([path.phi, path.rho, z_um])
    at, left = corners(path)
    return path._replace(t_s=t, tangents=timed_path.tangents(t, chan, at, left))


def corners(path: dpath.DPath) -> tuple[np.ndarray, np.ndarray]:
    """The points where a cut meets a transition (the cuts' end points, where X and Z may
    change slope: the transitions' Z is not the cut's, [5] eq. 14), inside the path, and
    whether each is the end of a cut (its velocity the cut's, before it) or a start."""
    cut = path.cut
    ends = np.flatnonzero((cut[:-1] >= 0) & (cut[1:] != cut[:-1]))
    starts = np.flatnonzero((cut[1:] >= 0) & (cut[1:] != cut[:-1])) + 1
    at = np.concatenate([ends, starts])
    left = np.concatenate([np.ones(ends.size, bool), np.zeros(starts.size, bool)])
    inside = (at > 0) & (at < cut.size - 1)
    order = np.argsort(at[inside], kind="stable")
    return at[inside][order], left[inside][order]


# the axes of a D-path program, in the order of the kinematics stage's columns
AXES = ("C", "X", "Z")


def period_of(machine: Any) -> float:
    """The controller's command period [s] (1/``command_rate_hz`` of the machine), the step in
    time over which a D path's axis accelerations are formed (model §6)."""
    return 1.0 / float(machine.command_rate_hz)


def sampled_motion(
    path: dpath.DPath, z_um: np.ndarray, t_points: np.ndarray, period_s: float, until_s: float = math.inf
) -> tuple[dpath_motion.Sampled, np.ndarray, kinematics.Motion]:
    """The program's planned path sampled every controller period up to ``until_s`` [s]
    (:func:`ftsweep.stages.paths.dpath.at_period`), its axes q (:func:`axes_of`) and their motion
    by the kinematics stage."""
    s = dpath_motion.at_period(path, z_um, t_points, period_s, until_s)
    q = axes_of(s)
    return s, q, kinematics.motion(s.t, q)


def axes_of(s: dpath_motion.Sampled) -> np.ndarray:
    """The axes q (C [rad], X, Z [m]) of samples ``s``, the columns of :data:`AXES`."""
    q = np.empty((s.t.size, 3))
    q[:, 0] = s.phi
    # written in place: millions of samples, no stacked copies
    np.multiply(s.rho, 1e-6, out=q[:, 1])
    np.multiply(s.z, 1e-6, out=q[:, 2])
    return q


# samples of the planned path taken at a time by :func:`sampled_extremes`: a stretch's
# arrays stay in the core's caches, and no array of the millions of samples is formed
SAMPLE_BLOCK = 65536


class PeriodSamples(NamedTuple):
    """The planned path's samples every controller period, as :class:`ftsweep.stages.paths.dpath.
    Sampled` names them in messages, without their arrays: ``n`` uniform times from ``first``
    to ``last`` [s] over the program's points at times ``t_points`` [s]."""

    first: float
    last: float
    n: int
    t_points: np.ndarray

    def time(self, i: int) -> float:
        """Time of sample ``i`` [s] (that of ``Sampled.t[i]``)."""
        return float(dpath_motion.period_times(self.first, self.last, self.n, i, i + 1)[0])

    def line(self, i: int) -> int:
        """The program line (0-based point) sample ``i`` follows."""
        return dpath_motion.line_at(self.t_points, self.time(i))


def sampled_extremes(
    path: dpath.DPath, z_um: np.ndarray, t_points: np.ndarray, period_s: float
) -> tuple[PeriodSamples, kinematics.Extremes, tuple[float, float]]:
    """The extremes of the motion of the program's planned path sampled every controller
    period (as :func:`sampled_motion`), the samples on a cut in group 1 and the rest in group
    0, and the lowest and highest X [µm]: the samples formed :data:`SAMPLE_BLOCK` at a time,
    each stretch with its neighbours, and their extremes carried from one to the next
    (:class:`ftsweep.stages.kinematics.axes.ExtremesOver`): the values and first points of one
    pass over every sample, without the millions of samples' arrays."""
    first, last, n = dpath_motion.period_grid(t_points, period_s)
    z = dpath_motion.z_plan(path, z_um)
    over = kinematics.ExtremesOver(n, len(AXES), 2)
    x_low, x_high = math.inf, -math.inf
    for lo in range(0, n, SAMPLE_BLOCK):
        hi = min(lo + SAMPLE_BLOCK, n)
        a, b = max(lo - 1, 0), min(hi + 1, n)
        s = dpath_motion.sample_path(path, z, t_points, dpath_motion.period_times(first, last, n, a, b))
        over.add(axes_of(s), kinematics.steps_of(s.t), s.on_cut, lo - a, hi - a, a)
        own = s.rho[lo - a : hi - a]
        x_low, x_high = min(x_low, float(own.min())), max(x_high, float(own.max()))
    return PeriodSamples(first, last, n, np.asarray(t_points)), over.out, (x_low, x_high)


def motion_summary(
    path: dpath.DPath, z_um: np.ndarray, rpm: float, machine: Any
) -> tuple[dict[str, float], str]:
    """Ranges and peaks of the motion at constant spindle speed ([5] eqs. 5–6) on the planned
    path sampled every controller period of ``machine`` (:func:`period_of`; the C step it
    makes is ``accel_step_deg``): X range, feed and acceleration (overall, on the cuts and in
    the transitions), Z velocity and acceleration (peak and RMS), the largest dρ/dθ jump at a
    junction and the machining time; and the machine's limits the motion exceeds ('' when it
    fits them, :func:`limits_reason`). A path with its points' times (``t_s``, a program file's
    lines) is timed by them, and checked with the slack their printed digits need."""
    t = run_times(path, z_um, rpm)
    period = period_of(machine)
    s, e, (x_min, x_max) = sampled_extremes(path, z_um, t, period)
    jumps = dpath_motion.junctions(path)
    summary = {
        "x_min_um": x_min,
        "x_max_um": x_max,
        "x_feed_peak_mm_s": float(e.speed[1] * 1e3),
        "x_accel_peak_m_s2": float(e.accel[1]),
        "z_velocity_peak_mm_s": float(e.speed[2] * 1e3),
        "z_accel_peak_m_s2": float(e.accel[2]),
        "z_accel_rms_m_s2": math.sqrt(float(e.accel_sq[2]) / s.n),
        "x_accel_cut_m_s2": float(e.accel_group[1, 1]),
        "x_accel_transition_m_s2": float(e.accel_group[0, 1]),
        "slope_jump_um_rad": float(np.abs(jumps["jump_d1"]).max()) if jumps["jump_d1"].size else 0.0,
        "machining_s": float(t[-1]),
        "accel_period_s": period,
        "accel_step_deg": math.degrees(rpm * 2.0 * math.pi / 60.0 * period),
    }
    # a file's lines are checked as export checked them before writing (the same numbers, the
    # same samples, slack 1e-6): verify refuses nothing export let through
    return summary, limits_reason(machine, s, e, 1e-9 if path.t_s is None else 1e-6)


NO_AXES = "the machine declares no X, Z, C axis limits (axes:) for a slow-tool-servo program"


def limits_reason(
    machine: Any, s: dpath_motion.Sampled | PeriodSamples, e: kinematics.Extremes, slack: float = 1e-9
) -> str:
    """The machine's X, Z and C limits the sampled motion of samples ``s`` (extremes ``e``)
    exceeds, checked by the kinematics stage on every sample and named by the program line
    it follows ('' when it fits them); a machine without axis limits cannot run a D path.
    ``slack``: relative allowance (rounding of a spindle speed at its limit; the printed
    digits of a program read back)."""
    if machine.axes is None:
        return NO_AXES

    def where(i: int) -> str:
        return f"line {s.line(i) + 1}, t = {s.time(i):.4f} s"

    return kinematics.extremes_reason(e, machine.axes.limits(AXES), slack, where)


def ray_angles(geometry: dpath.DGeometry, n: int) -> np.ndarray:
    """``n`` ray angles [rad] evenly inside the zone's angular span (that of its widest,
    innermost cut)."""
    span = float(geometry.half_angle(geometry.inner_um))
    return (np.arange(n) + 0.5) / n * 2.0 * span - span


def n_rays(path: dpath.DPath, resolution: Any) -> int:
    """Rays over the zone: ``n_theta`` if set, else ``samples_per_cell`` per point step of the
    innermost (widest) cut."""
    if resolution.n_theta is not None:
        return int(resolution.n_theta)
    return int(resolution.samples_per_cell * (path.points_per_cut - 1))


class DPathSimulation:
    """The batches of rays of a D-path case (module docstring; model §5–§6), the simulation
    of its kind (:class:`ftsweep.engine.contract.Simulation`): rays across the zone, on each the passes
    of the program crossing it, the machined nodes between the cuts (``points_per_feed`` per
    spacing) off an edge band of one spacing plus the nose's contact window, and the part's
    surface in its frame."""

    def __init__(self, s: Any, timer: Any) -> None:
        rcase = s.rcase
        path: dpath.DPath = rcase.layout
        g = path.geometry
        request, res, rc = rcase.case.layout, rcase.case.resolution, rcase.nose_radius_um
        assert rcase.values is not None and rcase.gouge is not None
        self.z_prog = rcase.values
        # a PVT program's channels C, X, Z for the cubic crossings, stacked once for every batch
        self.chan = None if path.tangents is None else np.column_stack([path.phi, path.rho, self.z_prog])
        require_finite(
            self.z_prog, "the D-path Z", lambda i: f"point {i} (C {math.degrees(path.phi[i]):.4f}°)"
        )
        self.rcase, self.path = rcase, path
        self.band = g.spacing_um + compensation.contact_window_um(rcase.gradient_bound, rc)
        ppf = res.points_per_feed
        self.d_nodes = g.outer_um - np.arange((g.n_cycles - 1) * ppf + 1)[::-1] * (g.spacing_um / ppf)
        self.machined = (self.d_nodes >= g.inner_um + self.band) & (self.d_nodes <= g.outer_um - self.band)
        self.surface = part_surface(request, g, rcase.surface)
        self.rotation = rotation_of(request)
        self.curvature = catalogs.curvature_bound(rcase.surface_spec)
        self.zone_split_um = res.zone_split * rcase.aperture.inner_radius_um
        self.rays = ray_angles(g, n_rays(path, res))
        self.n_batches = math.ceil(self.rays.size / RAYS_PER_BATCH)

    def batch(self, b: int, timer: Any) -> Any:
        """Batch ``b`` of rays through sampling, exact commands and the envelope of the
        passes' arcs (model §5)."""
        theta = self.rays[b * RAYS_PER_BATCH : (b + 1) * RAYS_PER_BATCH]
        rcase, g = self.rcase, self.path.geometry
        t = time.perf_counter()
        pos, w, valid, on_cut = _crossings(self.path, self.z_prog, theta, self.chan)
        n_valid = valid.sum(axis=1).astype(np.int64)
        ct, st = np.cos(theta)[:, None], np.sin(theta)[:, None]
        # the fully machined part: the edge band off the first and last cut and off the cuts'
        # ends, where the turn-round's arcs overhang the part
        side = np.abs(self.d_nodes[None, :] * (st / ct)) <= 0.5 * g.length_um - self.band
        query = np.where(self.machined[None, :] & side, self.d_nodes[None, :] / ct, np.nan)
        px, py = dpath_motion.to_part(query * ct, query * st, g.centre_um, self.rotation)
        inside = rcase.aperture.contains(px, py) & np.isfinite(query)
        f = np.zeros(query.shape)
        f[inside] = rcase.surface(px[inside], py[inside])[0]
        t = timer.add("sampling", t)
        w_exact = self._exact(pos, w, on_cut, theta)
        t = timer.add("compensation", t)
        rc = rcase.nose_radius_um
        z, cusp_r, cusp_z = envelope.machined_rows(pos, w, n_valid, rc, query)
        exact = None if w_exact is None else ExactRows(pos, w, w_exact, n_valid, rc, query, z)
        t = timer.add("envelope", t)
        cusp_f, cusp_in, cusp_dist = self._cusps(cusp_r, ct, st)
        timer.add("metrics", t)
        return Machined(z, f, inside, np.hypot(px, py), px, py, cusp_z, cusp_f, cusp_in, cusp_dist, exact)

    def _exact(self, pos: np.ndarray, w: np.ndarray, on_cut: np.ndarray, theta: np.ndarray) -> Any:
        """The exact commands of the passes on a cut (the transitions' own Z elsewhere), or
        None when the case asks the exact envelope off."""
        rcase = self.rcase
        if not rcase.case.resolution.interp_error:
            return None
        return exact_at_passes(rcase, self.surface, pos, theta, on_cut, w, self.curvature)

    def _cusps(self, cusp_r: np.ndarray, ct: np.ndarray, st: np.ndarray) -> tuple[np.ndarray, ...]:
        """The design at the cusp peaks between passes, which lie inside the fully machined
        part, and their distance from the part's centre [µm]."""
        rcase, g = self.rcase, self.path.geometry
        cx, cy = dpath_motion.to_part(cusp_r * ct, cusp_r * st, g.centre_um, self.rotation)
        d_cusp = cusp_r * ct
        cusp_in = (
            rcase.aperture.contains(cx, cy)
            & (d_cusp >= g.inner_um + self.band)
            & (d_cusp <= g.outer_um - self.band)
            & (np.abs(cusp_r * st) <= 0.5 * g.length_um - self.band)
            & np.isfinite(cusp_r)
        )
        fc = np.full(cusp_r.shape, np.nan)
        fc[cusp_in] = rcase.surface(cx[cusp_in], cy[cusp_in])[0]
        return fc, cusp_in, np.hypot(cx, cy)

    def record(self, errors: dict[str, float], timer: Any) -> dict[str, Any]:
        """The record: the shared fields, the D path's own and its axis motion against the
        machine's limits (:func:`record_fields`)."""
        rcase, path = self.rcase, self.path
        bad = non_finite(rcase, errors)
        if bad:
            raise CaseError(
                f"the metrics came out non-finite ({', '.join(bad)}): no evaluation point inside the "
                "fully machined part; check the part against the spacing and the nose radius"
            )
        t = time.perf_counter()
        summary, reason = motion_summary(path, self.z_prog, rcase.cutting.spindle_rpm, rcase.machine)
        timer.add("dynamics", t)
        record: dict[str, Any] = {"surface": rcase.case.surface, "layout": "dpath", "n_points": path.n_points}
        record.update(simulated(rcase, errors, self.rays.size, self.band, rcase.gouge))
        record.update(record_fields(rcase, summary, self.z_prog, reason))
        return record


def _crossings(
    path: dpath.DPath, z_prog: np.ndarray, theta: np.ndarray, chan: Optional[np.ndarray] = None
) -> tuple[np.ndarray, ...]:
    """The passes crossing each ray, sorted by position: positions [µm], commands [µm],
    validity and whether each lies on a cut (both neighbouring points on it). ``chan``: a
    PVT program's C, X, Z columns, its segments cubic in time (None: linear)."""
    if chan is None:
        pos, w, seg = rays.crossings(path.phi, path.rho, z_prog, theta)
    elif path.tangents is None:
        raise ValueError("a D path timed as PVT segments needs its velocities (tangents)")
    else:
        pos, w, seg = timed_path.crossings(path.phi, chan, path.tangents, theta)
    order = np.argsort(np.where(np.isnan(pos), np.inf, pos), axis=1)
    pos = np.take_along_axis(pos, order, axis=1)
    w = np.take_along_axis(w, order, axis=1)
    seg = np.take_along_axis(seg, order, axis=1)
    valid = np.isfinite(pos)
    # passes on a cut carry compensated commands; the transitions' Z is the program's own
    # interpolation ([5] eq. 14), exact as it stands
    step = np.maximum(seg, 0)
    on_cut = (
        valid & (path.cut[step] >= 0) & (path.cut[step] == path.cut[np.minimum(step + 1, path.n_points - 1)])
    )
    return pos, w, valid, on_cut


def record_fields(rcase: Any, summary: dict[str, float], z_um: np.ndarray, reason: str) -> dict[str, Any]:
    """The D-path fields of a case record ([5]; declared in :mod:`ftsweep.engine.result`); ``reason``:
    the limits the motion exceeds (:func:`motion_summary`)."""
    path: dpath.DPath = rcase.layout
    g, request = path.geometry, rcase.case.layout
    step = np.diff(path.phi)
    return {
        "spacing_um": g.spacing_um,
        "points_per_cut": path.points_per_cut,
        "transition": g.transition,
        "zones": g.zones,
        "offaxis_um": g.centre_um,
        "cut_angle_deg": float(option(request, "cut_angle_deg")),
        "n_cuts": path.n_cuts,
        "cut_length_um": g.length_um,
        "cut_width_um": g.width_um,
        "cut_step_um": path.cut_step_um,
        "revolutions": path.revolutions,
        "dphi_deg": float(np.degrees(step.mean())),
        "ds_um": float(np.mean(np.hypot(np.diff(path.rho), 0.5 * (path.rho[1:] + path.rho[:-1]) * step))),
        **{
            k: v
            for k, v in summary.items()
            if k not in ("z_velocity_peak_mm_s", "z_accel_peak_m_s2", "z_accel_rms_m_s2")
        },  # noqa: E501
        "stroke_um": float(np.max(z_um) - np.min(z_um)),
        "w_velocity_peak_mm_s": summary["z_velocity_peak_mm_s"],
        "w_accel_peak_m_s2": summary["z_accel_peak_m_s2"],
        "w_accel_rms_m_s2": summary["z_accel_rms_m_s2"],
        "feasible": int(not reason),
        "infeasible_reason": reason,
    }
