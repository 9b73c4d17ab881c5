"""Freeform Fresnel optics on an X-Y-Z-C lathe ([2]): contour slicing, quasi-spiral paths,
adaptive tool pose, tool-edge compensation and axis accelerations (model §1, §4, §5).

*Slicing* ([2] eq. 3). A surface f over its aperture is cut along contour lines into
facets of constant height h. With f_ref the surface's lowest point in the aperture and
j = floor((f − f_ref)/h) the facet's level counted from that point outwards,

    f_c = f − f_ref − j·h ∈ [0, h)

so f_c − f is constant on each facet and steps by h across each edge. [2] numbers facets
from outside to inside, n = N − j with N = ceil((max f − f_ref)/h); edge n, the contour
f_c(·, n) = h ([2] eq. 4), is the outer boundary of facet n, at level f_ref + (N − n + 1)·h.

*Quasi-spiral path* ([2] §2.2). K control points on every edge at equal angular increments
about the centroid of the area the edge encloses (eqs. 5–6, each ρ found by a golden-section
search along its ray), or, where an edge is not star-shaped about its centroid, K points at
equal arc length along the traced contour ([2] appendix A.3). Between edge n and edge n + 1
the path turns M_n times, each turn moving every point 1/M_n of the way from its control
point on edge n to the one on edge n + 1 (eq. 8, read as the continuous parameter
s = (m·K + k)/(M_n·K), m = 0..M_n − 1, k = 0..K − 1: [2]'s printed m(k − 1)/(M_n·K) is not
continuous between turns). M_n is the least integer keeping that step ≤ Δr, the feed per
turn (the purpose of eq. 7; eq. 7's estimate from the smallest slope on the edge is reported
beside it). The innermost facet closes on the surface's lowest point. Z = f_c of the facet,
except on the first turn onto a facet, where Z climbs the step of h across the edge along the
turn (:func:`entry_offset`) instead of between two points.

*Adaptive tool pose* ([2] §2.3, eq. 9). The spindle angle φ and the tool's global (x, y)
follow from R(φ)·(x, y) = (X, Y) and R(φ)·(−cos Δφ, sin Δφ) = ∇f/|∇f| with
R(φ) = [[cos φ, sin φ], [−sin φ, cos φ]]: the rake face, whose normal is the global y axis,
then faces the cutting direction (perpendicular to the local gradient) when Δφ = 0.

*Tool-edge compensation* ([2] §2.4). e_z = max over Δρ ≥ 0 of f(P + u·Δρ) − f(P) −
(R − sqrt(R² − Δρ²)), u = ∇f/|∇f| (eq. 10), or for a locally straight profile
e_z = R·tan β·tan(β/2), β = atan |∇f| (eq. 12); the tool tip runs at z = Z + e_z (eq. 13).

*Accelerations* ([2] eq. 14): a_k = 2·(Δ_k/T_k − Δ_{k−1}/T_{k−1})/(T_k + T_{k−1}) per axis.

Lengths µm, angles rad, times s.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from ftsweep.stages.sampling.geometry import SurfaceFn

CONTROL_SCHEMES = ("auto", "polar", "arc")
GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


class FresnelError(ValueError):
    """The surface cannot be sliced or turned along a quasi-spiral path; the message says why."""


# --------------------------------------------------------------------------- slicing
def facet_level(f: np.ndarray, f_ref: float, h: float) -> np.ndarray:
    """Facet level j = floor((f − f_ref)/h) of heights f [µm] ([2] eq. 3; j = N − n)."""
    return np.floor((np.asarray(f, dtype=np.float64) - f_ref) / h).astype(np.int64)


def sliced(
    f: np.ndarray, f_ref: float, h: float, level: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Fresnel heights f_c = f − f_ref − j·h [µm] and the facet level j ([2] eq. 3). ``level``
    fixes j (the facet a path point is cut on) instead of taking it from f."""
    j = facet_level(f, f_ref, h) if level is None else np.asarray(level, dtype=np.int64)
    return np.asarray(f, dtype=np.float64) - f_ref - j * h, j


def fresnel_surface(fn: SurfaceFn, f_ref: float, h: float) -> SurfaceFn:
    """The surface callable of the Fresnel form of ``fn`` ([2] eq. 3): heights f_c [µm],
    slopes those of f (the facets are the surface shifted by whole facet heights)."""

    def evaluate(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        f, fx, fy = fn(x, y)
        return sliced(f, f_ref, h)[0], fx, fy

    return evaluate


def golden_min(
    fun: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray, iterations: int = 60
) -> np.ndarray:
    """Golden-section search, vectorised: for every i the t in [lo_i, hi_i] minimising the
    unimodal ``fun(t)[i]`` (each bracket shrinks by 0.618 per iteration)."""
    a, b = np.array(lo, dtype=np.float64), np.array(hi, dtype=np.float64)
    c, d = b - GOLDEN * (b - a), a + GOLDEN * (b - a)
    fc, fd = fun(c), fun(d)
    for _ in range(iterations):
        left = fc < fd
        # the minimum lies in [a, d] (left) or [c, b]; the surviving interior point carries over
        b = np.where(left, d, b)
        a = np.where(left, a, c)
        keep, fkeep = np.where(left, c, d), np.where(left, fc, fd)
        new = np.where(left, b - GOLDEN * (b - a), a + GOLDEN * (b - a))
        fnew = fun(new)
        c, fc = np.where(left, new, keep), np.where(left, fnew, fkeep)
        d, fd = np.where(left, keep, new), np.where(left, fkeep, fnew)
    return 0.5 * (a + b)


# --------------------------------------------------------------------------- edges
def polygon_centroid(points: np.ndarray) -> np.ndarray:
    """Centroid [µm] of the area a closed polygon (K, 2) encloses ([2] eq. 6)."""
    x, y = points[:, 0], points[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    area = 0.5 * cross.sum()
    if abs(area) < 1e-300:
        return points.mean(axis=0)
    return np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6.0 * area)


def ray_crossings(
    fn: SurfaceFn, centre: np.ndarray, theta: np.ndarray, level: float, reach: float, samples: int = 96
) -> tuple[np.ndarray, np.ndarray]:
    """Where rays from ``centre`` [µm] at angles ``theta`` [rad] cross the contour f = level
    ([2] eq. 5): ρ [µm] by golden-section search on |f − level| in the bracket of the first
    sign change found by sampling the ray to ``reach`` [µm], and the number of sign changes
    on each ray (1 on an edge star-shaped about the centre). Raises FresnelError where a ray
    does not reach the contour."""
    u, v = np.cos(theta), np.sin(theta)
    t = np.linspace(0.0, reach, samples + 1)
    f = fn(centre[0] + np.outer(u, t), centre[1] + np.outer(v, t))[0] - level
    change = np.signbit(f[:, 1:]) != np.signbit(f[:, :-1])
    count = change.sum(axis=1)
    if not np.all(count > 0):
        raise FresnelError(
            f"the contour at level {level:.6g} µm is not closed within {reach:.6g} µm of its centre"
        )
    first = np.argmax(change, axis=1)

    def gap(r: np.ndarray) -> np.ndarray:
        return np.abs(fn(centre[0] + u * r, centre[1] + v * r)[0] - level)

    rho = golden_min(gap, t[first], t[first + 1])
    return rho, count


def polar_edge(
    fn: SurfaceFn, start: np.ndarray, level: float, theta: np.ndarray, reach: float
) -> tuple[np.ndarray, np.ndarray, bool]:
    """Control points (K, 2) [µm] of the contour f = level at the angles θ_k about the centroid
    of the area it encloses ([2] eqs. 5–6), the centroid found by iterating from ``start``;
    and whether the contour is star-shaped about it (every ray crosses it once)."""
    centre = np.asarray(start, dtype=np.float64)
    for _ in range(8):
        rho, count = ray_crossings(fn, centre, theta, level, reach)
        points = centre + np.column_stack([rho * np.cos(theta), rho * np.sin(theta)])
        new = polygon_centroid(points)
        moved = float(np.hypot(*(new - centre)))
        centre = new
        if moved < 1e-9 * max(reach, 1.0):
            break
    rho, count = ray_crossings(fn, centre, theta, level, reach)
    points = centre + np.column_stack([rho * np.cos(theta), rho * np.sin(theta)])
    return points, centre, bool(np.all(count == 1))


def _onto_level(fn: SurfaceFn, p: np.ndarray, level: float, steps: int = 4) -> np.ndarray:
    """Newton steps along the gradient from p [µm] onto the contour f = level."""
    for _ in range(steps):
        f, fx, fy = fn(p[..., 0], p[..., 1])
        g2 = np.maximum(fx * fx + fy * fy, 1e-300)
        p = p - np.stack([fx, fy], axis=-1) * ((f - level) / g2)[..., None]
    return p


def traced_edge(
    fn: SurfaceFn, start: np.ndarray, level: float, count: int, step: float, clockwise: bool = True
) -> np.ndarray:
    """K = ``count`` control points (K, 2) [µm] at equal arc length along the contour
    f = level, the first at ``start`` (put on the contour), found by marching along the
    tangent with ``step`` [µm] and correcting onto the contour ([2] appendix A.3, eqs. 18–19).
    Raises FresnelError when the contour does not close."""
    p0 = _onto_level(fn, np.asarray(start, dtype=np.float64), level)
    sign = -1.0 if clockwise else 1.0
    pts = [p0]
    p = p0
    travelled = 0.0
    for _ in range(2_000_000):
        _, fx, fy = fn(p[0:1], p[1:2])
        g = math.hypot(fx[0], fy[0])
        if g == 0.0:
            raise FresnelError(f"the contour at level {level:.6g} µm meets a flat point (∇f = 0)")
        # tangent: the gradient turned by +90° runs anticlockwise about a minimum
        p = _onto_level(fn, p + sign * step * np.array([-fy[0], fx[0]]) / g, level)
        travelled += step
        pts.append(p)
        if travelled > 4.0 * step and math.hypot(*(p - p0)) < step:
            break
    else:
        raise FresnelError(f"the contour at level {level:.6g} µm does not close")
    pts[-1] = p0
    poly = np.array(pts)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poly, axis=0).T))])
    want = np.arange(count) * (s[-1] / count)
    out = np.column_stack([np.interp(want, s, poly[:, 0]), np.interp(want, s, poly[:, 1])])
    return _onto_level(fn, out, level)


def inward_start(fn: SurfaceFn, p: np.ndarray, level: float) -> np.ndarray:
    """The point of the contour f = level reached from p [µm] down the local gradient, where
    the next edge's first control point lies ([2] appendix A.3)."""
    _, fx, fy = fn(p[0:1], p[1:2])
    g = math.hypot(fx[0], fy[0])
    u = -np.array([fx[0], fy[0]]) / g
    f0 = fn(p[0:1], p[1:2])[0][0]
    # a first guess from the slope, then Newton onto the contour
    return _onto_level(fn, p + u * max((f0 - level) / g, 0.0), level, steps=8)


# --------------------------------------------------------------------------- quasi-spiral
class QuasiSpiral(NamedTuple):
    """A quasi-spiral path over the facets of a Fresnel surface ([2] §2.2), outermost facet
    first. Lengths µm.

    edges : (N + 1, K, 2) control points of edges 1..N and, last, the lowest point repeated.
    centres : (N, 2) the centroid of each edge (polar scheme) or its first point (arc).
    turns : (N,) M_n, turns on facet n.
    turns_eq7 : (N,) [2] eq. 7's estimate of M_n from the smallest slope on edge n.
    xy : (P, 2) path points in the workpiece frame, K per turn, plus the closing point.
    facet : (P,) facet n of every point (0 = outermost).
    level : (P,) facet level j = N − 1 − n.
    scheme : ``polar`` (eqs. 5–6) or ``arc`` (appendix A.3).
    """

    edges: np.ndarray
    centres: np.ndarray
    turns: np.ndarray
    turns_eq7: np.ndarray
    xy: np.ndarray
    facet: np.ndarray
    level: np.ndarray
    scheme: str

    @property
    def n_facets(self) -> int:
        return int(self.turns.size)

    @property
    def points_per_turn(self) -> int:
        return int(self.edges.shape[1])

    @property
    def n_turns(self) -> int:
        return int(self.turns.sum())

    def enters_facet(self, turn: int) -> bool:
        """Whether ``turn`` is the first turn on its facet after another (every facet holds
        whole turns of K points)."""
        k = self.points_per_turn
        return bool(turn > 0 and self.facet[turn * k] != self.facet[turn * k - 1])


def turns_needed(outer: np.ndarray, inner: np.ndarray, feed: float) -> int:
    """M_n: the least number of turns keeping every control point's step per turn between
    two edges (K, 2) [µm] at or below the feed Δr [µm] (the purpose of [2] eq. 7)."""
    return max(1, math.ceil(float(np.max(np.hypot(*(inner - outer).T))) / feed - 1e-12))


def interpolate(edges: np.ndarray, turns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Path points (Σ M_n·K + 1, 2) [µm] between consecutive edges ([2] eq. 8, module
    docstring) and the facet of each; the last point closes on the final edge."""
    k = edges.shape[1]
    parts, facet = [], []
    for n, m in enumerate(turns):
        s = np.arange(m * k) / (m * k)
        a = np.tile(edges[n], (m, 1))
        b = np.tile(edges[n + 1], (m, 1))
        parts.append(a + s[:, None] * (b - a))
        facet.append(np.full(m * k, n))
    parts.append(edges[-1][:1])
    facet.append(np.array([len(turns) - 1]))
    return np.concatenate(parts), np.concatenate(facet)


def entry_offset(facet: np.ndarray, count: int, h: float) -> np.ndarray:
    """The Z offsets [µm] that spread every entry onto a new facet over the facet's first
    turn: Z = f_c rises by h across the edge ([2] eq. 3), and instead of that step between two
    points the tool climbs it along the first turn by a half-cosine, −h·(1 + cos(π·k/K))/2 at
    point k of the turn (K = ``count``), continuous with the last turn of the facet before and
    with zero slope at both ends; 0 elsewhere. The first turn runs within one feed Δr of the
    edge, so the ramp cuts only inside the band the nose forms the wall in anyway
    (sqrt(2·Rc·h) + Δr, left out of the form error); a step of h in one timestep would set the
    Z acceleration of the whole program (docs/kinds.md, "Freeform Fresnel optics")."""
    out = np.zeros(facet.size)
    starts = np.flatnonzero(np.diff(facet) != 0) + 1
    k = np.arange(count)
    for first in starts:
        span = k[: out.size - first]
        out[first : first + span.size] = -h * 0.5 * (1.0 + np.cos(np.pi * span / count))
    return out


# --------------------------------------------------------------------------- tool pose
def pose(
    xy: np.ndarray, gx: np.ndarray, gy: np.ndarray, deviation: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Spindle angle φ [rad] (unwrapped) and the tool's global x, y [µm] that put the tool on
    path point (X, Y) with the rake face turned Δφ = ``deviation`` [rad] from the cutting
    direction ([2] eq. 9): φ = atan2(sin Δφ, −cos Δφ) − atan2(∂f/∂y, ∂f/∂x), (x, y) = R(φ)ᵀ(X, Y).
    A point where ∇f = 0 keeps the previous point's angle."""
    ang = np.arctan2(gy, gx)
    flat = (gx == 0.0) & (gy == 0.0)
    if flat.any():
        idx = np.where(~flat, np.arange(ang.size), 0)
        np.maximum.accumulate(idx, out=idx)
        ang = ang[idx]
    phi = np.unwrap(math.atan2(math.sin(deviation), -math.cos(deviation)) - ang)
    return (phi, *global_of(phi, xy))


def global_of(phi: np.ndarray, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The tool's global (x, y) [µm] = R(φ)ᵀ·(X, Y) of path points (X, Y) at spindle angles φ."""
    c, s = np.cos(phi), np.sin(phi)
    return c * xy[:, 0] - s * xy[:, 1], s * xy[:, 0] + c * xy[:, 1]


def workpiece_of(phi: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Path points (X, Y) [µm] of global tool positions: R(φ)·(x, y) ([2] eq. 9, rows 1–2)."""
    c, s = np.cos(phi), np.sin(phi)
    return np.column_stack([c * x + s * y, -s * x + c * y])


# --------------------------------------------------------------------------- compensation
def compensation_straight(gx: np.ndarray, gy: np.ndarray, nose_radius: float) -> np.ndarray:
    """e_z = R·tan β·tan(β/2) [µm], β = atan |∇f| ([2] eq. 12: the profile along the gradient
    taken as a straight line)."""
    tan_b = np.hypot(gx, gy)
    return nose_radius * tan_b * np.tan(0.5 * np.arctan(tan_b))


def compensation_exact(
    fn: SurfaceFn, x: np.ndarray, y: np.ndarray, nose_radius: float, tol_um: float = 1e-6
) -> np.ndarray:
    """e_z [µm] of [2] eq. 10: the largest height of the surface above the nose arc along the
    uphill gradient direction, max over 0 ≤ Δρ < R of f(P + u·Δρ) − f(P) − (R − sqrt(R² − Δρ²)),
    by golden-section search (unimodal where the surface's curvature along u is below 1/R)
    until the bracket on Δρ is below ``tol_um`` [µm]: at the maximum, an offset error δ
    lowers e_z by about ½·(1/R + curvature)·δ², ~1e-14 µm at 1e-6 µm. Zero where ∇f = 0."""
    f0, gx, gy = fn(x, y)
    g = np.hypot(gx, gy)
    safe = np.where(g > 0.0, g, 1.0)
    ux, uy = gx / safe, gy / safe
    r = float(nose_radius)

    def lift(d: np.ndarray) -> np.ndarray:
        return fn(x + ux * d, y + uy * d)[0] - f0 - (r - np.sqrt(np.maximum(r * r - d * d, 0.0)))

    zero = np.zeros_like(g)
    # each iteration keeps 0.618 of the bracket [0, R)
    iterations = max(1, math.ceil(math.log(tol_um / r) / math.log(GOLDEN)))
    d = golden_min(lambda t: -lift(t), zero, zero + r * (1.0 - 1e-9), iterations)
    return np.where(g > 0.0, np.maximum(lift(d), 0.0), 0.0)


# --------------------------------------------------------------------------- accelerations
@njit(nogil=True, cache=True)
def _turn_relative_into(
    steps: np.ndarray, deltas: np.ndarray, inv_limit: np.ndarray, first: bool, rel: np.ndarray
) -> float:  # pragma: no cover - jit
    """Relative accelerations a/a_lim over one turn (eq. 14) into ``rel[:K]`` (K, A) and their
    largest magnitude; the other arguments as :func:`ftsweep.stages.paths.turnopt.turn_cost_into`'s."""
    k_n = steps.size
    big = 0.0
    for k in range(k_n):
        if first and k == 0:
            rel[k, :] = 0.0
            continue
        t0 = steps[k - 1] if k > 0 else steps[k_n - 1]
        t1 = steps[k]
        # divisions per step, not per axis (the optimiser evaluates this ~10^5 times a program)
        inv_t0, inv_t1, c = 1.0 / t0, 1.0 / t1, 2.0 / (t0 + t1)
        for j in range(deltas.shape[1]):
            a = (deltas[k + 1, j] * inv_t1 - deltas[k, j] * inv_t0) * c
            rel[k, j] = a * inv_limit[j]
            big = max(big, abs(rel[k, j]))
    return big


@njit(nogil=True, cache=True)
def _turn_relative(
    steps: np.ndarray, deltas: np.ndarray, inv_limit: np.ndarray, first: bool
) -> tuple[Any, ...]:  # pragma: no cover - jit
    """Relative accelerations a/a_lim (K, A) over one turn (eq. 14) and their largest
    magnitude."""
    rel = np.zeros((steps.size, deltas.shape[1]))
    return rel, _turn_relative_into(steps, deltas, inv_limit, first, rel)


@njit(nogil=True, cache=True)
def turn_peak(
    steps: np.ndarray, deltas: np.ndarray, inv_limit: np.ndarray, first: bool
) -> float:  # pragma: no cover - jit
    """Largest relative acceleration max |a/a_lim| over one turn (arguments of
    :func:`ftsweep.stages.paths.turnopt.turn_cost_into`)."""
    return _turn_relative(steps, deltas, inv_limit, first)[1]


# --------------------------------------------------------------------------- planning
def plan(
    fn: SurfaceFn,
    apex: np.ndarray,
    f_ref: float,
    h: float,
    n_facets: int,
    feed: float,
    count: int,
    reach: float,
    scheme: str = "auto",
) -> QuasiSpiral:
    """The quasi-spiral path ([2] §2.2) over ``n_facets`` facets of height h [µm] about the
    surface's lowest point ``apex`` (X, Y) [µm] of height f_ref [µm], with feed Δr [µm] per
    turn and K = ``count`` control points per edge, run clockwise (so that the spindle angle
    of eq. 9 increases). ``reach`` [µm] bounds the search for each edge along its rays;
    ``scheme``: ``polar`` (eqs. 5–6), ``arc`` (appendix A.3) or ``auto`` (polar where every
    edge is star-shaped about its centroid, else arc)."""
    if scheme not in CONTROL_SCHEMES:
        raise FresnelError(f"control-point scheme {scheme!r} is not one of {', '.join(CONTROL_SCHEMES)}")
    if n_facets < 1 or count < 8:
        raise FresnelError(f"need at least one facet and 8 control points per edge (got {n_facets}, {count})")
    apex = np.asarray(apex, dtype=np.float64)
    theta = -2.0 * np.pi * np.arange(count) / count
    levels = f_ref + h * (n_facets - np.arange(n_facets))
    edges, centres, star = [], [], True
    if scheme != "arc":
        for lvl in levels:
            pts, centre, ok = polar_edge(fn, apex, lvl, theta, reach)
            edges.append(pts)
            centres.append(centre)
            star &= ok
        if not star and scheme == "polar":
            raise FresnelError(
                "an edge is not star-shaped about its centroid (a ray crosses it more than once); "
                "use the arc-length control points of [2] appendix A.3 (scheme 'arc')"
            )
    used = "polar" if scheme != "arc" and star else "arc"
    if used == "arc":
        edges, centres = [], []
        rho, _ = ray_crossings(fn, apex, np.zeros(1), levels[0], reach)
        start = apex + np.array([rho[0], 0.0])
        for lvl in levels:
            start = inward_start(fn, start, lvl) if edges else start
            step = 2.0 * np.pi * max(float(np.hypot(*(start - apex))), h) / (4.0 * count)
            edges.append(traced_edge(fn, start, lvl, count, step))
            centres.append(edges[-1][0])
    edges.append(np.tile(apex, (count, 1)))
    stack = np.array(edges)
    turns = np.array([turns_needed(stack[n], stack[n + 1], feed) for n in range(n_facets)])
    slopes = [np.hypot(*fn(e[:, 0], e[:, 1])[1:]).min() for e in stack[:-1]]
    eq7 = np.array([(h / feed) / max(s, 1e-300) for s in slopes])
    xy, facet = interpolate(stack, turns)
    return QuasiSpiral(stack, np.array(centres), turns, eq7, xy, facet, n_facets - 1 - facet, used)
