"""Spiral path programs: control points along the tool path, planned from error budgets
([4], model §1, §4).

A *spiral program* is what an integrated servo controller (a slow tool servo, or an FTS run
by the lathe's own controller) executes: control points on the Archimedean spiral
ρ(φ) = ρ0 − F·φ/2π (model §1), each with its compensated command w [µm] (the same exact
arc contact as a table's, §4), interpolated *linearly in the spindle angle φ* between
consecutive points. Tables and paths differ only in where the points are and how they are
interpolated; the envelope, metrics and dynamics are the engine's.

A point is identified by its accumulated spindle angle φ [rad] (0 at the outer edge ρ0,
Φ = 2π·ρ0/F at the centre). Three sampling strategies place the points:

* constant angle — Np points per revolution, φ_j = j·2π/Np;
* constant arc length — one point every ``arc_um`` along the spiral (in the XY plane),
  with at least ``min_points_per_rev`` per revolution so the centre stays sampled;
* chord budget ([4] eq. 4) — each next point as far along the path as the chord to it
  stays within Δcho of the compensated path. [4] approximates the path between points
  by a circle of radius R_j and steps by |P_j P_j+1| = 2·sqrt(2R_jΔ − Δ²); here the
  deviation of the chord (the controller's linear interpolation) from the compensated path
  is measured directly on a dense sampling of the path, so the budget holds where the
  circle approximation would not (inflections, curvature changing within a step).

The feed may come from a residual (scallop) budget, [4] eqs. 1–3, derived here for
the tool-centre spacing (see :func:`feed_for_cusp`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit

from ftsweep.stages.interpolation import segments
from ftsweep.stages.interpolation.spiral_program import (
    SpiralPath,
    path_length_um,
    spiral_end_rad,
)

RULES = ("angle", "arc", "chord")
# fewest points per revolution of the arc and chord rules: without a floor the arc rule's
# angular step would grow without bound towards the centre
MIN_POINTS_PER_REV = 16


def _check(name: str, value: float) -> None:
    if not (value > 0.0 and math.isfinite(value)):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")


def _close(phi: np.ndarray, end: float) -> np.ndarray:
    """Points up to and including the spiral's end Φ (the centre), no duplicates."""
    phi = phi[phi < end - 1e-12 * max(end, 1.0)]
    return np.append(phi, end)


def merged_short_end(phi: np.ndarray, min_step_rad: float) -> np.ndarray:
    """The points' angles [rad] with a last segment shorter than ``min_step_rad`` [rad] (a
    controller's servo period at the spindle's speed) merged into the one before it: the
    point before the centre is dropped, so the last block runs from the point before that
    to the centre and no block takes less than the controller can execute."""
    if phi.size > 2 and phi[-1] - phi[-2] < min_step_rad * (1.0 - 1e-9):
        return np.delete(phi, -2)
    return phi


def constant_angle(rho0_um: float, feed_um: float, points_per_rev: int) -> SpiralPath:
    """Points at a constant spindle-angle step 2π/Np from the outer edge to the centre."""
    _check("points_per_rev", points_per_rev)
    if int(points_per_rev) != points_per_rev or points_per_rev < 3:
        raise ValueError(f"points_per_rev must be an integer ≥ 3, got {points_per_rev!r}")
    end = spiral_end_rad(rho0_um, feed_um)
    n = int(points_per_rev)
    phi = np.arange(int(math.ceil(end * n / (2.0 * math.pi) - 1e-9)) + 1) * (2.0 * math.pi / n)
    return SpiralPath("spiral", _close(phi, end), rho0_um, feed_um, "angle", float(n))


@njit(nogil=True, cache=True, inline="always")
def _newton_step(r: float, t: float, b: float, rho0_um: float) -> tuple[Any, ...]:  # pragma: no cover - jit
    """One Newton step on the length from the centre, (b/2)·(u·sqrt(1+u²) + asinh u) with
    u = r/b, towards the length ``t``: (the new radius, the step)."""
    u = r / b
    length = 0.5 * b * (u * math.sqrt(1.0 + u * u) + math.asinh(u))
    step = (length - t) * b / math.sqrt(r * r + b * b)
    return min(max(r - step, 0.0), rho0_um), step


@njit(nogil=True, cache=True)
def _arc_angles(
    total: float, arc_um: float, b: float, rho0_um: float, iterations: int, tol: float, phi: np.ndarray
) -> None:  # pragma: no cover - jit
    """Angles φ = (ρ0 − ρ)/b [rad] where the spiral has run j·``arc_um`` [µm] from the edge
    (``total`` [µm] long), into ``phi[:n]`` (n = phi.size − 1; the last slot is left for the
    end): each ρ by Newton on the length from the centre until a step is below ``tol`` [µm]
    (the length is convex in ρ: after at most one overshoot it converges monotonically,
    quadratically), from the large-ρ expansion t = (b/2)·(u² + ½ + ln 2u), u = ρ/b, where it
    holds (u > 2), else from t = ρ²/(2b); two or three steps a point."""
    for j in range(phi.size - 1):
        t = max(total - j * arc_um, 0.0)
        u0 = math.sqrt(2.0 * t / b)
        u2 = 2.0 * t / b - 0.5 - math.log(2.0 * u0) if u0 > 2.0 else -1.0
        r = min(b * math.sqrt(u2) if u2 > 0.0 else b * u0, rho0_um)
        for _ in range(iterations):
            r, step = _newton_step(r, t, b, rho0_um)
            if abs(step) < tol:
                break
        phi[j] = (rho0_um - r) / b


@njit(nogil=True, cache=True)
def _close_and_cap(phi: np.ndarray, n: int, end: float, max_step: float) -> int:  # pragma: no cover - jit
    """The ascending angles ``phi[:n]`` [rad] with those within 1e-12 of the end Φ dropped,
    Φ appended and every gap wider than ``max_step`` split into equal steps, written in place
    into ``phi[:count]`` from the back (an angle only moves up the array, past the ones not
    yet read), which needs ``phi.size`` ≥ count. Returns the count; −1, with ``phi``
    untouched, when the angles do not ascend (rounding; the caller sorts) or ``phi`` is too
    short (the caller gives more room)."""
    limit = end - 1e-12 * max(end, 1.0)
    kept = n
    while kept > 0 and phi[kept - 1] >= limit:
        kept -= 1
    count = 1
    nxt = end
    for j in range(kept - 1, -1, -1):
        p = phi[j]
        if p > nxt:
            return -1
        if nxt - p > max_step:
            count += max(math.ceil((nxt - p) / max_step - 1e-9), 1) - 1
        count += 1
        nxt = p
    if count > phi.size:
        return -1
    pos = count - 1
    phi[pos] = end
    nxt = end
    for j in range(kept - 1, -1, -1):
        p = phi[j]
        if nxt - p > max_step:
            pieces = max(math.ceil((nxt - p) / max_step - 1e-9), 1)
            step = (nxt - p) / pieces
            for i in range(pieces - 1, 0, -1):
                pos -= 1
                phi[pos] = p + i * step
        pos -= 1
        phi[pos] = p
        nxt = p
    return count


def constant_arc(
    rho0_um: float, feed_um: float, arc_um: float, min_points_per_rev: int = MIN_POINTS_PER_REV
) -> SpiralPath:
    """Points every ``arc_um`` [µm] of path length (XY plane) from the outer edge, and at
    least ``min_points_per_rev`` per revolution."""
    _check("arc_um", arc_um)
    b = feed_um / (2.0 * math.pi)
    end = spiral_end_rad(rho0_um, feed_um)
    total = path_length_um(rho0_um, feed_um)
    n = int(math.ceil(total / arc_um - 1e-9)) + 1
    max_step = 2.0 * math.pi / min_points_per_rev
    # room for the steps the angular floor adds (at most Φ/max_step); pages never written
    # take no memory, and the angles are split in place, without a second array to fault in
    phi = np.empty(n + 2 + int(math.ceil(end / max_step)))
    _arc_angles(total, float(arc_um), b, float(rho0_um), 60, 1e-9 * max(rho0_um, 1.0), phi[: n + 1])
    count = _close_and_cap(phi, n, end, max_step)
    if count < 0:  # not ascending after rounding (never seen): sorted first
        phi[:n] = np.sort(phi[:n])
        count = _close_and_cap(phi, n, end, max_step)
    phi = phi[:count]
    return SpiralPath("spiral", phi, rho0_um, feed_um, "arc", float(arc_um))


@njit(nogil=True, cache=True)
def _segment_ok(
    phi: np.ndarray, w: np.ndarray, dw: np.ndarray, j: int, i: int, budget: float
) -> bool:  # pragma: no cover - jit
    # largest deviation of the dense samples strictly between j and i from the segment j–i:
    # the chord, or with slopes ``dw`` the cubic Hermite through the path's own slopes
    span = phi[i] - phi[j]
    if dw.size == 0:
        slope = (w[i] - w[j]) / span
        for m in range(j + 1, i):
            if abs(w[j] + slope * (phi[m] - phi[j]) - w[m]) > budget:
                return False
        return True
    d0, d1 = dw[j] * span, dw[i] * span
    for m in range(j + 1, i):
        if abs(segments.hermite(w[j], w[i], d0, d1, (phi[m] - phi[j]) / span) - w[m]) > budget:
            return False
    return True


@njit(nogil=True, cache=True)
def _greedy_chords(
    phi: np.ndarray, w: np.ndarray, dw: np.ndarray, budget: float, max_step: float, keep: np.ndarray
) -> None:  # pragma: no cover - jit
    """Mark in ``keep`` the dense samples a greedy chord walk keeps: from each kept sample,
    the farthest sample (by galloping, then bisection) whose chord stays within ``budget``
    of every dense sample in between and spans at most ``max_step`` rad. Every accepted
    chord was checked, so the budget holds on the dense samples whatever the search visits."""
    n = phi.size
    j = 0
    keep[0] = True
    while j < n - 1:
        good = j + 1
        width = 1
        bad = -1
        while True:
            cand = j + 2 * width
            if cand >= n:
                cand = n - 1
            if cand <= good:
                break
            if phi[cand] - phi[j] <= max_step and _segment_ok(phi, w, dw, j, cand, budget):
                good = cand
                width *= 2
                if cand == n - 1:
                    break
            else:
                bad = cand
                break
        if bad > 0:
            lo, hi = good, bad
            while hi - lo > 1:
                mid = (lo + hi) // 2
                if phi[mid] - phi[j] <= max_step and _segment_ok(phi, w, dw, j, mid, budget):
                    lo = mid
                else:
                    hi = mid
            good = lo
        keep[good] = True
        j = good


@njit(nogil=True, cache=True)
def _chord_errors(
    phi: np.ndarray, w: np.ndarray, keep_idx: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover - jit
    for s in range(keep_idx.size - 1):
        j, i = keep_idx[s], keep_idx[s + 1]
        slope = (w[i] - w[j]) / (phi[i] - phi[j])
        worst = 0.0
        for m in range(j + 1, i):
            worst = max(worst, abs(w[j] + slope * (phi[m] - phi[j]) - w[m]))
        out[s] = worst


@njit(nogil=True, cache=True, inline="always")
def _cubic(phi: np.ndarray, w: np.ndarray, a: int, x: float) -> float:  # pragma: no cover - jit
    """The cubic through (phi[a + k], w[a + k]), k = 0..3, at ``x`` (Lagrange form)."""
    x0, x1, x2, x3 = phi[a], phi[a + 1], phi[a + 2], phi[a + 3]
    return (
        w[a] * (x - x1) * (x - x2) * (x - x3) / ((x0 - x1) * (x0 - x2) * (x0 - x3))
        + w[a + 1] * (x - x0) * (x - x2) * (x - x3) / ((x1 - x0) * (x1 - x2) * (x1 - x3))
        + w[a + 2] * (x - x0) * (x - x1) * (x - x3) / ((x2 - x0) * (x2 - x1) * (x2 - x3))
        + w[a + 3] * (x - x0) * (x - x1) * (x - x2) / ((x3 - x0) * (x3 - x1) * (x3 - x2))
    )


@njit(nogil=True, cache=True)
def _interval_smooth(phi: np.ndarray, w: np.ndarray, i: int, tol: float) -> bool:  # pragma: no cover - jit
    """Whether the centred cubic through samples i − 1 … i + 2 reproduces the path within
    ``tol`` [µm] on [φ_i, φ_i+1]: at the interval's middle it must agree within ``tol`` with
    the cubics shifted one sample either way. For a smooth path (uniform step h, fourth
    derivative w⁽⁴⁾) those differences are 0.0625·h⁴·|w⁽⁴⁾| there, the centred cubic's own
    largest error on the interval 0.0234·h⁴·|w⁽⁴⁾| (the Lagrange remainder): a pass bounds
    that error by tol/2.7. A kink or a jump within the stencils fails."""
    if i < 2 or i + 3 >= phi.size:
        return False
    mid = 0.5 * (phi[i] + phi[i + 1])
    centred = _cubic(phi, w, i - 1, mid)
    worst = max(abs(_cubic(phi, w, i - 2, mid) - centred), abs(_cubic(phi, w, i, mid) - centred))
    return worst <= tol  # NaN fails


@njit(nogil=True, cache=True)
def _smooth_intervals(
    phi: np.ndarray, w: np.ndarray, tol: float, out: np.ndarray
) -> int:  # pragma: no cover - jit
    """:func:`_interval_smooth` of every interval of (phi, w) into ``out``; returns how many
    are not."""
    rough = 0
    for i in range(out.size):
        out[i] = _interval_smooth(phi, w, i, tol)
        rough += not out[i]
    return rough


@njit(nogil=True, cache=True)
def _subdivide(
    phi_c: np.ndarray,
    w_c: np.ndarray,
    smooth: np.ndarray,
    m: int,
    phi: np.ndarray,
    w: np.ndarray,
    exact: np.ndarray,
) -> None:  # pragma: no cover - jit
    """Every interval of the coarse samples (phi_c, w_c) split into ``m`` equal steps in φ,
    into ``phi`` ((n − 1)·m + 1): the coarse samples keep their values, the others take the
    centred cubic where the interval is ``smooth``; the indices of the rest go into
    ``exact`` (sized for them) for the caller to compute."""
    e = 0
    for i in range(phi_c.size - 1):
        step = (phi_c[i + 1] - phi_c[i]) / m
        base = i * m
        phi[base] = phi_c[i]
        w[base] = w_c[i]
        if smooth[i]:
            # the cubic's Lagrange weights w_a/Π(x_a − x_b), once an interval (no division
            # per sample)
            x0, x1, x2, x3 = phi_c[i - 1], phi_c[i], phi_c[i + 1], phi_c[i + 2]
            c0 = w_c[i - 1] / ((x0 - x1) * (x0 - x2) * (x0 - x3))
            c1 = w_c[i] / ((x1 - x0) * (x1 - x2) * (x1 - x3))
            c2 = w_c[i + 1] / ((x2 - x0) * (x2 - x1) * (x2 - x3))
            c3 = w_c[i + 2] / ((x3 - x0) * (x3 - x1) * (x3 - x2))
        for k in range(1, m):
            x = phi_c[i] + k * step
            phi[base + k] = x
            if smooth[i]:
                d0, d1, d2, d3 = x - x0, x - x1, x - x2, x - x3
                w[base + k] = c0 * d1 * d2 * d3 + c1 * d0 * d2 * d3 + c2 * d0 * d1 * d3 + c3 * d0 * d1 * d2
            else:
                exact[e] = base + k
                e += 1
    last = phi_c.size - 1
    phi[last * m] = phi_c[last]
    w[last * m] = w_c[last]


def subdivided(
    coarse: tuple[np.ndarray, np.ndarray],
    m: int,
    commands: Callable[[np.ndarray], np.ndarray],
    tol_um: float,
) -> tuple[np.ndarray, np.ndarray, int]:
    """The ``coarse`` samples (φ [rad], exactly compensated w [µm], model §4) with every
    interval split into ``m`` equal steps in φ: the new samples take the centred cubic
    through the coarse ones where it is proven within ``tol_um`` [µm]
    (:func:`_interval_smooth`), ``commands(φ)`` elsewhere. Returns φ, w and how many samples
    were computed exactly."""
    phi_c, w_c = coarse
    smooth = np.empty(phi_c.size - 1, dtype=np.bool_)
    rough = _smooth_intervals(phi_c, w_c, float(tol_um), smooth)
    size = (phi_c.size - 1) * m + 1
    phi, w = np.empty(size), np.empty(size)
    exact = np.empty(rough * (m - 1), dtype=np.int64)
    _subdivide(phi_c, w_c, smooth, int(m), phi, w, exact)
    if exact.size:
        w[exact] = np.asarray(commands(phi[exact]), dtype=np.float64)
    return phi, w, int(exact.size)


# dense samples the chord rule wants in every kept segment: with d dense intervals per segment the
# chord's deviation between dense samples exceeds the largest sampled one by about Δ/d² of
# the budget on a segment of uniform curvature, which the rule's margin (DENSE_MARGIN) covers
DENSE_PER_SEGMENT = 8
# dense samples of the chord rule: ~80 bytes each with the compensation's temporaries (2.4 GB)
MAX_DENSE_SAMPLES = 30_000_000
DENSE_MARGIN = 1.0 / 16.0
# refined dense samples are interpolated from the first sampling where the interpolation is
# proven within this fraction of the chord budget (:func:`_interval_smooth`), else compensated
INTERP_TOL = 1e-3


def _check_samples(needed: float, max_samples: int, chord_um: float, step_um: float) -> None:
    """Refuse a dense sampling of ``needed`` points at ``step_um`` [µm] over ``max_samples``."""
    if needed > max_samples:
        raise ValueError(
            f"the chord budget {chord_um:g} µm needs a dense sampling of about {needed:.3g} points "
            f"(at {step_um:.3g} µm), more than {max_samples:,}: use a larger chord budget"
        )


def chord_budget(
    rho0_um: float,
    feed_um: float,
    chord_um: float,
    commands: Callable[[np.ndarray], np.ndarray],
    dense_um: float | None = None,
    min_points_per_rev: int = MIN_POINTS_PER_REV,
    max_refine: int = 5,
    max_samples: int = MAX_DENSE_SAMPLES,
    cubic: bool = False,
) -> tuple[SpiralPath, np.ndarray, np.ndarray]:
    """Points placed by the chord-error budget Δcho = ``chord_um`` [µm] ([4] eq. 4).

    ``commands(phi)`` gives the compensated command w [µm] at accumulated spindle angles φ
    [rad] (model §4). The path is sampled densely at constant arc length (``dense_um``,
    default the feed), the greedy walk of :func:`_greedy_chords` keeps the farthest next
    point whose chord stays within (1 − 1/16)·Δcho of every dense sample in between, and
    the dense sampling is refined (up to ``max_refine`` times) until every kept segment
    spans at least 8 dense intervals (refined samples: :func:`subdivided`). Returns the path,
    the commands at its points as sampled [µm] (within 1e-3·Δcho of ``commands``) and the
    largest sampled deviation of each segment [µm]; refuses (ValueError) a dense sampling of
    more than ``max_samples`` points before allocating it. With ``cubic`` (PVT, SPLINE1:
    docs/controllers.md) the segments are cubic: :func:`_kept_errors`.
    """
    _check("chord_um", chord_um)
    step = dense_um if dense_um is not None else feed_um
    _check("dense_um", step)
    budget = chord_um * (1.0 - DENSE_MARGIN)
    max_step = 2.0 * math.pi / min_points_per_rev
    # the dense angular floor leaves the rule's widest steps their DENSE_PER_SEGMENT samples
    floor = DENSE_PER_SEGMENT * min_points_per_rev
    revolutions = spiral_end_rad(rho0_um, feed_um) / (2.0 * math.pi)
    first = path_length_um(rho0_um, feed_um) / step + floor * revolutions
    coarse: tuple[np.ndarray, np.ndarray] | None = None
    m = 1
    for attempt in range(max_refine + 1):
        _check_samples(first * m, max_samples, chord_um, step / m)
        if coarse is None:
            dense = constant_arc(rho0_um, feed_um, step, floor).phi
            w = np.ascontiguousarray(commands(dense), dtype=np.float64)
            coarse = (dense, w)
        else:
            dense, w, _ = subdivided(coarse, m, commands, INTERP_TOL * chord_um)
        keep = np.zeros(dense.size, dtype=np.bool_)
        _greedy_chords(dense, w, _slopes(dense, w, cubic), budget, max_step, keep)
        idx = np.flatnonzero(keep)
        # the last segment ends at the centre wherever it falls: it sets no spacing
        per_segment = float(np.min(np.diff(idx)[:-1])) if idx.size > 2 else math.inf
        if per_segment >= DENSE_PER_SEGMENT or attempt == max_refine:
            break
        # segments scale little with the dense step, so one refinement usually suffices
        m = int(math.ceil(m * DENSE_PER_SEGMENT / (0.9 * per_segment)))
    idx, errors = _kept_errors(dense, w, idx, chord_um, cubic)
    path = SpiralPath("spiral", dense[idx], rho0_um, feed_um, "chord", float(chord_um))
    return path, w[idx], errors


def _slopes(dense: np.ndarray, w: np.ndarray, cubic: bool) -> np.ndarray:
    """The path's own slopes at the dense samples for the cubic rule (empty: the chord's)."""
    dw = np.empty(dense.size if cubic else 0)
    if cubic:
        segments.dense_slopes(dense, w, dw)
    return dw


def _kept_errors(
    dense: np.ndarray, w: np.ndarray, idx: np.ndarray, chord_um: float, cubic: bool
) -> tuple[np.ndarray, np.ndarray]:
    """The kept samples and each segment's largest deviation [µm] from the dense samples:
    the chord's, or (``cubic``) the natural spline's through the kept samples after every
    segment over Δcho is split (:func:`ftsweep.stages.interpolation.segments.split_until_within`); the
    greedy walk checked the cubic Hermite through the path's own slopes."""
    if cubic:
        return segments.split_until_within(dense, w, idx, chord_um)
    errors = np.empty(idx.size - 1)
    _chord_errors(dense, w, idx, errors)
    return idx, errors
