"""How a controller forms the commanded path between a program's points (docs/controllers.md):
linear segments, cubic Hermite segments through end positions and velocities (Delta Tau
PMAC PVT) and the uniform cubic B-spline (PMAC SPLINE1).

Every mode is held in one form: per segment k (from point k to k + 1) its end values
y_k, y_k+1 and its end tangents d0_k, d1_k in value units per segment (the derivative
times the segment's span), so that at the segment's parameter u ∈ [0, 1]

    y(u) = h00(u)·y_k + h10(u)·d0_k + h01(u)·y_k+1 + h11(u)·d1_k          (Hermite basis)

with h00 = 2u³ − 3u² + 1, h10 = u³ − 2u² + u, h01 = −2u³ + 3u², h11 = u³ − u².
Linear segments have d0 = d1 = y_k+1 − y_k; a PVT segment of time T has d0 = V_k·T and
d1 = V_k+1·T; a uniform cubic B-spline over control points P has the way-points
y_k = (P_k−1 + 4P_k + P_k+1)/6 and tangents d0_k = (P_k+1 − P_k−1)/2,
d1_k = (P_k+2 − P_k)/2, which is the same cubic as its basis-function form.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(nogil=True, cache=True, inline="always")
def hermite(y0: float, y1: float, d0: float, d1: float, u: float) -> float:  # pragma: no cover - jit
    """The cubic Hermite segment at parameter ``u`` ∈ [0, 1] (module docstring), in the
    nested form the C reference interpolator (controller/segments.h) evaluates, operation
    for operation, so both give the same double."""
    a = 2.0 * (y0 - y1) + d0 + d1
    b = 3.0 * (y1 - y0) - 2.0 * d0 - d1
    return ((a * u + b) * u + d0) * u + y0


@njit(nogil=True, cache=True)
def _natural_moments(x: np.ndarray, y: np.ndarray, m: np.ndarray) -> None:  # pragma: no cover - jit
    """Second derivatives ``m`` of the natural cubic spline through (x, y) (m = 0 at both
    ends), by the Thomas algorithm on its tridiagonal system (x strictly ascending)."""
    n = x.size
    m[0] = 0.0
    m[n - 1] = 0.0
    if n < 3:
        return
    c = np.empty(n)
    r = np.empty(n)
    c[0] = 0.0
    r[0] = 0.0
    for i in range(1, n - 1):
        h0 = x[i] - x[i - 1]
        h1 = x[i + 1] - x[i]
        rhs = 6.0 * ((y[i + 1] - y[i]) / h1 - (y[i] - y[i - 1]) / h0)
        diag = 2.0 * (h0 + h1) - h0 * c[i - 1]
        c[i] = h1 / diag
        r[i] = (rhs - h0 * r[i - 1]) / diag
    for i in range(n - 2, 0, -1):
        m[i] = r[i] - c[i] * m[i + 1]


@njit(nogil=True, cache=True)
def _tangents_of_moments(
    x: np.ndarray, y: np.ndarray, m: np.ndarray, d0: np.ndarray, d1: np.ndarray
) -> None:  # pragma: no cover - jit
    for k in range(x.size - 1):
        h = x[k + 1] - x[k]
        dy = y[k + 1] - y[k]
        d0[k] = dy - h * h * (2.0 * m[k] + m[k + 1]) / 6.0
        d1[k] = dy + h * h * (m[k] + 2.0 * m[k + 1]) / 6.0


def natural_spline(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Segment tangents (d0, d1) [y units per segment] of the natural cubic spline through
    (x, y), x strictly ascending: the C² interpolant with zero second derivative at both ends
    that both PVT velocities and SPLINE1 control points are derived from (docs/controllers.md).
    Its interpolation error on a smooth path is about h⁴·|y⁽⁴⁾|/384 per segment."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    y = np.ascontiguousarray(y, dtype=np.float64)
    if x.size < 2:
        return np.empty(0), np.empty(0)
    m = np.empty(x.size)
    _natural_moments(x, y, m)
    d0, d1 = np.empty(x.size - 1), np.empty(x.size - 1)
    _tangents_of_moments(x, y, m, d0, d1)
    return d0, d1


def pvt_tangents(velocity: np.ndarray, seconds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tangents of PVT segments: end velocities ``velocity`` [units/s] at the N points and
    segment times ``seconds`` (N − 1) [s]: d0_k = V_k·T_k, d1_k = V_k+1·T_k."""
    v = np.asarray(velocity, dtype=np.float64)
    t = np.asarray(seconds, dtype=np.float64)
    return v[:-1] * t, v[1:] * t


def control_points(y: np.ndarray) -> np.ndarray:
    """The control points P of the uniform cubic B-spline whose way-points are ``y`` with the
    end rule of :func:`bspline_segments` (P_−1 = 2P_0 − P_1): P_k = y_k − M_k/6 with M the
    natural spline's second differences per unit step, so P_0 = y_0 and P_N−1 = y_N−1."""
    y = np.ascontiguousarray(y, dtype=np.float64)
    m = np.empty(y.size)
    _natural_moments(np.arange(y.size, dtype=np.float64), y, m)
    return y - m / 6.0


@njit(nogil=True, cache=True)
def _bspline_kernel(
    p: np.ndarray, y: np.ndarray, d0: np.ndarray, d1: np.ndarray
) -> None:  # pragma: no cover - jit
    n = p.size
    for k in range(n):
        prev = p[k - 1] if k > 0 else 2.0 * p[0] - p[1]
        nxt = p[k + 1] if k < n - 1 else 2.0 * p[n - 1] - p[n - 2]
        y[k] = (prev + 4.0 * p[k] + nxt) / 6.0
    for k in range(n - 1):
        prev = p[k - 1] if k > 0 else 2.0 * p[0] - p[1]
        after = p[k + 2] if k < n - 2 else 2.0 * p[n - 1] - p[n - 2]
        d0[k] = (p[k + 1] - prev) / 2.0
        d1[k] = (after - p[k]) / 2.0


def bspline_segments(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Way-points y and segment tangents (d0, d1) of the uniform cubic B-spline over control
    points ``p`` (N ≥ 2), one segment between consecutive way-points, the ends continued by
    the phantom points P_−1 = 2P_0 − P_1 and P_N = 2P_N−1 − P_N−2 (zero curvature there:
    the natural end, so y_0 = P_0 and y_N−1 = P_N−1)."""
    p = np.ascontiguousarray(p, dtype=np.float64)
    if p.size < 2:
        raise ValueError("a B-spline program needs at least 2 control points")
    y, d0, d1 = np.empty(p.size), np.empty(p.size - 1), np.empty(p.size - 1)
    _bspline_kernel(p, y, d0, d1)
    return y, d0, d1


def added_pieces_segments(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Way-points y and segment tangents (d0, d1) of a SPLINE1 sequence as the controller
    runs it from rest to rest: the uniform cubic B-spline over control points ``p`` (N ≥ 2,
    the first the position the sequence starts from) with the manual's *added pieces* — a
    zero-distance segment of the same time at each end (control points P_0 and P_N−1 taken
    three times), so the path accelerates from and decelerates to a stop (Turbo PMAC User
    Manual, "Added Pieces"). N + 2 way-points, N + 1 segments: the first leaves y = P_0 at
    rest, the last arrives at P_N−1 at rest."""
    p = np.ascontiguousarray(p, dtype=np.float64)
    if p.size < 2:
        raise ValueError("a B-spline program needs at least 2 control points")
    q = np.concatenate([p[:1], p[:1], p, p[-1:], p[-1:]])
    y = (q[:-2] + 4.0 * q[1:-1] + q[2:]) / 6.0
    y[0], y[-1] = p[0], p[-1]  # (P + 4P + P)/6 is P: exactly, not to rounding
    slope = (q[2:] - q[:-2]) / 2.0
    return y, slope[:-1], slope[1:]


@njit(nogil=True, cache=True)
def _evaluate_kernel(
    x: np.ndarray, y: np.ndarray, d0: np.ndarray, d1: np.ndarray, q: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover - jit
    n = x.size
    for i in range(q.size):
        v = q[i]
        if v <= x[0]:
            out[i] = y[0]
            continue
        if v >= x[n - 1]:
            out[i] = y[n - 1]
            continue
        lo, hi = 0, n - 1
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if x[mid] <= v:
                lo = mid
            else:
                hi = mid
        u = (v - x[lo]) / (x[lo + 1] - x[lo])
        out[i] = hermite(y[lo], y[lo + 1], d0[lo], d1[lo], u)


def evaluate(x: np.ndarray, y: np.ndarray, d0: np.ndarray, d1: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The segments (x ascending, values y, tangents d0, d1) at ``q`` (ends held outside)."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    out = np.empty(q.shape)
    _evaluate_kernel(
        np.ascontiguousarray(x, dtype=np.float64),
        np.ascontiguousarray(y, dtype=np.float64),
        np.ascontiguousarray(d0, dtype=np.float64),
        np.ascontiguousarray(d1, dtype=np.float64),
        q.ravel(),
        out.reshape(-1),
    )
    return out


@njit(nogil=True, cache=True)
def _deviations(
    x: np.ndarray, y: np.ndarray, keep: np.ndarray, d0: np.ndarray, d1: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover - jit
    for s in range(keep.size - 1):
        j, i = keep[s], keep[s + 1]
        worst = 0.0
        for m in range(j + 1, i):
            u = (x[m] - x[j]) / (x[i] - x[j])
            worst = max(worst, abs(hermite(y[j], y[i], d0[s], d1[s], u) - y[m]))
        out[s] = worst


def deviations(x: np.ndarray, y: np.ndarray, keep: np.ndarray, d0: np.ndarray, d1: np.ndarray) -> np.ndarray:
    """Largest deviation of each segment between the kept samples ``keep`` (indices into the
    dense samples x, y) from the dense samples it spans, the segments given by tangents
    d0, d1 (one per kept segment)."""
    out = np.empty(max(keep.size - 1, 0))
    _deviations(x, y, np.asarray(keep, dtype=np.int64), d0, d1, out)
    return out


@njit(nogil=True, cache=True)
def dense_slopes(x: np.ndarray, y: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - jit
    """dy/dx at every sample by the three-point formula of unequal steps (one-sided at the
    ends): the path's own slope, which a PVT program's velocities approximate."""
    n = x.size
    if n < 2:
        out[:] = 0.0
        return
    for i in range(1, n - 1):
        h0 = x[i] - x[i - 1]
        h1 = x[i + 1] - x[i]
        out[i] = (h0 * h0 * (y[i + 1] - y[i]) + h1 * h1 * (y[i] - y[i - 1])) / (h0 * h1 * (h0 + h1))
    out[0] = (y[1] - y[0]) / (x[1] - x[0])
    out[n - 1] = (y[n - 1] - y[n - 2]) / (x[n - 1] - x[n - 2])


# splits of the cubic chord rule's over-budget segments: each halves a segment, and the
# greedy walk's segments already hold the budget with the path's own slopes
MAX_SPLITS = 12


def split_until_within(
    dense: np.ndarray, w: np.ndarray, idx: np.ndarray, chord_um: float
) -> tuple[np.ndarray, np.ndarray]:
    """The kept samples ``idx`` with every segment of the natural spline through them whose
    deviation from the dense samples passes ``chord_um`` split at its middle sample, until
    none does (or a segment can no longer be split); the final segments' deviations [µm]."""
    for _ in range(MAX_SPLITS):
        d0, d1 = natural_spline(dense[idx], w[idx])
        errors = deviations(dense, w, idx, d0, d1)
        over = np.flatnonzero((errors > chord_um) & (np.diff(idx) > 1))
        if over.size == 0:
            break
        idx = np.union1d(idx, (idx[over] + idx[over + 1]) // 2)
    return idx, errors


def quantised(x: np.ndarray, quantum: float) -> np.ndarray:
    """``x`` rounded to whole multiples of ``quantum`` (a controller's time step as an
    angle), refused (ValueError) if two points then fall on one step."""
    n = np.rint(np.asarray(x, dtype=np.float64) / quantum)
    if np.any(np.diff(n) <= 0.0):
        raise ValueError(
            f"two points fall within one controller time step ({quantum:.3g}): fewer points or a "
            "slower spindle"
        )
    return n * quantum


def whole_steps(seconds: float, quantum_s: float) -> bool:
    """Whether ``seconds`` is a whole number of ``quantum_s`` (to 1e-9 of a step)."""
    steps = seconds / quantum_s
    return math.isfinite(steps) and abs(steps - round(steps)) <= 1e-9 * max(1.0, abs(steps))
