"""One case: an immutable spec with a stable key, and the runner that predicts its form error.

The runner is the one place that calls the stages, in the order of architecture.md:
surface sampling → layout → compensation → interpolation along the spiral → envelope →
metrics. The part is simulated on batches of feed-plane lines so memory stays bounded
(a few MB per batch) whatever the layout and resolution.
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from collections.abc import Callable
from typing import Any, Literal, Optional

import numpy as np
from pydantic import Field, PositiveFloat, PositiveInt, model_validator

from ftsweep import catalogs
from ftsweep.catalogs import Strict
from ftsweep.stages import compensation, dynamics, envelope, interpolation, layouts, metrics
from ftsweep.stages.layouts import Layout
from ftsweep.stages.surfaces import radial_section


class CaseError(ValueError):
    """A case cannot be run as specified; the message says what to change."""


class Resolution(Strict):
    """Simulation resolution (physics.md §5). The defaults are converged: P-V moves by less
    than 3 % when the angular samples are quadrupled and the points per feed doubled."""

    samples_per_cell: PositiveInt = Field(
        3,
        description="spindle angles sampled per table cell at the outer radius; an odd number puts "
        "one sample on each ring cell's angular midpoint, where bilinear error peaks",
    )
    points_per_feed: PositiveInt = Field(2, description="evaluation points per feed along each angle")
    n_theta: Optional[PositiveInt] = Field(
        None, description="number of sampled spindle angles over 360°; overrides samples_per_cell"
    )
    compensation_scan: int = Field(5, ge=3, description="coarse-scan samples of the exact compensation")
    zone_split: float = Field(
        0.5, gt=0.0, lt=1.0, description="inner/outer zone boundary as a fraction of the inscribed radius"
    )
    error_map_bins: Optional[int] = Field(
        None,
        ge=4,
        le=1024,
        description="bins per side of a coarse error map over the aperture (None: no map)",
    )


class LayoutRequest(Strict):
    """A layout method with either explicit pitches or a target point count and aspect ratio.

    pitch: (Δρ [µm], Δθ [deg]) for rings, (Δx [µm], Δy [µm]) for meshes.
    points, aspect: target N and α (Δρ/Δθ [µm/deg] for rings, Δx/Δy for meshes).
    """

    kind: Literal["ring", "mesh"]
    pitch: Optional[tuple[PositiveFloat, PositiveFloat]] = None
    points: Optional[PositiveFloat] = None
    aspect: Optional[PositiveFloat] = None

    @model_validator(mode="after")
    def _one_way(self) -> LayoutRequest:
        target = self.points is not None or self.aspect is not None
        if self.pitch is not None and target:
            raise ValueError(
                "give either explicit pitches or a target point count and aspect ratio, not both"
            )
        if self.pitch is None and (self.points is None or self.aspect is None):
            raise ValueError("give explicit pitches, or both a target point count and an aspect ratio")
        return self

    def target(self) -> tuple[float, float]:
        """(points, aspect) of a target-count request."""
        if self.points is None or self.aspect is None:
            raise ValueError("this layout request gives explicit pitches, not a target")
        return self.points, self.aspect


class Case(Strict):
    """Everything that determines one prediction. ``key()`` is stable across processes."""

    surface: str
    layout: LayoutRequest
    machine: str = "fts-1m"
    cutting: str = "reference"
    feed_um: Optional[PositiveFloat] = Field(None, description="overrides the cutting entry [µm/rev]")
    nose_radius_um: Optional[PositiveFloat] = Field(None, description="overrides the cutting entry [µm]")
    compensation: Literal["exact", "slope", "none"] = "exact"
    resolution: Resolution = Resolution()

    def key(self) -> str:
        """Stable hash of the canonical JSON of the spec (16 hex digits)."""
        text = json.dumps(self.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def build_layout(surface: Any, request: LayoutRequest) -> Layout:
    """The control-point table of ``request`` covering the surface's aperture (physics.md §2).

    Rings cover the aperture's circumscribed radius; meshes its bounding box.
    """
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


def angular_samples(layout: Layout, rho0_um: float, resolution: Resolution) -> int:
    """Spindle angles sampled over 360° (even): ``n_theta`` if set, else ``samples_per_cell``
    per table cell along the outer circumference (Np cells for rings, 2πρ0/max(Δx, Δy) for
    meshes: bilinear error grows as the pitch squared, so the coarse direction's cells carry
    the error that must be resolved)."""
    if resolution.n_theta is not None:
        n = resolution.n_theta
    elif layout.kind == "ring":
        n = resolution.samples_per_cell * layout.shape[1]
    else:
        cells = math.ceil(2.0 * math.pi * rho0_um / max(layout.pitch))
        n = resolution.samples_per_cell * cells
    return n + (n % 2)


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
    """Accumulates wall time per named stage."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}

    def add(self, name: str, start: float) -> float:
        now = time.perf_counter()
        self.seconds[name] = self.seconds.get(name, 0.0) + now - start
        return now


# cost model of a case (ftsweep bench on this 2-core machine): throughput of the line
# simulation, and bytes held per evaluation node of one line by the batch arrays
NODES_PER_SECOND = 3.0e6
BYTES_PER_NODE = 160
MAX_NODES = 2.0e10  # about two hours of one core
MAX_LINE_BYTES = 4 * 2**30


def check_cost(nodes_per_ray: float, n_theta: int, max_nodes: float = MAX_NODES) -> None:
    """Refuse a case that would exhaust memory (one feed-plane line, two rays, must fit) or
    run for hours (more than ``max_nodes`` evaluation nodes), with its estimated cost."""
    line_bytes = 2.0 * nodes_per_ray * BYTES_PER_NODE
    if line_bytes > MAX_LINE_BYTES:
        raise CaseError(
            f"one feed-plane line would hold {2 * nodes_per_ray:,.3g} evaluation nodes "
            f"({line_bytes / 2**30:,.3g} GiB, limit {MAX_LINE_BYTES / 2**30:g} GiB): lower the points "
            "per feed or the nose radius (its contact window sets the simulated margin), or raise the feed"
        )
    total = 2.0 * nodes_per_ray * n_theta / 2.0  # n_theta angles are n_theta/2 lines of two rays
    if total > max_nodes:
        raise CaseError(
            f"the case needs {total:,.3g} evaluation nodes, about {total / NODES_PER_SECOND / 3600:,.2g} "
            f"hours on one core, over the limit of {max_nodes:,.3g}; lower the resolution, or raise "
            "the limit with --max-nodes"
        )


def require_finite(values: np.ndarray, what: str, where: Callable[[int], str]) -> None:
    """Raise :class:`CaseError` if ``values`` hold NaN or inf, naming how many and the first
    place (``where(flat index)``)."""
    finite = np.isfinite(values)
    if not finite.all():
        first = int(np.flatnonzero(~finite.ravel())[0])
        raise CaseError(
            f"{what} is not finite (NaN or inf) at {int(finite.size - finite.sum()):,} points, first at "
            f"{where(first)}"
        )


def _layout_point(layout: Layout, flat: int) -> str:
    i, j = np.unravel_index(flat, layout.shape)
    if layout.kind == "ring":
        rho = layout.origin[0] + i * layout.pitch[0]
        theta = layout.origin[1] + j * layout.pitch[1]
        return f"control point [{i}, {j}] (ρ = {rho:.6g} µm, θ = {theta:.6g}°)"
    x, y = layout.origin[0] + i * layout.pitch[0], layout.origin[1] + j * layout.pitch[1]
    return f"control point [{i}, {j}] (x = {x:.6g} µm, y = {y:.6g} µm)"


def _xy(r: float, theta: float) -> str:
    return f"x = {r * math.cos(theta):.6g} µm, y = {r * math.sin(theta):.6g} µm"


def _node_point(node_r: np.ndarray, ray_theta: np.ndarray) -> Callable[[int], str]:
    def where(flat: int) -> str:
        a, n = np.unravel_index(flat, node_r.shape)
        return _xy(float(node_r[a, n]), float(ray_theta[a, 0]))

    return where


def _pass_point(grid: Any, ray_theta: np.ndarray) -> Callable[[int], str]:
    """Location of pass ``flat`` of a path grid's (ray, pass) arrays, for messages."""

    def where(flat: int) -> str:
        a, k = np.unravel_index(flat, grid.pass_rho.shape)
        return "the pass at " + _xy(float(grid.pass_rho[a, k]), float(ray_theta[a, 0]))

    return where


STAGE_TIMERS = ("sampling", "compensation", "interpolation", "envelope", "metrics", "dynamics")


def run_case(
    case: Case,
    catalog_folder: Any = None,
    progress: Optional[Callable[[int, int], None]] = None,
    batch_nodes: int = 400_000,
    table: Optional[np.ndarray] = None,
    specs: Optional[tuple[Any, Any, Any]] = None,
    max_nodes: float = MAX_NODES,
) -> dict[str, Any]:
    """Predict the form error of one case (physics.md §1–§6).

    Returns a flat record: the resolved inputs (surface, layout, n_points, pitches, cutting
    conditions, resolution), the metrics of :func:`ftsweep.stages.metrics.finalize` in nm, the
    control points flagged as gouging, the feed cusp height, and wall seconds per stage
    (``seconds_<stage>``) and in total (``seconds``). ``progress(done, total)`` is called
    after each batch of lines. A given ``table`` [µm] (of the case's layout shape) replaces
    the compensated one: the controller's table as stored, e.g. after quantisation.
    ``specs`` = (surface, machine, cutting) entries replace the catalog look-up, e.g. the
    entries a cube or header recorded. A case of more than ``max_nodes`` evaluation nodes, or
    whose single line would not fit in memory, is refused before any work (:func:`check_cost`);
    a non-finite height, slope, command or metric fails the case naming where it occurred.
    """
    t_start = time.perf_counter()
    surface_spec, machine, cutting = specs or resolve_specs(case, catalog_folder)
    feed = case.feed_um or cutting.feed_um
    rc = case.nose_radius_um or cutting.nose_radius_um
    res = case.resolution
    if res.points_per_feed % 2:
        raise CaseError(
            "points_per_feed must be even so the cusp midway between passes is sampled, "
            f"got {res.points_per_feed}"
        )
    if not feed < 2.0 * rc:
        raise CaseError(
            f"feed {feed:g} µm/rev is not below twice the nose radius ({2.0 * rc:g} µm): consecutive "
            "passes of the nose arc would not overlap and nothing between them is machined (physics.md §5)"
        )

    try:
        layout = build_layout(surface_spec, case.layout)
    except ValueError as exc:
        raise CaseError(f"layout: {exc}") from None
    if layout.n_points > machine.capacity_points:
        raise CaseError(
            f"the {layout.kind} layout has {layout.n_points:,} points, over the capacity of machine "
            f"'{case.machine}' ({machine.capacity_points:,}); use larger pitches or fewer points"
        )

    surface = catalogs.surface_callable(surface_spec, catalog_folder)
    bound = catalogs.gradient_bound(surface_spec, catalog_folder)
    if not math.isfinite(bound):
        raise CaseError(
            f"the slope bound of surface '{case.surface}' is not finite: the surface gives no finite "
            "slope on its aperture"
        )
    aperture = catalogs.aperture_of(surface_spec)
    rho0 = aperture.outer_radius_um
    timer = Timer()

    # compensation of the control table (surface sampling happens inside, per scan offset)
    t = time.perf_counter()
    if table is None:
        table, gouge = control_table(case, layout, surface_spec, rc, catalog_folder)
    else:
        table = np.asarray(table, dtype=np.float64)
        if table.shape != layout.shape:
            raise CaseError(f"the given table has shape {table.shape}, the layout {layout.shape}")
        gouge = np.zeros(layout.shape, dtype=bool)
    require_finite(table, "the control table", lambda i: _layout_point(layout, i))
    t = timer.add("compensation", t)

    n_theta = angular_samples(layout, rho0, res)
    lines = interpolation.line_angles(n_theta)
    window = compensation.contact_window_um(bound, rc)
    margin = window + 2.0 * feed
    nodes_per_ray = (rho0 + 2.0 * margin) * res.points_per_feed / feed
    check_cost(nodes_per_ray, n_theta, max_nodes)
    per_batch = max(1, int(batch_nodes // (2.0 * nodes_per_ray)))
    mode = compensation.MODE_CODES[case.compensation]
    zone_split = res.zone_split * aperture.inner_radius_um
    stats = metrics.empty_stats()
    emap = ErrorMap.over(aperture, res.error_map_bins) if res.error_map_bins else None
    n_batches = math.ceil(lines.size / per_batch)
    for b in range(n_batches):
        t = time.perf_counter()
        grid = interpolation.path_grid(
            lines[b * per_batch : (b + 1) * per_batch], rho0, feed, res.points_per_feed, margin
        )
        ray_theta = grid.ray_theta[:, None]
        ct, st = np.cos(ray_theta), np.sin(ray_theta)
        g, gp = radial_section(surface, grid.node_r, ct, st)
        where = _node_point(grid.node_r, ray_theta)
        require_finite(g, f"the surface '{case.surface}' height", where)
        require_finite(gp, f"the surface '{case.surface}' slope", where)
        inside = aperture.contains_polar(grid.node_r, ct, st)
        t = timer.add("sampling", t)

        pass_nodes = grid.pass_nodes
        w_exact = np.empty(pass_nodes.shape)
        _commands_on_rays(g, gp, grid.spacing_um, rc, pass_nodes, grid.n_passes, mode, w_exact)
        t = timer.add("compensation", t)

        passes = np.arange(w_exact.shape[1])[None, :] < grid.n_passes[:, None]
        require_finite(np.where(passes, w_exact, 0.0), "the exact W command", _pass_point(grid, ray_theta))
        w_interp = interpolation.interpolate(layout, table, np.maximum(grid.pass_rho, 0.0), ray_theta)
        t = timer.add("interpolation", t)

        start = interpolation.first_machined_node(grid, window)
        z = np.empty(grid.node_r.shape)
        z_exact = np.empty(grid.node_r.shape)
        cusp_shape = (grid.node_r.shape[0], int(grid.n_passes.max()) + 2)
        cusp_r, cusp_z = np.empty(cusp_shape), np.empty(cusp_shape)
        unused_r, unused_z = np.empty(cusp_shape), np.empty(cusp_shape)
        envelope.envelope_lines(
            grid.node_r, w_interp, grid.n_passes, grid.node_offset, grid.ppf, start, rc, z, cusp_r, cusp_z
        )
        envelope.envelope_lines(
            grid.node_r,
            w_exact,
            grid.n_passes,
            grid.node_offset,
            grid.ppf,
            start,
            rc,
            z_exact,
            unused_r,
            unused_z,
        )
        t = timer.add("envelope", t)

        metrics.accumulate(z, z_exact, g, inside, np.abs(grid.node_r), zone_split, stats)
        cusp_f = interpolation.sample_on_nodes(grid, g, gp, cusp_r)
        cusp_inside = aperture.contains_polar(cusp_r, ct, st)
        metrics.accumulate_extrema(cusp_z, cusp_f, cusp_inside, cusp_r, zone_split, stats)
        if emap is not None:
            metrics.accumulate_map(
                z,
                g,
                inside,
                grid.node_r,
                ct,
                st,
                emap.x0,
                emap.y0,
                emap.bin_um,
                emap.total,
                emap.count,
                emap.peak,
            )
        timer.add("metrics", t)
        if progress is not None:
            progress(b + 1, n_batches)

    t = time.perf_counter()
    dyn = dynamics.analyse(
        layout, table, rho0, feed, cutting.spindle_rpm, machine.command_rate_hz, machine.spectrum_threshold
    )
    feasible, reason = dynamics.feasibility(
        dyn, machine.travel_um, machine.peak_accel_m_s2, machine.continuous_accel_m_s2, machine.bandwidth_hz
    )
    timer.add("dynamics", t)

    result = metrics.finalize(stats)
    bad = [k for k, v in result.items() if not math.isfinite(v)]
    if bad or not math.isfinite(dyn.stroke_um):
        raise CaseError(
            f"the metrics came out non-finite ({', '.join(bad) or 'stroke_um'}): no evaluation point "
            "inside the fully machined zone, or non-finite commands; check the aperture against "
            "the feed and the nose radius"
        )
    record: dict[str, Any] = {
        "surface": case.surface,
        "layout": layout.kind,
        "n_points": layout.n_points,
        "table_shape": list(layout.shape),
    }
    if layout.kind == "ring":
        record.update(drho_um=layout.pitch[0], dtheta_deg=layout.pitch[1], aspect_um_per_deg=layout.aspect)
    else:
        record.update(dx_um=layout.pitch[0], dy_um=layout.pitch[1], aspect=layout.aspect)
    record.update(
        compensation=case.compensation,
        machine=case.machine,
        feed_um=feed,
        nose_radius_um=rc,
        spindle_rpm=cutting.spindle_rpm,
        n_theta=n_theta,
        points_per_feed=res.points_per_feed,
        edge_band_um=feed + window,
    )
    record.update(result)
    record["cusp_nm"] = metrics.cusp_height_um(feed, rc) * 1e3
    record["gouge_points"] = int(np.count_nonzero(gouge))
    record.update(
        stroke_um=dyn.stroke_um,
        w_velocity_peak_mm_s=dyn.velocity_peak_mm_s,
        w_accel_peak_m_s2=dyn.accel_peak_m_s2,
        w_accel_rms_m_s2=dyn.accel_rms_m_s2,
        w_freq_max_hz=dyn.freq_max_hz,
        feasible=feasible,
        infeasible_reason=reason,
    )
    if emap is not None:
        record.update(emap.as_record())
    for name in STAGE_TIMERS:
        record[f"seconds_{name}"] = timer.seconds.get(name, 0.0)
    record["seconds"] = time.perf_counter() - t_start
    return record


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
    """The compensated control table [µm] of ``layout`` and its gouge flags (physics.md §4)."""
    node_rho, node_theta = layouts.layout_nodes(layout)
    return compensation.compensate(
        catalogs.surface_callable(surface_spec, catalog_folder),
        node_rho,
        node_theta,
        nose_radius_um,
        case.compensation,
        catalogs.gradient_bound(surface_spec, catalog_folder),
        n_scan=case.resolution.compensation_scan,
    )


def _commands_on_rays(g, gp, spacing, rc, pass_nodes, n_passes, mode, out) -> None:
    """Exact (or slope/none) commands at every pass of every ray, from the node samples."""
    for a in range(g.shape[0]):
        k = int(n_passes[a])
        compensation.compensate_on_ray(g[a], gp[a], spacing, rc, pass_nodes[a, :k], mode, out[a, :k])
        out[a, k:] = np.nan
