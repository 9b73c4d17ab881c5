"""Any lathe program as its controller commands it, simulated (docs/controllers.md,
"Predicting any program"): the passes of every cut over rays evenly round the part
(:mod:`ftsweep.stages.paths.commanded`), with the opposite ray's passes near the centre, the
arc envelope of them all (model §5) and the metrics (model §6) on radial nodes over the part
the program machines: from the centre (where its innermost pass reaches it) to its outermost
cut radius less the edge band, for a program read from a file. The spiral kind's simulation
of a :class:`~ftsweep.stages.paths.commanded.CommandedPath`; no spiral of constant feed is
assumed.

Its form error is split by cause (model §6): the *departure* of the program's Z from the
design-compensated tool path (model §4) at its own points, carried along by its
interpolation; the *interpolation* between its blocks (the design-compensated path at the
program's points against the exact one at every pass); what is left is the feed's cusps.
The centre, inside the innermost pass and one band beyond it, is also judged on its own.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Any, NamedTuple, Optional

import numpy as np

from ftsweep.engine.case import CaseError
from ftsweep.engine.cost import check_cost
from ftsweep.engine.record import layer_record, motion_fields, non_finite, simulated
from ftsweep.engine.simulator import ExactRows, Machined, exact_at_passes, require_finite
from ftsweep.inputs import catalogs
from ftsweep.stages.envelope import arcs as envelope
from ftsweep.stages.interpolation import compensation, segments
from ftsweep.stages.kinematics import dynamics
from ftsweep.stages.paths.commanded import CommandedPath, crossings

# rays round the part when the resolution does not set n_theta: samples_per_cell per point
# step of the program's finest revolution, within these bounds
MIN_RAYS, MAX_RAYS = 360, 20_000


class Passes(NamedTuple):
    """The passes over a batch of rays: positions [µm] along each ray (NaN padding last), the
    program's commands [µm], the design-compensated path's at the program's points and the
    exact design's at every pass (None when the case asks the split off), and how many passes
    each ray has."""

    pos: np.ndarray
    w: np.ndarray
    w_design: Optional[np.ndarray]
    w_exact: Optional[np.ndarray]
    n_valid: np.ndarray


class CommandedSimulation:
    """The batches of rays of a program read from a file (module docstring): the simulation
    (:class:`ftsweep.engine.contract.Simulation`) of a case whose layout is a
    :class:`CommandedPath`."""

    def __init__(self, s: Any, timer: Any) -> None:
        rcase = s.rcase
        path: CommandedPath = rcase.layout
        res, rc = rcase.case.resolution, rcase.nose_radius_um
        self.rcase, self.path = rcase, path
        self.z = np.asarray(rcase.values, dtype=np.float64)
        require_finite(self.z, "the program's Z", lambda i: f"point {i + 1}")
        self.band = path.feed_max_um + compensation.contact_window_um(rcase.gradient_bound, rc)
        inner = min(float(path.rho[lo:hi].min()) for lo, hi in path.cuts())
        outer = min(
            max(float(path.rho[lo:hi].max()) for lo, hi in path.cuts()), rcase.aperture.outer_radius_um
        )
        step = path.feed_um / res.points_per_feed
        # the innermost pass's arc reaches the centre when it passes within the nose radius:
        # then the part is judged from the centre, the opposite ray's passes taken there
        self.reaches_centre = inner < rc
        self.centre_um = inner + self.band
        lo, hi = (0.0 if self.reaches_centre else self.centre_um), outer - self.band
        if not (step > 0 and hi > lo):
            raise CaseError(
                f"the program cuts radii {inner / 1e3:.6g} to {outer / 1e3:.6g} mm of the part: no fully "
                "machined "
                f"ring beyond its edge bands of {self.band:.4g} µm (feed plus the nose's contact window)"
            )
        self.nodes = lo + np.arange(int((hi - lo) / step) + 1) * step
        self.span_mm = (inner / 1e3, outer / 1e3)
        n = res.n_theta or min(max(res.samples_per_cell * path.max_points_per_rev, MIN_RAYS), MAX_RAYS)
        self.rays = (np.arange(n) + 0.5) / n * 2.0 * math.pi
        # a ray holds its nodes and a crossing per revolution of every cut: the work and the
        # memory a batch takes, whatever the program (bounded like any case: check_cost)
        passes = sum(
            math.ceil((path.angle[hi - 1] - path.angle[lo]) / (2.0 * math.pi)) + 2 for lo, hi in path.cuts()
        )
        check_cost((self.nodes.size + passes) / 2.0, n, s.max_nodes)
        self.per_batch = max(1, int(s.batch_nodes // (self.nodes.size + passes)))
        self.n_batches = math.ceil(self.rays.size / self.per_batch)
        self.zone_split_um = res.zone_split * rcase.aperture.inner_radius_um
        self.curvature = catalogs.curvature_bound(rcase.surface_spec)
        self.design: Optional[tuple[CommandedPath, np.ndarray]] = (
            self._design_path() if res.interp_error else None
        )
        # extremes [min, max] over the batches [µm]: the departure, the form error within the
        # centre disc and beyond it
        self.departure = np.array([math.inf, -math.inf])
        self.centre = np.array([math.inf, -math.inf])
        self.beyond = np.array([math.inf, -math.inf])
        self._lock = threading.Lock()

    def _design_path(self) -> tuple[CommandedPath, np.ndarray]:
        """The design-compensated tool path at the program's own points (model §4: its Z where
        the part is, the program's beyond it) and its segments as the program's are formed:
        linear, or the natural cubic through the values over each cut's angle for cubic ones."""
        rcase, path = self.rcase, self.path
        res = rcase.case.resolution
        z = self.z.copy()
        on = path.rho <= rcase.aperture.outer_radius_um
        theta = np.mod(path.sense * path.angle, 2.0 * math.pi)
        z[on], _ = compensation.compensate(
            rcase.surface,
            path.rho[on],
            theta[on],
            rcase.nose_radius_um,
            rcase.case.compensation,
            rcase.gradient_bound,
            n_scan=res.compensation_scan,
            curvature_bound=self.curvature,
        )
        if path.tangents is None:
            return path, z
        tangents = path.tangents.copy()
        for lo, hi in path.cuts():
            if hi - lo >= 2:
                tangents[lo : hi - 1, 4], tangents[lo : hi - 1, 5] = segments.natural_spline(
                    path.angle[lo:hi], z[lo:hi]
                )
        return path._replace(tangents=tangents), z

    def _passes(self, theta: np.ndarray) -> Passes:
        """The passes over the rays at ``theta`` [rad] sorted by position (:class:`Passes`);
        near the centre the opposite ray's passes at −ρ, those within the nose radius of the
        centre (their arcs reach this ray)."""
        sides = [self._side(theta, 1.0)]
        if self.reaches_centre:
            sides.append(self._side(theta + math.pi, -1.0))
        pos = np.concatenate([side.pos for side in sides], axis=1)
        order = np.argsort(np.where(np.isnan(pos), np.inf, pos), axis=1)

        def merged(values: list[Optional[np.ndarray]]) -> Optional[np.ndarray]:
            if any(v is None for v in values):
                return None
            return np.take_along_axis(np.concatenate(values, axis=1), order, axis=1)  # type: ignore[arg-type]

        w = merged([side.w for side in sides])
        assert w is not None
        pos = np.take_along_axis(pos, order, axis=1)
        return Passes(
            pos,
            w,
            merged([side.w_design for side in sides]),
            merged([side.w_exact for side in sides]),
            np.isfinite(pos).sum(axis=1).astype(np.int64),
        )

    def _side(self, theta: np.ndarray, sign: float) -> Passes:
        """The passes over rays at ``theta`` [rad] at ``sign`` × their radius [µm] (−1: the
        opposite rays', only those within the nose radius of the centre), with their commands."""
        pos, w, n_valid = crossings(self.path, self.z, theta)
        if sign < 0:
            pos[~(pos < self.rcase.nose_radius_um)] = np.nan
        w_design = w_exact = None
        if self.design is not None:
            _, w_design, _ = crossings(self.design[0], self.design[1], theta)
            w_exact = self._exact(pos, np.mod(theta, 2.0 * math.pi), w_design)
        return Passes(sign * pos, w, w_design, w_exact, n_valid)

    def batch(self, b: int, timer: Any) -> Machined:
        """Batch ``b`` of rays through crossings, sampling, exact commands and the envelope."""
        theta = self.rays[b * self.per_batch : (b + 1) * self.per_batch]
        rcase, rc = self.rcase, self.rcase.nose_radius_um
        t = time.perf_counter()
        pos, w, w_design, w_exact, n_valid = self._passes(theta)
        t = timer.add("interpolation", t)
        ct, st = np.cos(theta)[:, None], np.sin(theta)[:, None]
        query = np.broadcast_to(self.nodes[None, :], (theta.size, self.nodes.size))
        px, py = query * ct, query * st
        inside = rcase.aperture.contains(px, py)
        f = np.zeros(query.shape)
        f[inside] = rcase.surface(px[inside], py[inside])[0]
        t = timer.add("sampling", t)
        query = np.ascontiguousarray(query)
        z, cusp_r, cusp_z = envelope.machined_rows(pos, w, n_valid, rc, query)
        exact = None
        if w_design is not None and w_exact is not None:
            # interpolation between blocks: the design at the program's points against the exact
            z_design = envelope.machined_rows(pos, w_design, n_valid, rc, query)[0]
            exact = ExactRows(pos, w_design, w_exact, n_valid, rc, query, z_design)
            # the departure: the program's envelope against the design path's, node by node
            d = (z - z_design)[inside & np.isfinite(z) & np.isfinite(z_design)]
            if d.size:
                self._extend(self.departure, np.array([d.min(), d.max()]))
        t = timer.add("envelope", t)
        cx, cy = cusp_r * ct, cusp_r * st
        cusp_in = (
            np.isfinite(cusp_r)
            & (cusp_r >= self.nodes[0])
            & (cusp_r <= self.nodes[-1])
            & rcase.aperture.contains(cx, cy)
        )
        cusp_f = np.full(cusp_r.shape, np.nan)
        cusp_f[cusp_in] = rcase.surface(cx[cusp_in], cy[cusp_in])[0]
        e, e_cusp = z - f, cusp_z - cusp_f
        for found, near in ((self.centre, True), (self.beyond, False)):
            part = np.concatenate(
                [
                    e[inside & ((query < self.centre_um) == near)],
                    e_cusp[cusp_in & ((cusp_r < self.centre_um) == near)],
                ]
            )
            if part.size:
                self._extend(found, np.array([part.min(), part.max()]))
        timer.add("metrics", t)
        return Machined(
            z, f, inside, np.hypot(px, py), px, py, cusp_z, cusp_f, cusp_in, np.hypot(cx, cy), exact
        )

    def _extend(self, found: np.ndarray, batch: np.ndarray) -> None:
        """Extremes [min, max] of a batch into those found so far (batches run on threads)."""
        with self._lock:
            found[0], found[1] = min(found[0], batch[0]), max(found[1], batch[1])

    def _exact(self, pos: np.ndarray, theta: np.ndarray, base: np.ndarray) -> Any:
        """The compensated design's commands at the passes (model §4): what the program would
        command with every point exact at every pass; beyond the part, where there is no
        design, ``base`` (the design path's commands, there the program's own)."""
        rcase = self.rcase
        on = np.isfinite(pos) & (pos <= rcase.aperture.outer_radius_um)
        return exact_at_passes(rcase, rcase.surface, pos, theta, on, base, self.curvature)

    def record(self, errors: dict[str, float], timer: Any) -> dict[str, Any]:
        """The record: the shared fields, the spiral kind's (its rule 'program') and the Z
        motion over the program's own times against the servo's limits."""
        rcase, path = self.rcase, self.path
        bad = non_finite(rcase, errors)
        if bad:
            raise CaseError(
                f"the metrics came out non-finite ({', '.join(bad)}): no evaluation point inside the part "
                f"between the program's radii {self.span_mm[0]:.6g} and {self.span_mm[1]:.6g} mm"
            )
        t = time.perf_counter()
        dyn = _motion(path, self.z)
        m = rcase.machine
        feasible, reason = dynamics.feasibility(
            dyn, m.travel_um, m.peak_accel_m_s2, m.continuous_accel_m_s2, m.bandwidth_hz
        )
        timer.add("dynamics", t)
        record: dict[str, Any] = {
            "surface": rcase.case.surface,
            "layout": path.kind,
            "n_points": path.n_points,
        }
        record.update(rcase.kind.record_fields(rcase))
        record["aspect_actual"] = path.aspect
        record.update(simulated(rcase, errors, self.rays.size, self.band, np.zeros(0, dtype=bool)))
        record.update(motion_fields(dyn, feasible, reason))
        record.update(
            cut_radii_mm=self.span_mm,
            judged_radii_mm=(float(self.nodes[0]) / 1e3, float(self.nodes[-1]) / 1e3),
            centre_radius_mm=self.centre_um / 1e3,
            pv_centre_nm=_pv_nm(self.centre),
            pv_beyond_centre_nm=_pv_nm(self.beyond),
            pv_departure_nm=_pv_nm(self.departure) if self.design is not None else math.nan,
        )
        record.update(layer_record(rcase, None, dyn.stroke_um))
        return record


def _pv_nm(extremes: np.ndarray) -> float:
    """The P-V [nm] of extremes [min, max] in µm (NaN where nothing was judged)."""
    return float(extremes[1] - extremes[0]) * 1e3 if extremes[1] >= extremes[0] else math.nan


def _motion(path: CommandedPath, z_um: np.ndarray) -> dynamics.Dynamics:
    """The Z (tool tip) motion over the program's own segment times, by finite differences at
    the points (each cut on its own; its approach left out); no spectrum (NaN)."""
    v_peak, accels = 0.0, []
    for lo, hi in path.cuts():
        dt = path.seconds[lo : hi - 1]
        if hi - lo < 3 or not np.all(dt > 0):
            continue
        v = np.diff(z_um[lo:hi]) / dt * 1e-3  # mm/s
        a = np.diff(v) / (0.5 * (dt[1:] + dt[:-1])) * 1e-3  # m/s²
        v_peak = max(v_peak, float(np.abs(v).max()))
        accels.append(a)
    a_all = np.concatenate(accels) if accels else np.zeros(1)
    stroke = float(z_um.max() - z_um.min())
    rms = float(np.sqrt(np.mean(np.square(a_all))))
    return dynamics.Dynamics(stroke, v_peak, float(np.abs(a_all).max()), rms, math.nan, 0)
