"""Any lathe program as its controller commands it, simulated (docs/controllers.md,
"Predicting any program"): the passes of every cut over rays evenly round the part
(:mod:`ftsweep.stages.paths.commanded`), the arc envelope of them all (model §5) and the
metrics (model §6) on radial nodes between the program's innermost and outermost cut radii,
for a program read from a file. The spiral kind's simulation of a
:class:`~ftsweep.stages.paths.commanded.CommandedPath`; no spiral of constant feed is assumed.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from ftsweep.engine.case import CaseError
from ftsweep.engine.cost import check_cost
from ftsweep.engine.record import layer_record, motion_fields, non_finite, simulated
from ftsweep.engine.simulator import ExactRows, Machined, exact_at_passes, require_finite
from ftsweep.inputs import catalogs
from ftsweep.stages.envelope import arcs as envelope
from ftsweep.stages.interpolation import compensation
from ftsweep.stages.kinematics import dynamics
from ftsweep.stages.paths.commanded import CommandedPath, crossings

# rays round the part when the resolution does not set n_theta: samples_per_cell per point
# step of the program's finest revolution, within these bounds
MIN_RAYS, MAX_RAYS = 360, 20_000


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
        lo, hi = inner + self.band, outer - self.band
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

    def batch(self, b: int, timer: Any) -> Machined:
        """Batch ``b`` of rays through crossings, sampling, exact commands and the envelope."""
        theta = self.rays[b * self.per_batch : (b + 1) * self.per_batch]
        rcase, rc = self.rcase, self.rcase.nose_radius_um
        t = time.perf_counter()
        pos, w, n_valid = crossings(self.path, self.z, theta)
        ct, st = np.cos(theta)[:, None], np.sin(theta)[:, None]
        query = np.broadcast_to(self.nodes[None, :], (theta.size, self.nodes.size))
        px, py = query * ct, query * st
        inside = rcase.aperture.contains(px, py)
        f = np.zeros(query.shape)
        f[inside] = rcase.surface(px[inside], py[inside])[0]
        t = timer.add("sampling", t)
        w_exact = self._exact(pos, theta)
        t = timer.add("compensation", t)
        z, cusp_r, cusp_z = envelope.machined_rows(pos, w, n_valid, rc, np.ascontiguousarray(query))
        exact = (
            None
            if w_exact is None
            else ExactRows(pos, w, w_exact, n_valid, rc, np.ascontiguousarray(query), z)
        )
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
        timer.add("metrics", t)
        return Machined(
            z, f, inside, np.hypot(px, py), px, py, cusp_z, cusp_f, cusp_in, np.hypot(cx, cy), exact
        )

    def _exact(self, pos: np.ndarray, theta: np.ndarray) -> Any:
        """The compensated design's commands at the passes (model §4): what the program would
        command with every point exact; None when the case asks the exact envelope off."""
        rcase = self.rcase
        if not rcase.case.resolution.interp_error:
            return None
        on = np.isfinite(pos) & (pos <= rcase.aperture.outer_radius_um)
        return exact_at_passes(
            rcase, rcase.surface, pos, theta, on, np.full(pos.shape, np.nan), self.curvature
        )

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
        )
        record.update(layer_record(rcase, None, dyn.stroke_um))
        return record


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
