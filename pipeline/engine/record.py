"""The record of a case: the flat result :mod:`ftsweep.engine.result` declares, built from the
resolved case, its metrics, dynamics, layers and error maps, with the wall time per stage.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Any, Optional

import numpy as np

from ftsweep.engine import result
from ftsweep.engine.case import CaseError
from ftsweep.engine.planning import ResolvedCase, layer_change_of, z_error_of
from ftsweep.engine.result import STAGES
from ftsweep.stages.interpolation import spiral_program
from ftsweep.stages.kinematics import dynamics
from ftsweep.stages.metrics import moments as metrics
from ftsweep.stages.paths import layers


class ErrorMap:
    """A coarse square map of the form error over the aperture's bounding box (µm in, nm out)."""

    def __init__(self, x0: float, y0: float, bin_um: float, bins: int) -> None:
        self.x0, self.y0, self.bin_um, self.bins = x0, y0, bin_um, bins
        self.total = np.zeros((bins, bins))
        self.count = np.zeros((bins, bins))
        self.peak = np.zeros((bins, bins))

    @classmethod
    def over(cls, aperture: Any, bins: int) -> ErrorMap:
        half = max(aperture.half_extent_um)
        return cls(-half, -half, 2.0 * half / bins, bins)

    def add_points(
        self, z: np.ndarray, g: np.ndarray, inside: np.ndarray, x: np.ndarray, y: np.ndarray
    ) -> None:
        """Accumulate the errors z − g [µm] at points x, y [µm] of the part's frame, any
        kind's nodes (:func:`ftsweep.stages.metrics.moments.accumulate_map_xy`)."""
        metrics.accumulate_map_xy(
            z, g, inside, x, y, self.x0, self.y0, self.bin_um, self.total, self.count, self.peak
        )

    def centres_um(self) -> np.ndarray:
        """Bin centres [µm] along x (and y)."""
        return self.x0 + (np.arange(self.bins) + 0.5) * self.bin_um

    def as_record(self) -> dict[str, Any]:
        """Mean and peak error maps [nm] (NaN where no point fell) and bin centres [µm]."""
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.where(self.count > 0, self.total / self.count, np.nan) * 1e3
        peak = np.where(self.count > 0, self.peak, np.nan) * 1e3
        return {"error_map_mean_nm": mean, "error_map_peak_nm": peak, "error_map_x_um": self.centres_um()}


class Timer:
    """Accumulates wall time per named stage; safe to share between the threads of a case
    (their stage times add up, so with N threads a stage may total more than the wall time)."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self._lock = threading.Lock()

    def add(self, name: str, start: float) -> float:
        now = time.perf_counter()
        with self._lock:
            self.seconds[name] = self.seconds.get(name, 0.0) + now - start
        return now


def layer_record(
    rcase: ResolvedCase, layering: Optional[layers.LayerPlan], stroke_um: float
) -> dict[str, Any]:
    """The plan's fields of a case record: the scalars a cube stores and ``layers``, the
    schedule per layer (None for a single pass, which is one layer: its zone the whole
    travel, its stroke the commands' range ``stroke_um``)."""
    rpm, machine = rcase.cutting.spindle_rpm, rcase.machine
    single_s = spiral_program.spiral_end_rad(rcase.rho0_um, rcase.feed_um) / (rpm * 2.0 * math.pi / 60.0)
    z_error = z_error_of(rcase)
    if layering is None:
        return dict(
            n_layers=1,
            layer_segments=1,
            layer_zone_um=machine.travel_um,
            layer_stroke_um=stroke_um,
            z_error_um=z_error,
            machining_s=single_s,
            single_pass_s=single_s,
            layer_change_s=layer_change_of(rcase),
            layer_change_share=0.0,
            layers=None,
        )
    change_s = layer_change_of(rcase)
    times = layers.layer_times(layering, rcase.rho0_um, rcase.feed_um, rpm, change_s)
    stroke = layering.stroke_used_um
    schedule = layer_schedule(layering, times, z_error)
    return dict(
        n_layers=layering.n_layers,
        layer_segments=layering.n_segments,
        layer_zone_um=layering.zone_um,
        layer_stroke_um=float(stroke.max()),
        z_error_um=z_error,
        machining_s=float(times.time_s.sum()),
        single_pass_s=times.single_pass_s,
        layer_change_s=change_s,
        layer_change_share=change_s * layering.n_segments / float(times.time_s.sum()),
        layers=schedule,
    )


def layer_schedule(layering: layers.LayerPlan, times: layers.LayerTimes, z_error: float) -> dict[str, Any]:
    """The schedule of a layered case ([3]) as its record's ``layers`` holds it: per layer its
    zone, Z offset and shift, radii, angles, segments, stroke, spiral length and time [µm, rad, s]."""
    stroke = layering.stroke_used_um
    return {
        "n_layers": layering.n_layers,
        "zone_um": layering.zone_um,
        "margin_um": layering.margin_um,
        "travel_um": layering.travel_um,
        "z_error_um": z_error,
        "order": "outer edge to centre within a layer; layers from the lowest zone up",
        "offset_um": layering.offsets_um.tolist(),
        "zone_bottom_um": layering.bottoms_um.tolist(),
        "z_shift_um": (-z_error * np.arange(layering.n_layers)).tolist(),
        "start_radius_um": times.start_radius_um.tolist(),
        "end_radius_um": times.end_radius_um.tolist(),
        "start_phi_rad": layering.first_phi.tolist(),
        "segments": times.segments.tolist(),
        "stroke_used_um": stroke.tolist(),
        "spiral_length_um": times.cut_length_um.tolist(),
        "time_s": times.time_s.tolist(),
        "total_time_s": float(times.time_s.sum()),
        "single_pass_time_s": times.single_pass_s,
        "stroke_extension": float(layering.w_high.max() - layering.levels_um[0]) / layering.travel_um,
    }


def record_of(
    rcase: ResolvedCase,
    plan: Any,  # lines.LinePlan: its n_theta and window_um
    errors: dict[str, float],
    dyn: Any,
    gouge: np.ndarray,
    layering: Optional[layers.LayerPlan] = None,
) -> dict[str, Any]:
    """The flat record of a finished case (see :func:`run_case`); ``errors`` are the metrics
    of :func:`ftsweep.stages.metrics.moments.finalize`. Refuses non-finite metrics."""
    bad = non_finite(rcase, errors)
    if bad or not math.isfinite(dyn.stroke_um):
        raise CaseError(
            f"the metrics came out non-finite ({', '.join(bad) or 'stroke_um'}): no evaluation point "
            "inside the fully machined zone, or non-finite commands; check the aperture against "
            "the feed and the nose radius"
        )
    case, layout, machine = rcase.case, rcase.layout, rcase.machine
    # layered, the servo strokes each layer's zone; the Z axis takes the rest ([3])
    stroke_dyn = dyn if layering is None else dyn._replace(stroke_um=float(layering.stroke_used_um.max()))
    feasible, reason = dynamics.feasibility(
        stroke_dyn,
        machine.travel_um,
        machine.peak_accel_m_s2,
        machine.continuous_accel_m_s2,
        machine.bandwidth_hz,
    )
    if layering is None and dyn.stroke_um > machine.travel_um:
        needed = layers.layers_needed(dyn.stroke_um, machine.travel_um, machine.layer_margin_um)
        reason += f" (layers off; layered machining would cut it in {needed} layers)"
    record: dict[str, Any] = {"surface": case.surface, "layout": layout.kind, "n_points": layout.n_points}
    record.update(rcase.kind.record_fields(rcase))
    record["aspect_actual"] = layout.aspect
    record.update(simulated(rcase, errors, plan.n_theta, rcase.feed_um + plan.window_um, gouge))
    record.update(motion_fields(dyn, feasible, reason))
    record.update(layer_record(rcase, layering, dyn.stroke_um))
    return record


def motion_fields(dyn: Any, feasible: bool, reason: str) -> dict[str, Any]:
    """The W command's motion fields of a record (model §6 dynamics) and its feasibility."""
    return {
        "stroke_um": dyn.stroke_um,
        "w_velocity_peak_mm_s": dyn.velocity_peak_mm_s,
        "w_accel_peak_m_s2": dyn.accel_peak_m_s2,
        "w_accel_rms_m_s2": dyn.accel_rms_m_s2,
        "w_freq_max_hz": dyn.freq_max_hz,
        "feasible": feasible,
        "infeasible_reason": reason,
    }


def non_finite(rcase: ResolvedCase, errors: dict[str, float]) -> list[str]:
    """The metrics that came out non-finite (pv_interp_nm is NaN by request when the
    exact-command envelope is asked off)."""
    skipped = set() if rcase.case.resolution.interp_error else {"pv_interp_nm"}
    return [k for k, v in errors.items() if not math.isfinite(v) and k not in skipped]


def simulated(
    rcase: ResolvedCase, errors: dict[str, float], n_theta: int, edge_band_um: float, gouge: np.ndarray
) -> dict[str, Any]:
    """The record fields every program kind shares: cutting conditions, sampling, the metrics,
    the flat-surface cusp and the gouging points."""
    case = rcase.case
    return {
        "compensation": case.compensation,
        "machine": case.machine,
        "feed_um": rcase.feed_um,
        "nose_radius_um": rcase.nose_radius_um,
        "spindle_rpm": rcase.cutting.spindle_rpm,
        "n_theta": n_theta,
        "points_per_feed": case.resolution.points_per_feed,
        "edge_band_um": edge_band_um,
        **errors,
        "cusp_nm": metrics.cusp_height_um(rcase.feed_um, rcase.nose_radius_um) * 1e3,
        "gouge_points": int(np.count_nonzero(gouge)),
    }


def timed(record: dict[str, Any], timer: Timer, t_start: float, kind: Any) -> dict[str, Any]:
    """``record`` with the wall time of each stage and in all, in ``kind``'s declared order."""
    for name in STAGES:
        record[f"seconds_{name}"] = timer.seconds.get(name, 0.0)
    record["seconds"] = time.perf_counter() - t_start
    return result.in_declared_order(record, kind)
