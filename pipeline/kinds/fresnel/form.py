"""The form error of a freeform Fresnel program ([2]) through the one simulator (model §5–§6).

The nose arc lies in the rake face, which eq. 9 turns onto the cutting direction: the arc's
plane holds the local gradient, which on the quasi-spiral about the surface's lowest point runs
across the path, along the rays from that point (exactly so for a surface of revolution about
it; for a freeform, the arc's section by the ray's plane is taken as the arc itself, an
approximation of second order in the angle between gradient and ray). So, as for a spiral about
the spindle, the machined surface is taken along rays from the lowest point: the program
crosses each ray once per turn, its points joined linearly as the machine moves between lines,
and the lower envelope of the nose arcs at the crossings (tips at the program's Z, model §5)
is the machined height. The design is the sliced surface f_c ([2] eq. 3).

*Facet walls.* Across an edge the design steps by h; the nose forms the wall, not the program,
and the arcs of the lower facet's passes reach into the upper facet over sqrt(2·Rc·h). A node
is evaluated only where every pass within that reach plus a feed on either side belongs to the
node's own facet, so the metrics are the facets' form error, walls left out (their width is
reported as ``edge_band_um``); likewise off the path's first and last turns.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from ftsweep.engine.case import CaseError
from ftsweep.engine.simulator import ExactRows, Machined, require_finite
from ftsweep.inputs import catalogs
from ftsweep.stages.envelope import arcs as envelope
from ftsweep.stages.interpolation import rays, timed_path
from ftsweep.stages.kinematics import axes as kinematics
from ftsweep.stages.metrics import moments as metrics
from ftsweep.stages.paths import fresnel as ff

RAYS_PER_BATCH = 64
# the case's compensation names [2]'s: eq. 10 (exact), eq. 12 (the straight-line "slope"), none
COMPENSATION = {"exact": "exact", "slope": "straight", "none": "none"}


def walls_band_um(nose_radius_um: float, facet_height_um: float, feed_um: float) -> float:
    """Reach of a facet wall's influence [µm]: where the nose arc rises by h, plus a feed."""
    return math.sqrt(2.0 * nose_radius_um * facet_height_um) + feed_um


class FresnelSimulation:
    """The batches of rays of a Fresnel case (module docstring), the simulation of its kind
    (:class:`ftsweep.engine.contract.Simulation`)."""

    def __init__(self, s: Any, timer: Any) -> None:
        rcase = s.rcase
        prog = rcase.layout
        fplan, res = prog.plan, rcase.case.resolution
        assert rcase.values is not None
        z = np.asarray(rcase.values, dtype=np.float64)
        require_finite(z, "the Fresnel Z", lambda i: f"point {i}")
        self.rcase, self.fplan = rcase, fplan
        self.apex = np.asarray(fplan.apex_um, dtype=np.float64)
        # the closing point is the lowest point itself, where the ray angle is open
        d = prog.xy[:-1] - self.apex
        psi = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
        self.sign = 1.0 if psi[-1] >= psi[0] else -1.0
        self.psi, self.r, self.z = self.sign * psi, np.hypot(d[:, 0], d[:, 1]), z[:-1]
        if not np.all(np.diff(self.psi) > 0.0):
            raise CaseError(
                "the quasi-spiral does not turn steadily about the surface's lowest point (an edge "
                "is not star-shaped about it): its form error cannot be taken along rays from there"
            )
        self.level = np.asarray(fplan.path.level[:-1], dtype=np.int64)
        # a PVT program's channels C, X, Y, Z (closing point dropped), stacked once for every batch
        self.tangents = None if prog.tangents is None else prog.tangents[:-1]
        self.chan = None
        if self.tangents is not None:
            self.chan = np.column_stack([fplan.phi, fplan.x_um, fplan.y_um, z])[:-1]
        self.fn = catalogs.base_callable(rcase.surface_spec, s.catalog_folder)
        h, feed, rc = fplan.facet_height_um, rcase.feed_um, rcase.nose_radius_um
        self.band = walls_band_um(rc, h, feed)
        step = feed / res.points_per_feed
        self.d_nodes = np.arange(1, int(self.r.max() / step) + 1) * step
        n = res.n_theta or res.samples_per_cell * fplan.path.points_per_turn
        self.rays = (np.arange(n) + 0.5) * (2.0 * math.pi / n)
        self.n_batches = math.ceil(n / RAYS_PER_BATCH)
        self.zone_split_um = res.zone_split * rcase.aperture.inner_radius_um
        # per batch, per facet level j: the statistics of its interior's nodes (merged in
        # batch order by the record, so they do not depend on how many threads ran batches)
        self.facet_stats: dict[int, dict[int, np.ndarray]] = {}

    def _design(self, x: np.ndarray, y: np.ndarray, level: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """f_c [µm] and the facet level at part points x, y [µm] ([2] eq. 3)."""
        return ff.sliced(self.fn(x, y)[0], self.fplan.f_ref_um, self.fplan.facet_height_um, level)

    def batch(self, b: int, timer: Any) -> Machined:
        """Batch ``b`` of rays: the crossings, the design on the nodes of the facets' interiors,
        the exact commands at the crossings and the envelopes of both (model §5)."""
        rcase = self.rcase
        theta = self.rays[b * RAYS_PER_BATCH : (b + 1) * RAYS_PER_BATCH]
        t = time.perf_counter()
        pos, w, lev, n_valid = self._crossings(theta)
        ct, st = np.cos(self.sign * theta)[:, None], np.sin(self.sign * theta)[:, None]
        q = np.broadcast_to(self.d_nodes[None, :], (theta.size, self.d_nodes.size))
        x, y = self.apex[0] + q * ct, self.apex[1] + q * st
        g, level = self._design(x, y)
        inside = rcase.aperture.contains(x, y) & _one_facet(pos, lev, n_valid, q, level, self.band)
        t = timer.add("sampling", t)
        w_exact = self._exact(pos, lev, ct, st) if rcase.case.resolution.interp_error else None
        t = timer.add("compensation", t)
        query = np.where(inside, q, np.nan)
        rc = rcase.nose_radius_um
        z, cusp_r, cusp_z = envelope.machined_rows(pos, w, n_valid, rc, query)
        exact = None if w_exact is None else ExactRows(pos, w, w_exact, n_valid, rc, query, z)
        t = timer.add("envelope", t)
        cx, cy = self.apex[0] + cusp_r * ct, self.apex[1] + cusp_r * st
        cusp_g = np.full(cusp_r.shape, np.nan)
        finite = np.isfinite(cusp_r)
        cusp_level = np.full(cusp_r.shape, -1, dtype=np.int64)
        cusp_g[finite], cusp_level[finite] = self._design(cx[finite], cy[finite])
        cusp_in = finite & rcase.aperture.contains(cx, cy)
        cusp_in &= _one_facet(pos, lev, n_valid, np.where(finite, cusp_r, 0.0), cusp_level, self.band)
        timer.add("metrics", t)
        r = np.hypot(x, y)
        facets = {}
        for j in np.unique(level[inside]):
            facets[int(j)] = stats = metrics.empty_stats()
            facet = inside & (level == j)
            metrics.accumulate(z, g, facet, r, self.zone_split_um, stats)
            if exact is not None:
                exact.extrema(facet, stats[metrics.INTERP])
        self.facet_stats[b] = facets
        return Machined(z, g, inside, r, x, y, cusp_z, cusp_g, cusp_in, np.hypot(cx, cy), exact)

    def _crossings(self, theta: np.ndarray) -> tuple[np.ndarray, ...]:
        """The passes crossing each ray, sorted outwards: distance from the lowest point [µm],
        tool tip Z [µm], facet level, and how many there are."""
        if self.chan is None or self.tangents is None:
            pos, w, seg = rays.crossings(self.psi, self.r, self.z, theta)
        else:
            # cubic in time (PVT): the path between points followed exactly through eq. 9
            pos, w, seg = timed_path.crossings(
                self.psi, self.chan, self.tangents, theta, timed_path.TURNED, tuple(self.apex), self.sign
            )
        order = np.argsort(np.where(np.isnan(pos), np.inf, pos), axis=1)
        pos = np.take_along_axis(pos, order, axis=1)
        w = np.take_along_axis(w, order, axis=1)
        lev = self.level[np.maximum(np.take_along_axis(seg, order, axis=1), 0)]
        return pos, w, lev, np.isfinite(pos).sum(axis=1).astype(np.int64)

    def _exact(self, pos: np.ndarray, lev: np.ndarray, ct: np.ndarray, st: np.ndarray) -> np.ndarray:
        """The exact tool tip Z [µm] at the crossings: f_c of the pass's facet plus the case's
        compensation there ([2] eqs. 10, 12, 13)."""
        ok = np.isfinite(pos)
        x = (self.apex[0] + pos * ct)[ok]
        y = (self.apex[1] + pos * st)[ok]
        mode = COMPENSATION[self.rcase.case.compensation]
        rc = self.rcase.nose_radius_um
        if mode == "exact":
            ez = ff.compensation_exact(self.fn, x, y, rc)
        elif mode == "straight":
            _, gx, gy = self.fn(x, y)
            ez = ff.compensation_straight(gx, gy, rc)
        else:
            ez = np.zeros(x.shape)
        out = np.full(pos.shape, np.nan)
        out[ok] = self._design(x, y, lev[ok])[0] + ez
        return out

    def record(self, errors: dict[str, float], timer: Any) -> dict[str, Any]:
        """The record: the shared fields, the program's own and its axis motion against the
        machine's limits (:func:`record_fields`)."""
        from ftsweep.engine.record import non_finite, simulated

        rcase = self.rcase
        bad = non_finite(rcase, errors)
        if bad:
            raise CaseError(
                f"the metrics came out non-finite ({', '.join(bad)}): no evaluation point inside a "
                "facet's interior; check the facet height against the feed and the nose radius"
            )
        t = time.perf_counter()
        fields = record_fields(rcase)
        timer.add("dynamics", t)
        record: dict[str, Any] = {"surface": rcase.case.surface, "layout": "fresnel"}
        record["n_points"] = rcase.layout.n_points
        record.update(simulated(rcase, errors, self.rays.size, self.band, rcase.gouge))
        record.update(fields)
        record["facets"] = self._facets()
        return record

    def _facets(self) -> list[dict[str, Any]]:
        """P-V and RMS [nm] of every facet's interior on the evaluation nodes, outermost facet
        first (facet n = N − 1 − j of level j, [2]'s numbering from outside)."""
        top = self.fplan.path.n_facets - 1
        merged: dict[int, np.ndarray] = {}
        for b in sorted(self.facet_stats):
            for j, stats in self.facet_stats[b].items():
                merged[j] = metrics.merge_stats(merged.get(j, metrics.empty_stats()), stats)
        out = []
        for j in sorted(merged, reverse=True):
            m = metrics.finalize(merged[j])
            out.append({"facet": top - j, "pv_nm": m["pv_nm"], "rms_nm": m["rms_nm"], "n_eval": m["n_eval"]})
        return out


def _one_facet(
    pos: np.ndarray, lev: np.ndarray, n_valid: np.ndarray, r: np.ndarray, level: np.ndarray, band: float
) -> np.ndarray:
    """Whether every pass within ``band`` [µm] of each point at distance r [µm] along its ray
    lies on the point's facet ``level``, with passes beyond the band on both sides (the point
    is in a facet's interior, off the path's first and last turns)."""
    out = np.zeros(r.shape, dtype=bool)
    for a in range(pos.shape[0]):
        nv = int(n_valid[a])
        if nv < 3:
            continue
        p, lv = pos[a, :nv], lev[a, :nv]
        changes = np.concatenate([[0], np.cumsum(lv[1:] != lv[:-1])])
        lo = np.searchsorted(p, r[a] - band)
        hi = np.searchsorted(p, r[a] + band, side="right") - 1
        ok = (lo >= 1) & (hi < nv - 1) & (hi >= lo)
        lo, hi = np.clip(lo, 0, nv - 1), np.clip(hi, 0, nv - 1)
        out[a] = ok & (changes[hi] == changes[lo]) & (lv[lo] == level[a])
    return out


def record_fields(rcase: Any) -> dict[str, Any]:
    """The Fresnel fields of a case record ([2]; declared in :mod:`ftsweep.engine.result`): the
    program, its Z motion (the servo's W fields) and its axes against the machine's limits
    (the kinematics stage), machining times with adaptive and constant timesteps."""
    from ftsweep.kinds.fresnel import program as fresnel

    prog = rcase.layout
    fplan, steps = prog.plan, prog.steps
    q = fplan.axes_si()
    m = kinematics.over_steps(q, steps.steps)  # the optimiser's steps are all positive
    reason = kinematics.limits_reason(q, steps.steps, fresnel.limits_of(rcase.machine, rcase.case.machine))
    z_acc = m.accel[:, 3]
    time_adaptive = float(steps.steps.sum())
    time_constant = steps.constant * (q.shape[0] - 1)
    step_c = np.diff(fplan.phi)
    return {
        "facet_height_um": fplan.facet_height_um,
        "points_per_turn": fplan.path.points_per_turn,
        "deviation_deg": math.degrees(fplan.deviation_rad),
        "n_facets": fplan.path.n_facets,
        "revolutions": float(fplan.path.xy.shape[0] - 1) / fplan.path.points_per_turn,
        "dphi_deg": float(np.degrees(np.abs(step_c).mean())),
        "ds_um": float(np.hypot(*np.diff(fplan.path.xy, axis=0).T).mean()),
        **{k: v for k, v in fresnel.ez_on_part(fplan, rcase.aperture).items() if k != "ez_difference_max_nm"},
        "stroke_um": float(np.ptp(fplan.tool_z_um)),
        "w_velocity_peak_mm_s": float(np.abs(m.velocity[:, 3]).max() * 1e3),
        "w_accel_peak_m_s2": float(np.abs(z_acc).max()),
        "w_accel_rms_m_s2": float(np.sqrt(np.mean(z_acc**2))),
        "feasible": int(not reason),
        "infeasible_reason": reason,
        "machining_s": time_adaptive,
        "time_constant_s": time_constant,
        "speedup": time_constant / time_adaptive,
    }
