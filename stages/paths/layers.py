"""Layered tool trajectories: parts deeper than the servo's stroke ([3], model §1, §5).

An FTS strokes only ``travel`` µm. [3] machines deeper parts in *layers*: the height range
of the commands is split into stroke zones, and for each zone the Z axis sets the workpiece
so that the zone lies inside the stroke; between layers the spindle stops and Z retracts the
workpiece by one zone. Here:

* Zones are [L_j, L_j+1] with L_j = w_min + j·S and S = travel − margin (the margin keeps
  the commands off the stroke's ends); a zone holding no command is no layer.
* Layer j sets the workpiece at Z offset Z_j = L_j − margin/2 and the FTS executes
  W = clip(w − Z_j, 0, travel): inside its zone W stays within [margin/2, travel − margin/2].
* A layer cuts along the same spiral (same program, same commands) but only on its
  *segments*: the stretches of the spiral where the command stays at or below the zone's top,
  trimmed to the first and last point inside the zone. A segment ends where the command
  rises through the top: the FTS is at its upper limit there, which is where [3] stops the
  spindle (its exit point), and the next segment starts where the command comes back down
  through the top (its re-entry point, also on the upper limit). Going inwards along the
  spiral, a layer's first point is the outermost point of the part inside its zone: its
  start radius is the outermost radius of its outline (the transition rule of [3]).
  Between segments the tool is lifted over the part, which stands above the zone there.
* Retractions: each layer's zone starts where the previous one ends (the largest Z boundary
  the previous layer reached), so no band of material is left between layers (over-retraction,
  [3] fig. 8) and none is cut twice at different offsets.

Every command of the program lies in some zone and so on some segment of that zone's layer,
where it is executed unchanged: with exact Z positioning the layered passes are the single
pass's, split. The machined surface is the lower envelope over all layers' passes (model
§5); a pass that two layers share (a dip below a zone inside a segment is cut in the air at
the zone's bottom) counts with its lower height. A Z positioning error e per retraction
shifts layer j by −j·e (the retractions fall short and add up).

Angles are accumulated spindle angles φ [rad] along the spiral (0 at the outer edge), lengths
µm, times s.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import NamedTuple

import numpy as np
from numba import njit

from ftsweep.stages.interpolation.spiral_program import (
    SpiralPath,
    arc_length_between,
    spiral_end_rad,
    spiral_radius,
)
from ftsweep.stages.interpolation.tables import Program, interpolate

# a plan whose zones need more segments than this is refused: it is no longer a layered
# trajectory but a stop at every feature (and its schedule would not fit a controller)
MAX_SEGMENTS = 2_000_000


class LayerPlan(NamedTuple):
    """A layered plan (see the module docstring). Lengths µm, angles rad.

    levels_um : (Z+1,) boundaries of every stroke zone, w_min + j·zone_um.
    zone_um : height S of a zone (travel less margin).
    margin_um : margin kept off the stroke's ends (half at each end).
    travel_um : the servo's stroke.
    bottoms_um : (K,) zone bottom of each layer (zones holding no command are left out).
    seg_ptr : (K+1,) segments of layer k are ``seg_ptr[k]:seg_ptr[k+1]``.
    seg_start, seg_end : (M,) accumulated spindle angle where each segment starts and ends,
        increasing within a layer.
    w_low, w_high : (K,) lowest and highest command each layer executes [µm] (a dip below
        the zone inside a segment is executed at the zone's bottom).
    phi_end : accumulated angle of the program's end (the centre) [rad].
    """

    levels_um: np.ndarray
    zone_um: float
    margin_um: float
    travel_um: float
    bottoms_um: np.ndarray
    seg_ptr: np.ndarray
    seg_start: np.ndarray
    seg_end: np.ndarray
    w_low: np.ndarray
    w_high: np.ndarray
    phi_end: float

    @property
    def n_layers(self) -> int:
        return int(self.bottoms_um.size)

    @property
    def n_segments(self) -> int:
        return int(self.seg_start.size)

    @property
    def offsets_um(self) -> np.ndarray:
        """(K,) Z offset of the workpiece in each layer [µm]: the command W = w − Z_k."""
        return self.bottoms_um - 0.5 * self.margin_um

    @property
    def stroke_used_um(self) -> np.ndarray:
        """(K,) W range each layer executes [µm], within the travel by construction."""
        return self.w_high - np.minimum(self.w_low, self.bottoms_um)

    @property
    def first_phi(self) -> np.ndarray:
        """(K,) angle [rad] where each layer's first segment starts."""
        return self.seg_start[self.seg_ptr[:-1]]

    @property
    def last_phi(self) -> np.ndarray:
        """(K,) angle [rad] where each layer's last segment ends."""
        return self.seg_end[self.seg_ptr[1:] - 1]

    @property
    def seg_layer(self) -> np.ndarray:
        """(M,) layer of each segment."""
        return np.repeat(np.arange(self.n_layers), np.diff(self.seg_ptr))

    def segments_of(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """(start, end) angles [rad] of layer ``k``'s segments."""
        sl = slice(int(self.seg_ptr[k]), int(self.seg_ptr[k + 1]))
        return self.seg_start[sl], self.seg_end[sl]


@njit(nogil=True, cache=True, inline="always")
def _cross(phi1: float, w1: float, phi2: float, w2: float, level: float) -> float:  # pragma: no cover - jit
    # where the linear command between two samples reaches ``level``; the same arithmetic for
    # a zone's top and the next zone's bottom, so one layer exits exactly where the next enters
    return phi1 + (level - w1) / (w2 - w1) * (phi2 - phi1)


@njit(nogil=True, cache=True, inline="always")
def _zone_of(w: float, levels: np.ndarray) -> int:  # pragma: no cover - jit
    nz = levels.size - 1
    j = int(math.floor((w - levels[0]) / (levels[1] - levels[0])))
    return min(max(j, 0), nz - 1)


# one loop over the samples, above the complexity gate: with each zone's step in an inlined
# helper it ran 20× slower (plan_layers over 4 M samples: 1.31 against 0.066 s, the same
# plan; docs/performance.md)
@njit(nogil=True, cache=True)
def _plan_kernel(  # noqa: C901
    phi: np.ndarray,
    w: np.ndarray,
    start: int,
    levels: np.ndarray,
    zones: tuple[np.ndarray, ...],
    outputs: tuple[np.ndarray, ...],
) -> int:  # pragma: no cover - jit
    """Segments of every zone over samples ``start..`` of one chunk (state carried in the
    arrays between chunks). Returns the sample it stopped at (the output was full) or -1."""
    in_run, started, seg_open, last_ge, lo, hi, dips = zones
    out_z, out_a, out_b, count = outputs
    nz = levels.size - 1
    cap = out_z.size
    for i in range(start, phi.size - 1):
        p1, w1, p2, w2 = phi[i], w[i], phi[i + 1], w[i + 1]
        j_lo = max(_zone_of(min(w1, w2), levels) - 1, 0)
        j_hi = min(_zone_of(max(w1, w2), levels) + 1, nz - 1)
        if count[0] + (j_hi - j_lo + 1) > cap:
            return i
        for j in range(j_lo, j_hi + 1):
            b, t = levels[j], levels[j + 1]
            # a step through the zone is cut between its crossings even with no sample inside
            if min(w1, w2) <= b <= max(w1, w2) and w1 != w2:
                lo[j] = min(lo[j], b)
            if min(w1, w2) <= t <= max(w1, w2) and w1 != w2:
                hi[j] = max(hi[j], t)
            if in_run[j]:
                if w2 <= t:
                    if not started[j]:
                        if w2 >= b:
                            started[j] = True
                            seg_open[j] = _cross(p1, w1, p2, w2, b) if w1 < b else p1
                            last_ge[j] = p2
                    elif w2 >= b:
                        last_ge[j] = p2
                    elif w1 >= b:
                        last_ge[j] = _cross(p1, w1, p2, w2, b)
                        dips[j] = True
                else:
                    # exit on the upper limit
                    if not started[j]:
                        seg_open[j] = _cross(p1, w1, p2, w2, b) if w1 < b else p1
                    out_z[count[0]] = j
                    out_a[count[0]] = seg_open[j]
                    out_b[count[0]] = _cross(p1, w1, p2, w2, t)
                    count[0] += 1
                    started[j] = False
                    in_run[j] = False
            elif w2 <= t:
                # re-entry on the upper limit
                in_run[j] = True
                started[j] = True
                seg_open[j] = _cross(p1, w1, p2, w2, t)
                last_ge[j] = p2 if w2 >= b else _cross(p1, w1, p2, w2, b)
        j2 = _zone_of(w2, levels)
        lo[j2] = min(lo[j2], w2)
        hi[j2] = max(hi[j2], w2)
    return -1


class _Planner:
    """The state of :func:`_plan_kernel` over a stream of chunks."""

    def __init__(self, levels: np.ndarray) -> None:
        nz = levels.size - 1
        self.levels = levels
        self.in_run = np.zeros(nz, dtype=np.bool_)
        self.started = np.zeros(nz, dtype=np.bool_)
        self.seg_open = np.zeros(nz)
        self.last_ge = np.zeros(nz)
        self.lo = np.full(nz, np.inf)
        self.hi = np.full(nz, -np.inf)
        self.dips = np.zeros(nz, dtype=np.bool_)
        self.out_z = np.empty(1024, dtype=np.int64)
        self.out_a = np.empty(1024)
        self.out_b = np.empty(1024)
        self.count = np.zeros(1, dtype=np.int64)
        self.prev: tuple[float, float] | None = None

    def first(self, phi0: float, w0: float) -> None:
        b, t = self.levels[:-1], self.levels[1:]
        self.in_run[:] = w0 <= t
        self.started[:] = self.in_run & (w0 >= b)
        self.seg_open[:] = phi0
        self.last_ge[:] = phi0
        j = min(max(int(np.searchsorted(self.levels, w0, side="right")) - 1, 0), b.size - 1)
        self.lo[j] = self.hi[j] = w0

    def feed(self, phi: np.ndarray, w: np.ndarray) -> None:
        if self.prev is None:
            self.first(float(phi[0]), float(w[0]))
        else:
            phi = np.concatenate(([self.prev[0]], phi))
            w = np.concatenate(([self.prev[1]], w))
        start = 0
        while True:
            zones = (self.in_run, self.started, self.seg_open, self.last_ge, self.lo, self.hi, self.dips)
            outputs = (self.out_z, self.out_a, self.out_b, self.count)
            start = _plan_kernel(phi, w, start, self.levels, zones, outputs)
            if start < 0:
                break
            if self.out_z.size >= MAX_SEGMENTS:
                raise ValueError(
                    f"the layered trajectory needs more than {MAX_SEGMENTS:,} exit/re-entry segments: "
                    "the commands cross the stroke zones at almost every feature; a longer stroke "
                    "(or a slow tool servo) is needed"
                )
            grow = self.out_z.size * 2
            self.out_z = np.resize(self.out_z, grow)
            self.out_a = np.resize(self.out_a, grow)
            self.out_b = np.resize(self.out_b, grow)
        self.prev = (float(phi[-1]), float(w[-1]))

    def finish(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        n = int(self.count[0])
        z, a, b = self.out_z[:n], self.out_a[:n], self.out_b[:n]
        open_ = np.flatnonzero(self.started)
        z = np.concatenate((z, open_))
        a = np.concatenate((a, self.seg_open[open_]))
        b = np.concatenate((b, self.last_ge[open_]))
        keep = b > a  # a touch of a boundary is cut by the neighbouring zone's segment
        return z[keep], a[keep], b[keep]


Chunks = Callable[[], Iterable[tuple[np.ndarray, np.ndarray]]]


def plan_layers(chunks: Chunks, travel_um: float, margin_um: float, phi_end: float) -> LayerPlan:
    """The layered plan of a program whose executed commands along the spiral ``chunks()``
    yields in order as (φ [rad], w [µm]) arrays (linear between samples; called twice: once
    for the command range, once for the segments).

    Raises ValueError when the margin leaves no zone, or when the plan needs more than
    :data:`MAX_SEGMENTS` segments.
    """
    zone = travel_um - margin_um
    if not (zone > 0.0 and margin_um >= 0.0):
        raise ValueError(
            f"the layer margin {margin_um:g} µm leaves no stroke zone of the {travel_um:g} µm travel"
        )
    w_min, w_max = math.inf, -math.inf
    for _, w in chunks():
        w_min, w_max = min(w_min, float(np.min(w))), max(w_max, float(np.max(w)))
    if not (math.isfinite(w_min) and math.isfinite(w_max)):
        raise ValueError("the program's commands are not finite: no layered plan")
    n_zones = _zones(w_max - w_min, zone)
    levels = w_min + zone * np.arange(n_zones + 1, dtype=np.float64)
    levels[-1] = max(levels[-1], w_max)
    planner = _Planner(levels)
    for phi, w in chunks():
        planner.feed(np.asarray(phi, dtype=np.float64), np.asarray(w, dtype=np.float64))
    z, a, b = planner.finish()
    order = np.lexsort((a, z))
    z, a, b = z[order], a[order], b[order]
    used = np.unique(z)
    ptr = np.searchsorted(z, np.append(used, n_zones)).astype(np.int64)
    hi = planner.hi[used]
    # a layer whose segments dip below its zone executes those dips at the zone's bottom
    lo = np.where(planner.dips[used], np.minimum(planner.lo[used], levels[used]), planner.lo[used])
    return LayerPlan(levels, zone, margin_um, travel_um, levels[used], ptr, a, b, lo, hi, float(phi_end))


# samples of a table's command stream per chunk: a few tens of MB at a time
STREAM_CHUNK = 2_000_000


def command_stream(
    program: Program, values: np.ndarray, rho0_um: float, feed_um: float, commands_per_rev: int
) -> Iterable[tuple[np.ndarray, np.ndarray]]:
    """The commands the controller executes along the whole spiral, in chunks of
    (φ [rad], w [µm]) from the outer edge (φ = 0) to the centre (model §1, §3): for a table,
    its bilinear interpolation at every command instant (``commands_per_rev`` per
    revolution) and at the centre; for a spiral program, its points (linear in φ between
    them, the end values held to the spiral's ends)."""
    phi_end = spiral_end_rad(rho0_um, feed_um)
    if isinstance(program, SpiralPath):
        phi, w = program.phi, np.asarray(values, dtype=np.float64)
        if phi[0] > 0.0:
            phi, w = np.concatenate(([0.0], phi)), np.concatenate(([w[0]], w))
        if phi[-1] < phi_end:
            phi, w = np.append(phi, phi_end), np.append(w, w[-1])
        yield phi, w
        return
    step = 2.0 * math.pi / commands_per_rev
    n = int(math.ceil(phi_end / step - 1e-9))
    for first in range(0, n + 1, STREAM_CHUNK):
        phi = np.minimum(np.arange(first, min(first + STREAM_CHUNK, n + 1)) * step, phi_end)
        rho = spiral_radius(phi, rho0_um, feed_um)
        yield phi, interpolate(program, values, rho, np.mod(phi, 2.0 * math.pi))


@njit(nogil=True, cache=True)
def _cut_kernel(
    theta: np.ndarray,
    k0: int,
    n_passes: np.ndarray,
    w: np.ndarray,
    ptr: np.ndarray,
    seg_a: np.ndarray,
    seg_b: np.ndarray,
    offsets: np.ndarray,
    shifts: np.ndarray,
    travel: float,
    phi_end: float,
    out: np.ndarray,
) -> None:  # noqa: E501  # pragma: no cover - jit
    two_pi = 2.0 * math.pi
    n_layers = offsets.size
    for r in range(w.shape[0]):
        for k in range(n_passes[r]):
            # the last pass may sit a rounding error past the centre
            phi = min(two_pi * (k + k0) + theta[r], phi_end)
            best = math.inf
            for layer in range(n_layers):
                lo, hi = ptr[layer], ptr[layer + 1]
                # last segment of the layer starting at or before phi
                while lo < hi:
                    mid = (lo + hi) // 2
                    if seg_a[mid] <= phi:
                        lo = mid + 1
                    else:
                        hi = mid
                s = lo - 1
                if s >= ptr[layer] and phi <= seg_b[s]:
                    stroke = min(max(w[r, k] - offsets[layer], 0.0), travel)
                    best = min(best, offsets[layer] + stroke + shifts[layer])
            out[r, k] = best


def layered_pass_commands(
    plan: LayerPlan,
    ray_theta: np.ndarray,
    n_passes: np.ndarray,
    w: np.ndarray,
    z_error_um: float = 0.0,
    first_revolution: int = 0,
) -> np.ndarray:
    """Height [µm] of the tool's lowest point on every pass (R, Kmax) of a layered program:
    the passes ``w`` [µm] of the single spiral (pass k of the ray at θ is the tool at
    φ = 2πk + θ, model §5), each executed by every layer whose segments hold it at that
    layer's offset with W clipped to the travel, shifted by −j·``z_error_um`` for layer j,
    and the lowest kept (the lower envelope over the layers' passes). A pass no layer cuts
    is +inf. Entries k ≥ n_passes are left undefined. Column k is the spiral's pass k + k0,
    k0 = ``first_revolution`` (see :func:`ftsweep.stages.interpolation.tables.path_grid`)."""
    out = np.full(w.shape, np.inf)
    shifts = -z_error_um * np.arange(plan.n_layers, dtype=np.float64)
    _cut_kernel(
        np.ascontiguousarray(ray_theta, dtype=np.float64),
        int(first_revolution),
        np.ascontiguousarray(n_passes, dtype=np.int64),
        np.ascontiguousarray(w, dtype=np.float64),
        plan.seg_ptr,
        plan.seg_start,
        plan.seg_end,
        plan.offsets_um,
        shifts,
        float(plan.travel_um),
        float(plan.phi_end),
        out,
    )
    return out


class LayerTimes(NamedTuple):
    """Per-layer figures of a plan (arrays of K), see :func:`layer_times`."""

    start_radius_um: np.ndarray
    end_radius_um: np.ndarray
    segments: np.ndarray
    cut_length_um: np.ndarray
    span_rad: np.ndarray
    time_s: np.ndarray
    single_pass_s: float


def layer_times(
    plan: LayerPlan, rho0_um: float, feed_um: float, spindle_rpm: float, change_s: float
) -> LayerTimes:
    """Where each layer starts and ends (radii [µm] of its first and last segment), its
    segments, the spiral length it cuts [µm], and its machining time [s]: the spindle turns
    at ``spindle_rpm`` from its first segment's start to its last segment's end (the tool
    lifted between segments), plus ``change_s`` per segment (stop the spindle, move Z,
    restart: the retraction into the layer, then each re-entry). ``single_pass_s`` is the
    whole spiral at the same speed, without stops."""
    omega = spindle_rpm * 2.0 * math.pi / 60.0
    k = plan.n_layers
    seg_len = arc_length_between(plan.seg_start, plan.seg_end, rho0_um, feed_um)
    counts = np.diff(plan.seg_ptr)
    span = plan.last_phi - plan.first_phi
    return LayerTimes(
        start_radius_um=spiral_radius(plan.first_phi, rho0_um, feed_um),
        end_radius_um=spiral_radius(plan.last_phi, rho0_um, feed_um),
        segments=counts,
        cut_length_um=np.bincount(plan.seg_layer, weights=seg_len, minlength=k),
        span_rad=span,
        time_s=span / omega + change_s * counts,
        single_pass_s=plan.phi_end / omega,
    )


def layers_needed(span_um: float, travel_um: float, margin_um: float) -> int:
    """Zones of ``travel − margin`` [µm] a command span [µm] needs (1 if it fits the travel)."""
    if span_um <= travel_um:
        return 1
    return _zones(span_um, travel_um - margin_um)


def _zones(span_um: float, zone_um: float) -> int:
    """Zones of ``zone_um`` that cover a span [µm] (at least one)."""
    return max(1, math.ceil(span_um / zone_um - 1e-12))
