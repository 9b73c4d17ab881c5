"""One case: an immutable spec with a stable key, and the runner that predicts its form error.

The runner is the one place that calls the stages, in the order of architecture.md:
surface sampling → layout → compensation → interpolation along the spiral → envelope →
metrics. The part is simulated on batches of feed-plane lines so memory stays bounded
(a few MB per batch) whatever the layout and resolution.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, Optional

import numpy as np
from pydantic import Field, PositiveFloat, PositiveInt, field_validator, model_serializer, model_validator

from ftsweep import catalogs, result
from ftsweep import dpath as dpath_program
from ftsweep.catalogs import Strict
from ftsweep.result import STAGES
from ftsweep.stages import compensation, dynamics, envelope, interpolation, layers, layouts, metrics, spiral
from ftsweep.stages.interpolation import Program
from ftsweep.stages.layouts import Layout
from ftsweep.stages.surfaces import radial_section


class CaseError(ValueError):
    """A case cannot be run as specified; the message says what to change."""


class Resolution(Strict):
    """Simulation resolution (model §5). The defaults are converged: P-V moves by less
    than 3 % when the angular samples are quadrupled and the points per feed doubled."""

    samples_per_cell: PositiveInt = Field(
        3,
        description="spindle angles sampled per table cell at the outer radius; an odd number puts "
        "one sample on each ring cell's angular midpoint, where bilinear error peaks",
    )
    points_per_feed: PositiveInt = Field(
        2,
        description="evaluation points per feed along each angle; even, so the cusp midway "
        "between passes is a node",
    )
    n_theta: Optional[PositiveInt] = Field(
        None, description="number of sampled spindle angles over 360°; overrides samples_per_cell"
    )
    compensation_scan: int = Field(
        5,
        ge=3,
        description="coarse-scan samples of the exact compensation where the surface declares no "
        "curvature bound (with one, the solver and its scan density follow from the bound)",
    )
    zone_split: float = Field(
        0.5, gt=0.0, lt=1.0, description="inner/outer zone boundary as a fraction of the inscribed radius"
    )
    error_map_bins: Optional[int] = Field(
        None,
        ge=4,
        le=1024,
        description="bins per side of a coarse error map over the aperture (None: no map)",
    )

    interp_error: bool = Field(
        True,
        description="also simulate the envelope of the exact commands, for pv_interp_nm (the "
        "interpolation-only error, model §6); off skips them (about a fifth of a case) and "
        "leaves pv_interp_nm NaN",
    )

    angular_ladder: Optional[float] = Field(
        None,
        gt=1.0,
        le=2.0,
        description="round the angular samples of the samples_per_cell rule up to the next rung "
        "2·⌈r^k/2⌉ of a geometric ladder of ratio r, so cases of a sweep with nearby samplings share "
        "the same lines and reuse their layout-independent work; costs up to a factor r more samples, "
        "and ring samples no longer fall on the cells' angular midpoints (None: the rule's own count)",
    )

    @model_serializer(mode="wrap")
    def _stable_dump(self, handler: Any) -> Any:
        # cubes of specs written before these options existed stay resumable
        return catalogs.without_defaults(handler(self), {"interp_error": True, "angular_ladder": None})

    @field_validator("points_per_feed")
    @classmethod
    def _even(cls, value: int) -> int:
        if value % 2:
            raise ValueError("must be even so the cusp midway between passes is sampled")
        return value


class LayoutRequest(Strict):
    """A program: a table (ring or mesh) with either explicit pitches or a target point count
    and aspect ratio, or a spiral path program with one sampling rule ([4]).

    pitch: (Δρ [µm], Δθ [deg]) for rings, (Δx [µm], Δy [µm]) for meshes.
    points, aspect: target N and α (Δρ/Δθ [µm/deg] for rings, Δx/Δy for meshes).
    points_per_rev, arc_um, chord_um: the spiral's rule (constant angle, constant arc length
    [µm], chord-error budget [µm]); residual_um: the residual budget [µm] that sets the
    spiral's feed ([4] eqs. 1–3) instead of the cutting entry's.
    """

    kind: Literal["ring", "mesh", "spiral", "dpath"]
    pitch: Optional[tuple[PositiveFloat, PositiveFloat]] = None
    points: Optional[PositiveFloat] = None
    aspect: Optional[PositiveFloat] = None
    points_per_rev: Optional[int] = Field(None, ge=3, description="spiral: points per revolution")
    arc_um: Optional[PositiveFloat] = Field(None, description="spiral: path length between points [µm]")
    chord_um: Optional[PositiveFloat] = Field(None, description="spiral: chord-error budget Δcho [µm]")
    residual_um: Optional[PositiveFloat] = Field(
        None, description="spiral: residual (cusp) budget Δres [µm] that sets the feed"
    )
    # D-shaped slow-tool-servo paths ([5]); unset: ftsweep.dpath.DEFAULTS
    spacing_um: Optional[PositiveFloat] = Field(
        None, description="dpath: spacing h between cuts [µm] (default: the feed)"
    )
    points_per_cut: Optional[int] = Field(None, ge=2, description="dpath: points on every cut (default 201)")
    transition: Optional[Literal["traditional", "optimised"]] = Field(
        None, description="dpath: turn-round between cuts, arc (traditional) or quintic (optimised, default)"
    )
    zones: Optional[Literal[1, 2, 4]] = Field(
        None, description="dpath: cutting zones per revolution (default 1)"
    )
    offaxis_um: Optional[PositiveFloat] = Field(
        None, description="dpath: distance of the part's centre from the C axis [µm] (default 30 mm)"
    )
    cut_angle_deg: Optional[float] = Field(
        None, description="dpath: direction of the cuts in the part's frame [deg from +x] (default 90)"
    )
    transition_step_deg: Optional[PositiveFloat] = Field(
        None, description="dpath: largest C step between transition points [deg] (default 1)"
    )

    @model_serializer(mode="wrap")
    def _stable_dump(self, handler: Any) -> Any:
        # table and spiral cases keep their keys
        return catalogs.without_defaults(handler(self), dict.fromkeys((*SPIRAL_FIELDS, *DPATH_FIELDS)))

    @model_validator(mode="after")
    def _one_way(self) -> LayoutRequest:
        rules = [name for name in SPIRAL_RULES if getattr(self, name) is not None]
        dpath_given = [n for n in DPATH_FIELDS if getattr(self, n) is not None]
        if self.kind == "dpath":
            other = [n for n in ("pitch", "points", "aspect", *SPIRAL_FIELDS) if getattr(self, n) is not None]
            if other:
                raise ValueError(
                    f"a D-path program takes no {', '.join(other)}: give spacing_um, points_per_cut and "
                    "its path options"
                )
            return self
        if dpath_given:
            raise ValueError(
                f"{', '.join(dpath_given)} belong(s) to D-path programs, not to a {self.kind} program"
            )
        if self.kind == "spiral":
            table = [n for n in ("pitch", "points", "aspect") if getattr(self, n) is not None]
            if table:
                raise ValueError(
                    f"a spiral program takes no {', '.join(table)}: give one of points_per_rev, "
                    "arc_um or chord_um"
                )
            if len(rules) != 1:
                raise ValueError(
                    "a spiral program needs exactly one sampling rule: points_per_rev, arc_um or "
                    f"chord_um (got {', '.join(rules) or 'none'})"
                )
            return self
        spiral = [n for n in SPIRAL_FIELDS if getattr(self, n) is not None]
        if spiral:
            raise ValueError(f"{', '.join(spiral)} belong(s) to spiral programs, not to a {self.kind} table")
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

    def spiral_rule(self) -> tuple[str, float]:
        """(rule, parameter) of a spiral request: ("angle", Np), ("arc", µm) or ("chord", µm)."""
        for name, rule in zip(SPIRAL_RULES, spiral.RULES, strict=True):
            value = getattr(self, name)
            if value is not None:
                return rule, float(value)
        raise ValueError("this request is not a spiral program")


SPIRAL_RULES = ("points_per_rev", "arc_um", "chord_um")
SPIRAL_FIELDS = (*SPIRAL_RULES, "residual_um")
DPATH_FIELDS = (
    "spacing_um",
    "points_per_cut",
    "transition",
    "zones",
    "offaxis_um",
    "cut_angle_deg",
    "transition_step_deg",
)


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
    layers: Literal["auto", "off"] = Field(
        "auto",
        description="auto: cut commands spanning more than the machine's travel in layers ([3]); "
        "off: one pass, infeasible when the commands exceed the travel",
    )
    z_error_um: Optional[float] = Field(
        None, description="Z positioning error per retraction between layers [µm]; overrides the machine's"
    )

    @model_serializer(mode="wrap")
    def _stable_dump(self, handler: Any) -> Any:
        # keys of cases written before layered machining stay the same
        return catalogs.without_defaults(handler(self), {"layers": "auto", "z_error_um": None})

    def key(self) -> str:
        """Stable hash of the canonical JSON of the spec (16 hex digits)."""
        text = json.dumps(self.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]


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


def angular_samples(layout: Program, rho0_um: float, resolution: Resolution) -> int:
    """Spindle angles sampled over 360° (even): ``n_theta`` if set, else ``samples_per_cell``
    per table cell along the outer circumference (Np cells for rings, 2πρ0/max(Δx, Δy) for
    meshes: bilinear error grows as the pitch squared, so the coarse direction's cells carry
    the error that must be resolved; for a spiral program, the segments of its most densely
    sampled revolution); with ``angular_ladder``, the rule's count rounded up to
    the ladder's next rung (:func:`ladder_rung`)."""
    if resolution.n_theta is not None:
        n = resolution.n_theta
    else:
        if isinstance(layout, spiral.SpiralPath):
            n = resolution.samples_per_cell * layout.max_points_per_rev
        elif layout.kind == "ring":
            n = resolution.samples_per_cell * layout.shape[1]
        else:
            cells = math.ceil(2.0 * math.pi * rho0_um / max(layout.pitch))
            n = resolution.samples_per_cell * cells
        if resolution.angular_ladder is not None:
            return ladder_rung(n, resolution.angular_ladder)
    return n + (n % 2)


def ladder_rung(n: int, ratio: float) -> int:
    """The smallest even rung 2·⌈r^k/2⌉ (k = 0, 1, ...) of the geometric ladder of ratio
    ``ratio`` that is ≥ ``n``. Rungs depend on ``ratio`` alone, so any two counts between the
    same rungs share one."""
    k = max(0, math.floor(math.log(n) / math.log(ratio)) - 1)
    while 2 * math.ceil(ratio**k / 2.0) < n:
        k += 1
    return 2 * math.ceil(ratio**k / 2.0)


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

    def add(
        self,
        z: np.ndarray,
        g: np.ndarray,
        inside: np.ndarray,
        node_r: np.ndarray,
        ct: np.ndarray,
        st: np.ndarray,
    ) -> None:
        """Accumulate the errors z − g [µm] of a batch of node grids (rays at cos/sin ``ct``,
        ``st``) into the bins (:func:`ftsweep.stages.metrics.accumulate_map`)."""
        metrics.accumulate_map(
            z, g, inside, node_r, ct, st, self.x0, self.y0, self.bin_um, self.total, self.count, self.peak
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


def ray_nodes(rho0_um: float, margin_um: float, points_per_feed: float, feed_um: float) -> float:
    """Evaluation nodes on one ray of a feed-plane line (model §5): the radius plus the margin
    at both ends, ``points_per_feed`` per feed."""
    return (rho0_um + 2.0 * margin_um) * points_per_feed / feed_um


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


def _layout_point(layout: Program, flat: int) -> str:
    if isinstance(layout, spiral.SpiralPath):
        rho, theta = float(layout.rho[flat]), float(layout.theta[flat])
        return f"spiral point {flat} (ρ = {rho:.6g} µm, C = {math.degrees(theta):.6g}°)"
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


STAGE_TIMERS = STAGES


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
    # a line's memory is known before anything is planned or compensated: refuse it now
    margin = compensation.contact_window_um(bound, rc) + 2.0 * feed
    rho0 = float(catalogs.aperture_of(surface_spec).outer_radius_um)
    check_cost(ray_nodes(rho0, margin, case.resolution.points_per_feed, feed), 2, math.inf)
    surface = catalogs.surface_callable(surface_spec, catalog_folder)
    extra: dict[str, Any] = {}
    if request.kind == "spiral":
        t = time.perf_counter()
        note = " (estimated: a tenth of the count the curvature bound allows)" if request.chord_um else ""
        estimate = spiral_points(case, surface_spec, feed)
        check_capacity(case, "spiral program", estimate, machine.capacity_points, note)
        layout, extra = plan_spiral(case, surface_spec, surface, feed, rc, bound, program)
        assert sections is not None
        extra["residual_error_um"] = residual_error_um(sections, feed, rc)
        extra["plan_seconds"] = time.perf_counter() - t
    elif request.kind == "dpath":
        t = time.perf_counter()
        layout, extra = plan_dpath(
            case, surface_spec, surface, feed, rc, bound, program, machine.capacity_points
        )
        extra["plan_seconds"] = time.perf_counter() - t
    else:
        try:
            layout = build_layout(surface_spec, request)
        except ValueError as exc:
            raise CaseError(f"layout: {exc}") from None
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


def count_text(n: float) -> str:
    """A point count as people read it: grouped digits, or 3 significant digits when huge."""
    return f"{n:,.0f}" if n < 1e12 else f"{n:.3g}"


def check_capacity(case: Case, what: str, n_points: float, capacity: int, note: str = "") -> None:
    """Refuse a program or layout of more points than the machine's controller holds (also an
    estimate, before anything is planned or allocated; ``note`` says how it was estimated)."""
    if n_points > capacity:
        raise CaseError(
            f"the {what} has {count_text(n_points)} points{note}, over the capacity of machine "
            f"'{case.machine}' "
            f"({capacity:,}); use larger pitches, steps or budgets, fewer points, or a larger machine"
        )


def spiral_points(case: Case, surface_spec: Any, feed_um: float) -> float:
    """Points a spiral request's rule gives, estimated before planning ([4]): Np per
    revolution times ρ0/F for the angle rule, the path length over the step for the arc
    rule; 0 for the chord rule (known only once sampled; :func:`spiral.chord_budget` bounds
    its own sampling)."""
    rho0 = float(catalogs.aperture_of(surface_spec).outer_radius_um)
    rule, value = case.layout.spiral_rule()
    if rule == "angle":
        return value * rho0 / feed_um
    if rule == "arc":
        return spiral.path_length_um(rho0, feed_um) / value
    curvature = catalogs.curvature_bound(surface_spec)
    if curvature is not None and math.isfinite(curvature):
        # a chord of length s on a curve of curvature ≤ K deviates by ≤ K·s²/8 ([4] eq. 4), so
        # the budget needs points no closer than sqrt(8Δ/K): an upper estimate of the count,
        # refused only when even a tenth of it is over the capacity
        estimate = spiral.path_length_um(rho0, feed_um) * math.sqrt(curvature / (8.0 * value))
        return estimate / CHORD_ESTIMATE_MARGIN
    return 0.0


# the chord rule's up-front count (an upper estimate) is divided by this before the capacity check
CHORD_ESTIMATE_MARGIN = 10.0


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


@dataclass(frozen=True)
class LinePlan:
    """How the part is sampled (model §5): ``n_theta`` spindle angles as feed-plane lines,
    the simulated margin beyond the aperture [µm] (the arc's contact window plus two feeds),
    and the lines simulated per batch so a batch holds about ``batch_nodes`` nodes."""

    n_theta: int
    lines: np.ndarray
    window_um: float
    margin_um: float
    per_batch: int
    zone_split_um: float

    @classmethod
    def of(cls, rcase: ResolvedCase, batch_nodes: int, max_nodes: float) -> LinePlan:
        """The plan of a resolved case; refuses one too costly to run (:func:`check_cost`)."""
        res = rcase.case.resolution
        n_theta = angular_samples(rcase.layout, rcase.rho0_um, res)
        window = compensation.contact_window_um(rcase.gradient_bound, rcase.nose_radius_um)
        margin = window + 2.0 * rcase.feed_um
        nodes_per_ray = ray_nodes(rcase.rho0_um, margin, res.points_per_feed, rcase.feed_um)
        check_cost(nodes_per_ray, n_theta, max_nodes)
        return cls(
            n_theta=n_theta,
            lines=interpolation.line_angles(n_theta),
            window_um=window,
            margin_um=margin,
            per_batch=max(1, int(batch_nodes // (2.0 * nodes_per_ray))),
            zone_split_um=res.zone_split * rcase.aperture.inner_radius_um,
        )

    @property
    def n_batches(self) -> int:
        return math.ceil(self.lines.size / self.per_batch)

    def batch(self, b: int) -> np.ndarray:
        """Line angles [rad] of batch ``b``."""
        return self.lines[b * self.per_batch : (b + 1) * self.per_batch]


def run_case(
    case: Case,
    catalog_folder: Any = None,
    progress: Optional[Callable[[int, int], None]] = None,
    batch_nodes: int = 400_000,
    table: Optional[np.ndarray] = None,
    specs: Optional[tuple[Any, Any, Any]] = None,
    max_nodes: float = MAX_NODES,
    lines: Optional[LineCache] = None,
    program: Optional[tuple[spiral.SpiralPath, np.ndarray]] = None,
) -> dict[str, Any]:
    """Predict the form error of one case (model §1–§6), a table or a spiral program.

    Returns a flat record whose fields :mod:`ftsweep.result` declares (names, units, order):
    the resolved inputs (surface, layout, n_points, pitches, cutting conditions), the metrics
    of :func:`ftsweep.stages.metrics.finalize` in nm, the control points flagged as gouging,
    the feed cusp height, and wall seconds per stage (``seconds_<stage>``) and in total
    (``seconds``); with ``resolution.error_map_bins``, the error maps. ``progress(done, total)`` is called
    after each batch of lines. A given ``table`` [µm] (of the case's layout shape) replaces
    the compensated one: the controller's table as stored, e.g. after quantisation.
    ``specs`` = (surface, machine, cutting) entries replace the catalog look-up, e.g. the
    entries a cube or header recorded. A case of more than ``max_nodes`` evaluation nodes, or
    whose single line would not fit in memory, is refused before any work (:func:`check_cost`);
    a non-finite height, slope, command or metric fails the case naming where it occurred.
    With a ``lines`` cache, the layout-independent work on each batch of lines
    (:class:`LineData`) is taken from it when an earlier case computed it, and kept for later
    cases: the result is the same. A spiral case is planned by its rule unless ``program``
    (path, commands [µm]) gives it as stored, e.g. read from an exported program.
    """
    t_start = time.perf_counter()
    rcase = resolve_case(case, catalog_folder, specs, program)
    timer = Timer()
    timer.seconds["compensation"] = rcase.plan_seconds
    if case.layout.kind == "dpath":
        return _run_dpath(rcase, timer, progress, t_start)
    t = time.perf_counter()
    table, gouge = _table_of(rcase, table, catalog_folder)
    timer.add("compensation", t)
    plan = LinePlan.of(rcase, batch_nodes, max_nodes)
    t = time.perf_counter()
    layering = layer_plan(rcase, table)
    timer.add("interpolation", t)
    stats = metrics.empty_stats()
    bins = case.resolution.error_map_bins
    emap = ErrorMap.over(rcase.aperture, bins) if bins else None
    key = line_key(rcase, plan) if lines is not None else None
    for b in range(plan.n_batches):
        data = lines.get((key, b)) if lines is not None else None
        if data is None:
            data = _line_data(rcase, plan, plan.batch(b), timer)
            if lines is not None:
                lines.put((key, b), data)
        _simulate_lines(rcase, plan, table, stats, emap, timer, data, layering)
        if progress is not None:
            progress(b + 1, plan.n_batches)
    t = time.perf_counter()
    machine, cutting = rcase.machine, rcase.cutting
    dyn = dynamics.analyse(
        rcase.layout,
        table,
        rcase.rho0_um,
        rcase.feed_um,
        cutting.spindle_rpm,
        machine.command_rate_hz,
        machine.spectrum_threshold,
    )
    timer.add("dynamics", t)
    errors = metrics.finalize(stats)
    if not case.resolution.interp_error:
        errors["pv_interp_nm"] = math.nan  # not simulated: asked off
    record = _record(rcase, plan, errors, dyn, gouge, layering)
    if emap is not None:
        record.update(emap.as_record())
    return _timed(record, timer, t_start)


def _table_of(
    rcase: ResolvedCase, table: Optional[np.ndarray], catalog_folder: Any
) -> tuple[np.ndarray, np.ndarray]:
    """The compensated control table [µm] and its gouge flags, or a given table checked
    against the layout (no gouge flags: it is used as stored). A spiral program's commands
    were planned with it (:func:`plan_spiral`)."""
    layout = rcase.layout
    if table is None and rcase.values is not None and rcase.gouge is not None:
        table, gouge = rcase.values, rcase.gouge
    elif table is None:
        assert isinstance(layout, Layout)
        table, gouge = control_table(
            rcase.case, layout, rcase.surface_spec, rcase.nose_radius_um, catalog_folder
        )
    else:
        table = np.asarray(table, dtype=np.float64)
        shape = layout.shape if isinstance(layout, Layout) else (layout.n_points,)
        if table.shape != shape:
            raise CaseError(f"the given table has shape {table.shape}, the layout {shape}")
        gouge = np.zeros(shape, dtype=bool)
    require_finite(table, "the control table", lambda i: _layout_point(layout, i))
    return table, gouge


@dataclass(frozen=True)
class LineData:
    """What a batch of feed-plane lines gives independently of the table (model §3–§6): the
    path grid, the ray directions, the design height ``g`` [µm] and radial slope ``gp`` on the
    nodes, which nodes lie inside the aperture, and the envelope ``z_exact`` [µm] of the exact
    commands (None when the case does not ask for it)."""

    grid: Any
    ct: np.ndarray
    st: np.ndarray
    g: np.ndarray
    gp: np.ndarray
    inside: np.ndarray
    z_exact: Optional[np.ndarray]

    @property
    def nbytes(self) -> int:
        arrays = [self.ct, self.st, self.g, self.gp, self.inside, self.grid.node_r]
        arrays += [self.grid.ray_theta, self.grid.first_pass, self.grid.n_passes]
        return sum(a.nbytes for a in arrays) + (0 if self.z_exact is None else self.z_exact.nbytes)


# default memory [MiB] per sweep worker for shared lines: on this 24 GiB, 2-core machine a
# twelfth of the memory per worker, the lines of a 250k-point ring case (about 0.2 GB) ten times over
LINE_CACHE_MB = 2048.0


class LineCache:
    """The :class:`LineData` of batches of lines, kept within ``budget_bytes`` for the cases
    that follow on the same lines (e.g. the cases of a sweep that share an angular sampling).

    Entries are keyed by (everything the line data depend on (:func:`line_key`), batch), so a
    cached batch is the very array a case would compute: results are identical with and
    without the cache. To make room, the least recently used batches of other lines are
    dropped first; lines larger than the whole budget keep their first batches. Safe to share
    between threads (a Dask worker may run several tasks at once)."""

    def __init__(self, budget_bytes: float) -> None:
        self.budget_bytes = float(budget_bytes)
        self.nbytes = 0
        self.hits = 0
        self.misses = 0
        self._entries: OrderedDict[tuple[Any, ...], LineData] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: tuple[Any, ...]) -> Optional[LineData]:
        """The cached batch of ``key`` (None if not held)."""
        with self._lock:
            data = self._entries.get(key)
            if data is None:
                self.misses += 1
                return None
            self._entries.move_to_end(key)
            self.hits += 1
            return data

    def put(self, key: tuple[Any, ...], data: LineData) -> None:
        """Keep ``data`` under ``key``, dropping the least recently used to stay in budget."""
        size = data.nbytes
        with self._lock:
            if size > self.budget_bytes or key in self._entries:
                return
            while self.nbytes + size > self.budget_bytes:
                # never evict batches of the lines being filled: cases read their batches in
                # order, so lines larger than the budget keep their first batches (which the
                # next case reuses) instead of each batch evicting the one the next case reads first
                older = next((k for k in self._entries if k[0] != key[0]), None)
                if older is None:
                    return
                self.nbytes -= self._entries.pop(older).nbytes
            self._entries[key] = data
            self.nbytes += size


def line_key(rcase: ResolvedCase, plan: LinePlan) -> tuple[Any, ...]:
    """Everything the :class:`LineData` of a case's batches depend on: the surface entry, the
    spiral (start radius, feed), the arc, the sampling (angles, nodes per feed, margin, batch
    size) and, for the exact envelope, the compensation method."""
    res = rcase.case.resolution
    surface = rcase.surface_spec.model_dump_json()
    mode = rcase.case.compensation if res.interp_error else None
    return (
        surface,
        rcase.rho0_um,
        rcase.feed_um,
        rcase.nose_radius_um,
        plan.n_theta,
        res.points_per_feed,
        plan.margin_um,
        plan.window_um,
        plan.per_batch,
        mode,
    )


def _line_data(rcase: ResolvedCase, plan: LinePlan, lines: np.ndarray, timer: Timer) -> LineData:
    """The layout-independent part of a batch of lines (model §3, §5, §6): surface samples,
    the exact commands along the path and their envelope."""
    res, rc = rcase.case.resolution, rcase.nose_radius_um
    t = time.perf_counter()
    grid = interpolation.path_grid(lines, rcase.rho0_um, rcase.feed_um, res.points_per_feed, plan.margin_um)
    ray_theta = grid.ray_theta[:, None]
    ct, st = np.cos(ray_theta), np.sin(ray_theta)
    if rcase.lines is not None:
        g, gp = rcase.lines(grid.first_pass, grid.spacing_um, grid.node_offset, grid.node_r.shape[1], ct, st)
    else:
        g, gp = radial_section(rcase.surface, grid.node_r, ct, st)
    where = _node_point(grid.node_r, ray_theta)
    require_finite(g, f"the surface '{rcase.case.surface}' height", where)
    require_finite(gp, f"the surface '{rcase.case.surface}' slope", where)
    inside = rcase.aperture.contains_polar(grid.node_r, ct, st)
    t = timer.add("sampling", t)
    if not res.interp_error:
        return LineData(grid, ct, st, g, gp, inside, None)
    mode = compensation.MODE_CODES[rcase.case.compensation]
    w_exact = compensation.commands_on_rays(g, gp, grid.spacing_um, rc, grid.pass_nodes, grid.n_passes, mode)
    t = timer.add("compensation", t)
    passes = np.arange(w_exact.shape[1])[None, :] < grid.n_passes[:, None]
    require_finite(np.where(passes, w_exact, 0.0), "the exact W command", _pass_point(grid, ray_theta))
    z_exact = _machined(grid, w_exact, plan, rc)[0]
    timer.add("envelope", t)
    return LineData(grid, ct, st, g, gp, inside, z_exact)


def _machined(
    grid: Any, pass_w: np.ndarray, plan: LinePlan, rc: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The envelope (model §5) of commands ``pass_w`` [µm] on ``grid``, evaluated over the
    fully machined zone: machined height z and the cusp peaks (radius, height) [µm]."""
    start = interpolation.first_machined_node(grid, plan.window_um)
    return envelope.machined_lines(grid.node_r, pass_w, grid.n_passes, grid.node_offset, grid.ppf, start, rc)


def _simulate_lines(
    rcase: ResolvedCase,
    plan: LinePlan,
    table: np.ndarray,
    stats: np.ndarray,
    emap: Optional[ErrorMap],
    timer: Timer,
    data: LineData,
    layering: Optional[layers.LayerPlan] = None,
) -> None:
    """One batch of feed-plane lines through the stages that depend on the table (model
    §3–§6): the controller's interpolation along the path (executed layer by layer when
    ``layering`` is given, [3]), the arc envelope, and the metrics against the design and the
    exact-command envelope of ``data``, accumulated into ``stats`` (and ``emap``)."""
    rc, aperture, grid = rcase.nose_radius_um, rcase.aperture, data.grid
    t = time.perf_counter()
    w_interp = interpolation.pass_commands(rcase.layout, table, grid)
    if layering is not None:
        w_interp = layers.layered_pass_commands(
            layering, grid.ray_theta, grid.n_passes, w_interp, z_error_of(rcase)
        )
        passes = np.arange(w_interp.shape[1])[None, :] < grid.n_passes[:, None]
        require_finite(
            np.where(passes, w_interp, 0.0),
            "the layered W command (a pass no layer cuts)",
            _pass_point(grid, grid.ray_theta[:, None]),
        )
    t = timer.add("interpolation", t)

    z, cusp_r, cusp_z = _machined(grid, w_interp, plan, rc)
    # without the exact commands, z stands in for z_exact: pv_interp_nm is then set NaN
    z_exact = z if data.z_exact is None else data.z_exact
    t = timer.add("envelope", t)

    g, inside = data.g, data.inside
    metrics.accumulate(z, z_exact, g, inside, grid.node_r, plan.zone_split_um, stats)
    cusp_f = interpolation.sample_on_nodes(grid, g, data.gp, cusp_r)
    cusp_inside = aperture.contains_polar(cusp_r, data.ct, data.st)
    metrics.accumulate_extrema(cusp_z, cusp_f, cusp_inside, cusp_r, plan.zone_split_um, stats)
    if emap is not None:
        emap.add(z, g, inside, grid.node_r, data.ct, data.st)
    timer.add("metrics", t)


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


def layer_record(
    rcase: ResolvedCase, layering: Optional[layers.LayerPlan], stroke_um: float
) -> dict[str, Any]:
    """The plan's fields of a case record: the scalars a cube stores and ``layers``, the
    schedule per layer (None for a single pass, which is one layer: its zone the whole
    travel, its stroke the commands' range ``stroke_um``)."""
    rpm, machine = rcase.cutting.spindle_rpm, rcase.machine
    single_s = spiral.spiral_end_rad(rcase.rho0_um, rcase.feed_um) / (rpm * 2.0 * math.pi / 60.0)
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
            layers=None,
        )
    times = layers.layer_times(layering, rcase.rho0_um, rcase.feed_um, rpm, machine.layer_change_s)
    stroke = layering.stroke_used_um
    schedule = {
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
    return dict(
        n_layers=layering.n_layers,
        layer_segments=layering.n_segments,
        layer_zone_um=layering.zone_um,
        layer_stroke_um=float(stroke.max()),
        z_error_um=z_error,
        machining_s=float(times.time_s.sum()),
        single_pass_s=times.single_pass_s,
        layers=schedule,
    )


def _record(
    rcase: ResolvedCase,
    plan: LinePlan,
    errors: dict[str, float],
    dyn: Any,
    gouge: np.ndarray,
    layering: Optional[layers.LayerPlan] = None,
) -> dict[str, Any]:
    """The flat record of a finished case (see :func:`run_case`); ``errors`` are the metrics
    of :func:`ftsweep.stages.metrics.finalize`. Refuses non-finite metrics."""
    bad = _non_finite(rcase, errors)
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
    if isinstance(layout, spiral.SpiralPath):
        rule, value = case.layout.spiral_rule()
        record.update(
            spiral_rule=rule,
            points_per_rev=value if rule == "angle" else math.nan,
            arc_um=value if rule == "arc" else math.nan,
            chord_um=value if rule == "chord" else math.nan,
            residual_um=case.layout.residual_um or math.nan,
            revolutions=layout.revolutions,
            dphi_deg=layout.dphi_deg,
            ds_um=layout.ds_um,
            chord_error_nm=rcase.chord_error_um * 1e3,
            residual_error_nm=rcase.residual_error_um * 1e3,
        )
    else:
        pitch_names = result.pitch_names(layout.kind)
        record.update(
            {
                "table_rows": layout.shape[0],
                "table_cols": layout.shape[1],
                pitch_names[0]: layout.pitch[0],
                pitch_names[1]: layout.pitch[1],
            }
        )
    record["aspect_actual"] = layout.aspect
    record.update(_simulated(rcase, errors, plan.n_theta, rcase.feed_um + plan.window_um, gouge))
    record.update(
        stroke_um=dyn.stroke_um,
        w_velocity_peak_mm_s=dyn.velocity_peak_mm_s,
        w_accel_peak_m_s2=dyn.accel_peak_m_s2,
        w_accel_rms_m_s2=dyn.accel_rms_m_s2,
        w_freq_max_hz=dyn.freq_max_hz,
        feasible=feasible,
        infeasible_reason=reason,
    )
    record.update(layer_record(rcase, layering, dyn.stroke_um))
    return record


def _run_dpath(
    rcase: ResolvedCase, timer: Timer, progress: Optional[Callable[[int, int], None]], t_start: float
) -> dict[str, Any]:
    """:func:`run_case` of a D-path program ([5]): its form error through the same envelope
    and metrics (:func:`ftsweep.dpath.simulate`), its axis motion and the machine's axis
    limits (:func:`ftsweep.dpath.record_fields`)."""
    case, path = rcase.case, rcase.layout
    assert rcase.values is not None and rcase.gouge is not None
    z = rcase.values
    require_finite(z, "the D-path Z", lambda i: f"point {i} (C {math.degrees(path.phi[i]):.4f}°)")
    errors, rays, band = dpath_program.simulate(rcase, z, progress, timer.seconds)
    bad = _non_finite(rcase, errors)
    if bad:
        raise CaseError(
            f"the metrics came out non-finite ({', '.join(bad)}): no evaluation point inside the fully "
            "machined part; check the part against the spacing and the nose radius"
        )
    t = time.perf_counter()
    summary = dpath_program.motion_summary(path, z, rcase.cutting.spindle_rpm)
    timer.add("dynamics", t)
    record: dict[str, Any] = {"surface": case.surface, "layout": "dpath", "n_points": path.n_points}
    record.update(_simulated(rcase, errors, rays, band, rcase.gouge))
    record.update(dpath_program.record_fields(rcase, summary, z))
    return _timed(record, timer, t_start)


def _non_finite(rcase: ResolvedCase, errors: dict[str, float]) -> list[str]:
    """The metrics that came out non-finite (pv_interp_nm is NaN by request when the
    exact-command envelope is asked off)."""
    skipped = set() if rcase.case.resolution.interp_error else {"pv_interp_nm"}
    return [k for k, v in errors.items() if not math.isfinite(v) and k not in skipped]


def _simulated(
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


def _timed(record: dict[str, Any], timer: Timer, t_start: float) -> dict[str, Any]:
    """``record`` with the wall time of each stage and in all, in declared order."""
    for name in STAGE_TIMERS:
        record[f"seconds_{name}"] = timer.seconds.get(name, 0.0)
    record["seconds"] = time.perf_counter() - t_start
    return result.in_declared_order(record)


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
