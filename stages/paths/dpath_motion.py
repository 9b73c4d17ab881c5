"""Motion of a D path ([5]) once planned: the bound of its second differences, the junctions
of cuts and transitions, the times of its points at a spindle speed or a feed-rate, the
axis motion and accelerations over a command period, its Z commands, its samples at the
controller's period and where the rays of the simulation cross it. Angles in rad, lengths
in µm, times in s."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numba import njit

from ftsweep.stages.kinematics import axes as kinematics
from ftsweep.stages.paths.dpath import TIMINGS, DPath, _evaluate_kernel, _poly, cut_radius, radius_at


@njit(nogil=True, cache=True)
def _peak_over(
    phi: np.ndarray,
    mid: np.ndarray,
    h: float,
    points: np.ndarray,
    bounds: np.ndarray,
    cut_d: np.ndarray,
    cut_centre: np.ndarray,
    coeffs: np.ndarray,
    peak: float,
) -> float:  # pragma: no cover - jit
    """``peak`` raised to |ρ(φ + h) − 2ρ(φ) + ρ(φ − h)| [µm] at the ``points`` (ascending
    indices into ``phi``; ``mid`` = ρ(φ)): the neighbours evaluated by :func:`_evaluate_kernel`
    a block at a time, so no array of the whole path is formed."""
    block = 4096
    ahead, behind = np.empty(block), np.empty(block)
    rho_a, rho_b = np.empty(block), np.empty(block)
    flags, none = np.empty(block, dtype=np.bool_), np.empty(0)
    for start in range(0, points.size, block):
        n = min(block, points.size - start)
        for m in range(n):
            p = phi[points[start + m]]
            ahead[m], behind[m] = p + h, p - h
        _evaluate_kernel(ahead[:n], bounds, cut_d, cut_centre, coeffs, rho_a, none, none, flags, False)
        _evaluate_kernel(behind[:n], bounds, cut_d, cut_centre, coeffs, rho_b, none, none, flags, False)
        for m in range(n):
            d = abs(rho_a[m] - 2.0 * mid[points[start + m]] + rho_b[m])
            if d > peak:
                peak = d
    return peak


@njit(nogil=True, cache=True, inline="always")
def _cut_difference_bound(
    h: float, start: float, end: float, d: float, centre: float, reach: float
) -> float:  # pragma: no cover - jit
    """An upper bound [µm] of the computed |ρ(φ + h) − 2ρ(φ) + ρ(φ − h)| at any point whose
    φ ± h lie inside the cut from ``start`` to ``end`` [rad] (distance ``d`` [µm], centre
    ``centre`` [rad]), |φ| + h ≤ ``reach`` [rad]. Exactly, the second difference is
    h²·ρ''(ξ) for some ξ between, and ρ'' = d·sec x·(tan² x + sec² x) ([5] eq. 3) grows with
    |x|: at most h²·ρ'' at the cut's farther end. Computed, each ρ is off by at most ρ'·(the
    rounding of φ ± h − centre, 1.2e-16·reach) plus two ulp: the bound adds 16× that (inf
    where the cut comes within 0.07 rad of x = π/2)."""
    xm = max(abs(start - centre), abs(end - centre))
    if not xm < 1.5:
        return math.inf
    sec = 1.0 / math.cos(xm)
    tan = math.tan(xm)
    ad = abs(d)
    curv = ad * sec * (tan * tan + sec * sec)
    slope = ad * sec * tan
    return h * h * curv * (1.0 + 1e-9) + 16.0 * (4.0 * slope * 1.2e-16 * reach + 4.0 * 4.5e-16 * ad * sec)


@njit(nogil=True, cache=True, inline="always")
def _transition_difference_bound(
    h: float, span: float, b: np.ndarray, reach: float
) -> float:  # pragma: no cover - jit
    """:func:`_cut_difference_bound` for a transition ρ = Σ b_m τ^m, τ = (φ − a)/``span``
    ([5] eq. 4): ρ'' = P''(τ)/span², whose largest |value| on [0, 1] lies at an end or where
    the derivative of P'' vanishes (a quadratic's roots); the bound adds 1e-12 of
    Σ m(m − 1)|b_m| for the rounding of those roots and values, and 16× the rounding of the
    three Horner evaluations (12 ulp of Σ|b_m| each) and of τ (ρ'·(1.2e-16·reach/span + 2 ulp))."""
    s0 = s1 = s2 = 0.0
    for m in range(6):
        s0 += abs(b[m])
        s1 += m * abs(b[m])
        s2 += m * (m - 1) * abs(b[m])
    # P'' = c0 + c1 τ + c2 τ² + c3 τ³; its derivative c1 + 2 c2 τ + 3 c3 τ²
    c0, c1, c2, c3 = 2.0 * b[2], 6.0 * b[3], 12.0 * b[4], 20.0 * b[5]
    top = max(abs(c0), abs(c0 + c1 + c2 + c3))
    qa, qb, qc = 3.0 * c3, 2.0 * c2, c1
    r0 = r1 = -1.0
    if qa != 0.0:
        disc = qb * qb - 4.0 * qa * qc
        if disc >= 0.0:
            sq = math.sqrt(disc)
            r0, r1 = (-qb - sq) / (2.0 * qa), (-qb + sq) / (2.0 * qa)
    elif qb != 0.0:
        r0 = -qc / qb
    for t in (r0, r1):
        if 0.0 < t < 1.0:
            top = max(top, abs(c0 + t * (c1 + t * (c2 + t * c3))))
    curv = (top + 1e-12 * s2) / (span * span)
    rounding = 4.0 * s1 * (1.2e-16 * reach / span + 4.5e-16) + 4.0 * 12.0 * 2.3e-16 * s0
    return h * h * curv * (1.0 + 1e-9) + 16.0 * rounding


@njit(nogil=True, cache=True)
def _peak_second_difference(
    phi: np.ndarray,
    mid: np.ndarray,
    h: float,
    bounds: np.ndarray,
    cut_d: np.ndarray,
    cut_centre: np.ndarray,
    coeffs: np.ndarray,
) -> float:  # pragma: no cover - jit
    """max |ρ(φ + h) − 2ρ(φ) + ρ(φ − h)| [µm] over the points ``phi`` (ascending) whose φ ± h
    stay on the program (``mid`` = ρ(φ)). A point whose φ ± h lie strictly inside its own
    segment (a cut, or a transition's polynomial) is evaluated only where that segment's
    bound (:func:`_cut_difference_bound`, :func:`_transition_difference_bound`) reaches the
    peak of the points near the junctions: the result is the largest over every point, to
    the last bit, while the inner points of most segments of a smooth path are left out."""
    inner = np.full(phi.size, -1, dtype=np.int64)
    points = np.empty(phi.size, dtype=np.int64)
    n = _split_inner(phi, h, bounds, coeffs.shape[0], inner, points)
    peak = _peak_over(phi, mid, h, points[:n], bounds, cut_d, cut_centre, coeffs, 0.0)
    reach = max(abs(phi[0]), abs(phi[-1])) + h
    bound = np.full(bounds.size, math.nan)
    n = 0
    for k in range(phi.size):
        s = inner[k]
        if s < 0:
            continue
        if math.isnan(bound[s]):
            bound[s] = _segment_bound(h, s, bounds, cut_d, cut_centre, coeffs, reach)
        if bound[s] >= peak:
            points[n] = k
            n += 1
    return _peak_over(phi, mid, h, points[:n], bounds, cut_d, cut_centre, coeffs, peak)


@njit(nogil=True, cache=True, inline="always")
def _segment_bound(
    h: float,
    s: int,
    bounds: np.ndarray,
    cut_d: np.ndarray,
    cut_centre: np.ndarray,
    coeffs: np.ndarray,
    reach: float,
) -> float:  # pragma: no cover - jit
    """The bound of |second difference| [µm] inside segment ``s`` (even: a cut, odd: a transition)."""
    i = s // 2
    if s % 2 == 0:
        return _cut_difference_bound(h, bounds[s], bounds[s + 1], cut_d[i], cut_centre[i], reach)
    return _transition_difference_bound(h, bounds[s + 1] - bounds[s], coeffs[i], reach)


@njit(nogil=True, cache=True, inline="always")
def _split_inner(
    phi: np.ndarray, h: float, bounds: np.ndarray, nt: int, inner: np.ndarray, points: np.ndarray
) -> int:  # pragma: no cover - jit
    """Mark in ``inner`` the segment of each point whose φ ± h lie strictly inside it, and
    list the other points on the program in ``points``; returns how many those are."""
    lo, hi = phi[0], phi[-1]
    nb = bounds.size
    n = 0
    seg = 0
    for k in range(phi.size):
        p = phi[k]
        if not (p - h >= lo and p + h <= hi):
            continue
        if p < bounds[seg]:
            seg = max(np.searchsorted(bounds, p, side="right") - 1, 0)
        while seg + 1 < nb and bounds[seg + 1] <= p:
            seg += 1
        # strictly inside: all three evaluations take this segment's expression
        # (_evaluate_kernel; without transition polynomials, odd segments take a cut's)
        own = seg % 2 == 0 or seg // 2 < nt
        if own and seg + 1 < nb and p - h > bounds[seg] and p + h < bounds[seg + 1]:
            inner[k] = seg
        else:
            points[n] = k
            n += 1
    return n


def junctions(path: DPath) -> dict[str, np.ndarray]:
    """ρ, dρ/dθ and d²ρ/dθ² on both sides of every junction of a cut and a transition:
    ``jump_rho``, ``jump_d1``, ``jump_d2`` (transition side minus cut side; µm, µm/rad,
    µm/rad²) and ``rho``, ``d1``, ``d2`` (the cut side), one entry per junction in path order."""
    if path.coeffs.shape[0] == 0:
        empty = np.empty(0)
        return {k: empty for k in ("rho", "d1", "d2", "jump_rho", "jump_d1", "jump_d2")}
    half = np.asarray(path.geometry.half_angle(path.cut_d))
    ends = cut_radius(path.cut_d[:-1], half[:-1])
    starts = cut_radius(path.cut_d[1:], -half[1:])
    span = path.bounds[2::2] - path.bounds[1:-1:2]
    at0 = _poly(path.coeffs, np.zeros(span.size), span)
    at1 = _poly(path.coeffs, np.ones(span.size), span)
    out = {}
    for name, q in zip(("rho", "d1", "d2"), range(3), strict=True):
        cut_side = np.empty(2 * span.size)
        cut_side[0::2], cut_side[1::2] = ends[q], starts[q]
        t_side = np.empty(2 * span.size)
        t_side[0::2], t_side[1::2] = at0[q], at1[q]
        out[name] = cut_side
        out[f"jump_{name}"] = t_side - cut_side
    return out


def transition_z(path: DPath, z_cut: np.ndarray) -> np.ndarray:
    """Z [µm] of every point given Z on the cut points ``z_cut`` (in path order): on each
    transition linear in θ from the end of one cut to the start of the next ([5] eq. 14)."""
    on = path.cut >= 0
    z = np.empty(path.n_points)
    z[on] = z_cut
    z[~on] = np.interp(path.phi[~on], path.phi[on], z_cut)
    return z


def point_times(
    phi: np.ndarray,
    rho: np.ndarray,
    z: np.ndarray,
    mode: str,
    spindle_rpm: float,
    feed_mm_min: float = math.nan,
    fed: np.ndarray | None = None,
) -> np.ndarray:
    """Time [s] of every point of a program (φ [rad], ρ and Z [µm]) from the first.

    ``spindle``: constant spindle speed, t = (φ − φ0)/ω. ``feed``: the XZC interpolation at
    a constant feed ``feed_mm_min`` along the tool's path over the part (step length
    sqrt(Δρ² + (ρ̄·Δφ)² + ΔZ²)), the C speed capped at ``spindle_rpm``; ``fed`` (P − 1
    bools) limits the feed to those steps (e.g. the cuts), the others run at the cap."""
    if mode not in TIMINGS:
        raise ValueError(f"timing mode must be one of {', '.join(TIMINGS)}, got {mode!r}")
    omega = spindle_rpm * 2.0 * math.pi / 60.0
    dphi = np.diff(phi)
    dt = dphi / omega
    if mode == "feed":
        if not (math.isfinite(feed_mm_min) and feed_mm_min > 0.0):
            raise ValueError(f"the constant-feed mode needs a positive feed [mm/min], got {feed_mm_min!r}")
        mean_rho = 0.5 * (rho[1:] + rho[:-1])
        step_um = np.sqrt(np.diff(rho) ** 2 + (mean_rho * dphi) ** 2 + np.diff(z) ** 2)
        at_feed = np.maximum(dt, step_um / (feed_mm_min * 1000.0 / 60.0))
        dt = at_feed if fed is None else np.where(fed, at_feed, dt)
    return np.concatenate([[0.0], np.cumsum(dt)])


def axis_motion(t: np.ndarray, phi: np.ndarray, x_um: np.ndarray, z_um: np.ndarray) -> dict[str, np.ndarray]:
    """Velocities over the steps (P − 1) and accelerations at the points (P) of the X, Z and C
    axes along a program sampled at times ``t`` [s] (:mod:`ftsweep.stages.kinematics.axes`, the one
    scheme of every kind): ``x_feed_mm_s``, ``x_accel_m_s2``, ``z_velocity_mm_s``,
    ``z_accel_m_s2``, ``c_speed_rpm``, ``c_accel_rad_s2``."""
    m = kinematics.motion(t, np.column_stack([phi, x_um * 1e-6, z_um * 1e-6]))
    return {
        "x_feed_mm_s": m.velocity[:, 1] * 1e3,
        "x_accel_m_s2": m.accel[:, 1],
        "z_velocity_mm_s": m.velocity[:, 2] * 1e3,
        "z_accel_m_s2": m.accel[:, 2],
        "c_speed_rpm": m.velocity[:, 0] * 60.0 / (2.0 * math.pi),
        "c_accel_rad_s2": m.accel[:, 0],
    }


def x_accel_peak_at_step(
    path: DPath, spindle_rpm: float, step_rad: float, rho_um: np.ndarray | None = None
) -> float:
    """The peak X acceleration [m/s²] at the program's points of the planned curve
    (:func:`evaluate`) at constant spindle speed, formed over a C step h either side:
    ω²·|ρ(φ+h) − 2ρ(φ) + ρ(φ−h)|/h², the kinematics stage's scheme ([2] eq. 14) on the uniform
    step h, over the points whose φ ± h stay on the program (0 if none). At a traditional
    junction it reads the slope jump over h, ω²·Δ(dρ/dθ)/h; on smooth stretches the
    curvature, ω²·d²ρ/dθ². ``rho_um``: the curve at the points, ``radius_at(path, path.phi)[0]``,
    if already known (several steps). One compiled pass, no arrays: the scaling is monotone,
    so this is the largest of the per-point accelerations, to the last bit."""
    omega = spindle_rpm * 2.0 * math.pi / 60.0
    phi = np.ascontiguousarray(path.phi, dtype=np.float64)
    mid = radius_at(path, phi)[0] if rho_um is None else np.ascontiguousarray(rho_um, dtype=np.float64)
    d = _peak_second_difference(
        phi, mid, float(step_rad), path.bounds, path.cut_d, path.cut_centre, np.ascontiguousarray(path.coeffs)
    )
    return float(omega**2 * d / step_rad**2 * 1e-6)


class ZPlan(NamedTuple):
    """What :func:`planned_z` needs of a program's Z at its points, formed once: the Z
    [µm] of every point, of the cuts' points (C, points per cut) and their slopes along the
    cut [µm/µm]."""

    z_um: np.ndarray
    zc: np.ndarray
    slope: np.ndarray


def z_plan(path: DPath, z_um: np.ndarray) -> ZPlan:
    """The :class:`ZPlan` of Z ``z_um`` [µm] at the points of ``path``: the cuts' slopes by
    second-order differences (one-sided at the ends)."""
    z_um = np.ascontiguousarray(z_um, dtype=np.float64)
    n, p = path.n_cuts, path.points_per_cut
    zc = z_um[path.cut >= 0].reshape(n, p)
    du = path.cut_step_um
    slope = np.empty_like(zc)
    slope[:, 1:-1] = (zc[:, 2:] - zc[:, :-2]) / (2.0 * du)
    slope[:, 0] = (-3.0 * zc[:, 0] + 4.0 * zc[:, 1] - zc[:, 2]) / (2.0 * du) if p > 2 else zc[:, 1] - zc[:, 0]
    slope[:, -1] = (3.0 * zc[:, -1] - 4.0 * zc[:, -2] + zc[:, -3]) / (2.0 * du) if p > 2 else slope[:, 0]
    return ZPlan(z_um, zc, slope)


def planned_z(
    path: DPath,
    z_um: np.ndarray | ZPlan,
    phi: np.ndarray,
    on_cut: np.ndarray | None = None,
) -> np.ndarray:
    """Z [µm] of the planned path at accumulated angles ``phi`` [rad] given Z at its points
    ``z_um`` (or their :func:`z_plan`): on a cut the cubic Hermite curve through the cut's
    points in the distance u along it (slopes by second-order differences, so it is exact for
    Z quadratic in u and its second derivative converges to the surface's); across a
    transition linear in θ ([5] eq. 14), as the points there are. ``on_cut``:
    :func:`evaluate`'s flags of ``phi``, if known."""
    plan = z_um if isinstance(z_um, ZPlan) else z_plan(path, z_um)
    phi = np.ascontiguousarray(phi, dtype=np.float64)
    on_cut = radius_at(path, phi)[1] if on_cut is None else np.ascontiguousarray(on_cut, dtype=np.bool_)
    out = np.empty(phi.shape)
    _planned_z_kernel(
        phi.reshape(-1),
        on_cut.reshape(-1),
        np.ascontiguousarray(path.phi, dtype=np.float64),
        plan.z_um,
        plan.zc,
        plan.slope,
        path.bounds,
        path.cut_d,
        path.cut_centre,
        path.cut_step_um,
        0.5 * path.geometry.length_um,
        out.reshape(-1),
    )
    return out


@njit(nogil=True, cache=True)
def _planned_z_kernel(
    phi: np.ndarray,
    on_cut: np.ndarray,
    path_phi: np.ndarray,
    z_um: np.ndarray,
    zc: np.ndarray,
    slope: np.ndarray,
    bounds: np.ndarray,
    cut_d: np.ndarray,
    cut_centre: np.ndarray,
    du: float,
    half: float,
    out: np.ndarray,
) -> None:  # pragma: no cover - jit
    """:func:`planned_z` sample by sample: the point step and the segment of each angle found
    by a walk from the last one's (a search for the first and when the angles go back), then
    the line between the points (numpy's ``interp``: slope·(φ − φ_j) + z_j) or the cut's
    Hermite cubic."""
    last, nb, n, p = path_phi.size - 2, bounds.size, cut_d.size, zc.shape[1]
    j = -1
    seg = 0
    for k in range(phi.size):
        q = phi[k]
        if not on_cut[k]:
            if q <= path_phi[0]:
                out[k] = z_um[0]
                continue
            if q >= path_phi[-1]:
                out[k] = z_um[-1]
                continue
            if j < 0 or q < path_phi[j]:
                # the step a walk from the first point ends on (φ increases), without the walk
                j = min(max(np.searchsorted(path_phi, q, side="right") - 1, 0), last)
            while j < last and path_phi[j + 1] <= q:
                j += 1
            out[k] = (z_um[j + 1] - z_um[j]) / (path_phi[j + 1] - path_phi[j]) * (q - path_phi[j]) + z_um[j]
            continue
        if q < bounds[seg]:
            seg = max(np.searchsorted(bounds, q, side="right") - 1, 0)
        while seg + 1 < nb and bounds[seg + 1] <= q:
            seg += 1
        i = min(seg // 2, n - 1)
        u = cut_d[i] * math.tan(q - cut_centre[i]) + half
        m = min(max(np.int64(math.floor(u / du)), 0), p - 2)
        s = u / du - m
        h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
        h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
        out[k] = h00 * zc[i, m] + h10 * du * slope[i, m] + h01 * zc[i, m + 1] + h11 * du * slope[i, m + 1]


def line_at(t_points: np.ndarray, t: float) -> int:
    """The program line (0-based point) a sample at time ``t`` [s] follows, the points at
    times ``t_points`` [s]."""
    found = int(np.searchsorted(t_points, t, side="right")) - 1
    return min(max(found, 0), t_points.size - 1)


class Sampled(NamedTuple):
    """A D-path program's motion sampled on its planned path every controller period:
    times t [s], C φ [rad], X = ρ and Z [µm], whether each sample lies on a cut, and the
    times of the program's points [s] (:meth:`line`)."""

    t: np.ndarray
    phi: np.ndarray
    rho: np.ndarray
    z: np.ndarray
    on_cut: np.ndarray
    t_points: np.ndarray

    def line(self, i: int) -> int:
        """The program line (0-based point) sample ``i`` follows: found for the few samples a
        message names, not for millions of samples that no one reads."""
        return line_at(self.t_points, float(self.t[i]))

    def time(self, i: int) -> float:
        """Time of sample ``i`` [s]."""
        return float(self.t[i])


def period_grid(t_points: np.ndarray, period_s: float, until_s: float = math.inf) -> tuple[float, float, int]:
    """The uniform times at most ``period_s`` [s] apart over the program's points at times
    ``t_points`` [s] (up to ``until_s``): first and last time [s] and their number (≥ 3)."""
    if not (math.isfinite(period_s) and period_s > 0.0):
        raise ValueError(f"the controller period must be positive, got {period_s!r} s")
    end = min(float(t_points[-1]), until_s)
    n = int(math.ceil((end - float(t_points[0])) / period_s)) + 1
    return float(t_points[0]), end, max(n, 3)


def period_times(first: float, last: float, n: int, lo: int, hi: int) -> np.ndarray:
    """Times ``lo`` … ``hi`` − 1 [s] of ``np.linspace(first, last, n)``, the same values
    (its arithmetic: i·step + first, the last exactly ``last``), so a long grid can be taken
    a stretch at a time."""
    delta, div = last - first, n - 1
    step = delta / div
    i = np.arange(lo, hi, dtype=np.float64)
    # linspace's own branches: a step that underflows to zero scales the fractions instead
    t = (i / div * delta if step == 0.0 else i * step) + first
    if hi == n and hi > lo:
        t[-1] = last
    return t


def sample_path(path: DPath, z: ZPlan, t_points: np.ndarray, t: np.ndarray) -> Sampled:
    """The planned path (:func:`evaluate`, :func:`planned_z`) at times ``t`` [s] over the
    program's points at times ``t_points`` [s], C linear in time between points."""
    phi = np.interp(t, t_points, path.phi)
    rho, on_cut = radius_at(path, phi)
    return Sampled(t, phi, rho, planned_z(path, z, phi, on_cut), on_cut, np.asarray(t_points))


def at_period(
    path: DPath, z_um: np.ndarray, t_points: np.ndarray, period_s: float, until_s: float = math.inf
) -> Sampled:
    """The program's planned path (:func:`evaluate`, :func:`planned_z`) at uniform times at
    most ``period_s`` [s] apart over the program's points at times ``t_points`` [s] (up to
    ``until_s``, :func:`period_grid`), C taken linear in time between points (exact at
    constant spindle speed). Accelerations formed on these samples by the kinematics stage
    are those the machine's controller forms over its command period: a slope jump reads
    ω·Δ(dρ/dθ)/T, a smooth stretch ω²·d²ρ/dθ² (model §6)."""
    first, last, n = period_grid(t_points, period_s, until_s)
    return sample_path(path, z_plan(path, z_um), t_points, period_times(first, last, n, 0, n))


def placed(
    surface: Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray]], centre_um: float, rotation_rad: float
) -> Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The part ``surface`` (its own frame, centred) mounted with its centre at (centre, 0)
    on the chuck and turned by ``rotation_rad``: a surface callable in the spindle's frame,
    (X, Y) [µm] -> (f, ∂f/∂X, ∂f/∂Y)."""
    c, s = math.cos(rotation_rad), math.sin(rotation_rad)

    def at(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        dx = np.asarray(x) - centre_um
        y = np.asarray(y)
        f, fx, fy = surface(c * dx - s * y, s * dx + c * y)
        return f, c * fx + s * fy, -s * fx + c * fy

    return at


def to_part(
    x: np.ndarray, y: np.ndarray, centre_um: float, rotation_rad: float
) -> tuple[np.ndarray, np.ndarray]:
    """Spindle-frame (X, Y) [µm] to the part's own frame (see :func:`placed`)."""
    c, s = math.cos(rotation_rad), math.sin(rotation_rad)
    dx = x - centre_um
    return c * dx - s * y, s * dx + c * y


def zone_of(half_w: float, half_h: float, rotation_rad: float) -> tuple[float, float]:
    """(l, s) [µm]: the extent along and across the cuts of a part whose bounding box is
    2·half_w × 2·half_h, turned by ``rotation_rad`` on the chuck (cuts run along the
    spindle frame's Y in zone 0)."""
    c, s = abs(math.cos(rotation_rad)), abs(math.sin(rotation_rad))
    across = 2.0 * (half_w * c + half_h * s)
    along = 2.0 * (half_w * s + half_h * c)
    return along, across
