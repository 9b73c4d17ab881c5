"""Timed programs whose axes a controller joins by cubics in time (PMAC PVT,
docs/controllers.md): their segments' tangents, the velocities a PVT file writes, and where
the commanded path crosses the rays of the simulation (model §5).

A timed program is N points of K channels (C [rad] first, then X, optionally Y, and Z
[µm] last) at times t [s]. Between points k and k + 1 each channel is the cubic Hermite
segment of :mod:`ftsweep.stages.interpolation.segments` in u = (t − t_k)/T_k, its tangents the natural
cubic spline's in time (what a PVT program writes as velocities), or those read back from a
file's velocities. Where linear programs are taken as linear in the workpiece's polar angle
between points (exact for C and X linear in time on a lathe), a cubic program is followed
exactly: the crossing of the ray at angle q is the root u of angle(u) = q on its segment,
found by the Illinois method inside the bracket the points give.

Frames: ``SPINDLE`` (a D path, [5]): the polar angle is C, the radius X. ``TURNED`` (a
Fresnel program on an X-Y-Z-C lathe, [2] eq. 9): the workpiece point is R(C)·(X, Y) and the
angle and radius are taken about ``apex`` with ``sign`` (+1 counter-clockwise).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ftsweep.stages.interpolation.rays import ray_grid
from ftsweep.stages.interpolation.segments import hermite, quantised

SPINDLE = 0
TURNED = 1
# the Illinois iteration stops when the angle is this close, relative to its size [rad]: a few
# rounding steps of a double, ~1e-9 µm of position at a radius of 10 mm
ANGLE_TOLERANCE = 1e-14
MAX_ITERATIONS = 100


# points of the local polynomial a velocity is the slope of (a quartic: its slope is off by
# O(h⁴), and the Hermite segments through such slopes by O(h⁵) beside their own h⁴ term)
WINDOW = 5


@njit(nogil=True, cache=True)
def _local_slopes(
    t: np.ndarray, y: np.ndarray, a: int, b: int, out: np.ndarray
) -> None:  # pragma: no cover - jit
    """dy/dt at points a … b (inclusive) from the polynomial through the WINDOW points of the
    piece [a, b] nearest each (one-sided at the piece's ends): Lagrange's derivative, on the
    differences y_k − y_i (the weights sum to zero), so a large C angle loses no digits."""
    m = min(WINDOW, b - a + 1)
    for i in range(a, b + 1):
        lo = min(max(i - m // 2, a), b - m + 1)
        slope = 0.0
        for k in range(lo, lo + m):
            if k == i:
                continue
            num, den = 1.0, t[k] - t[i]
            for j in range(lo, lo + m):
                if j != k and j != i:
                    num *= t[i] - t[j]
                    den *= t[k] - t[j]
            slope += (y[k] - y[i]) * num / den
        out[i] = slope


def slopes(
    t: np.ndarray, y: np.ndarray, breaks: np.ndarray | None = None, left: np.ndarray | None = None
) -> np.ndarray:
    """dy/dt [y units/s] at every point: the slope of the quartic through the five nearest
    points of its piece. Pieces end at ``breaks``, points where the path's slope jumps (a D
    path's cut meeting its transition); a break takes its ``left`` piece's slope where
    ``left`` is True, else its right piece's (a PVT point carries one velocity: the piece
    that cuts keeps its own, the other is rounded within its one segment). Local, so a change
    of curvature moves its neighbours' velocities only (a natural spline rings along the path)."""
    t = np.ascontiguousarray(t, dtype=np.float64)
    y = np.ascontiguousarray(y, dtype=np.float64)
    n = t.size
    at = np.asarray([] if breaks is None else breaks, dtype=np.int64)
    keep_left = np.zeros(at.size, dtype=bool) if left is None else np.asarray(left, dtype=bool)
    ends = np.concatenate([[0], at, [n - 1]])
    if np.any(np.diff(ends) <= 0):
        raise ValueError("breaks must lie strictly inside the path, ascending")
    out = np.empty(n)
    for p in range(ends.size - 1):
        kept = out[ends[p]]  # the previous piece's slope at the shared point
        _local_slopes(t, y, int(ends[p]), int(ends[p + 1]), out)
        if p > 0 and keep_left[p - 1]:
            out[ends[p]] = kept
    return out


def tangents(
    t: np.ndarray, channels: np.ndarray, breaks: np.ndarray | None = None, left: np.ndarray | None = None
) -> np.ndarray:
    """(N − 1, 2K) tangents [channel units per segment] of the PVT segments through the K
    columns of ``channels`` (N, K) at times ``t`` [s], each point's velocity its local slope
    (:func:`slopes`, with its ``breaks`` and ``left``): columns 2k, 2k+1 the d0, d1 of channel k."""
    t = np.asarray(t, dtype=np.float64)
    channels = np.asarray(channels, dtype=np.float64)
    velocity = np.column_stack([slopes(t, channels[:, k], breaks, left) for k in range(channels.shape[1])])
    return from_velocities(velocity, np.diff(t))


def on_time_steps(t: np.ndarray, quantum_s: float, longest_s: float) -> np.ndarray:
    """The points' times ``t`` [s] rounded to a controller's whole time steps ``quantum_s``
    [s] (a PVT segment's time is a whole number of them); refused (ValueError) two points
    within one step or a segment longer than ``longest_s`` [s]."""
    q = quantised(np.asarray(t, dtype=np.float64), quantum_s)
    longest = float(np.diff(q).max(initial=0.0))
    if longest > longest_s:
        raise ValueError(
            f"a segment takes {longest * 1e3:.6g} ms, longer than the controller's {longest_s * 1e3:g} ms"
        )
    return q


def velocities(tan: np.ndarray, seconds: np.ndarray) -> np.ndarray:
    """(N, K) velocities [units/s] at the points of segments with tangents ``tan`` (N − 1, 2K)
    and times ``seconds`` (N − 1): d0_k/T_k, the last point d1/T of the last segment (one
    velocity a point, so d1_k/T_k = d0_k+1/T_k+1 up to rounding)."""
    seconds = np.asarray(seconds, dtype=np.float64)
    d0, d1 = tan[:, 0::2], tan[:, 1::2]
    return np.vstack([d0 / seconds[:, None], d1[-1:] / seconds[-1]])


def from_velocities(velocity: np.ndarray, seconds: np.ndarray) -> np.ndarray:
    """(N − 1, 2K) tangents of PVT segments of times ``seconds`` (N − 1) [s] between points of
    velocities ``velocity`` (N, K) [units/s]: d0_k = V_k·T_k, d1_k = V_k+1·T_k."""
    v = np.asarray(velocity, dtype=np.float64)
    s = np.asarray(seconds, dtype=np.float64)[:, None]
    out = np.empty((s.size, 2 * v.shape[1]))
    out[:, 0::2] = v[:-1] * s
    out[:, 1::2] = v[1:] * s
    return out


@njit(nogil=True, cache=True, inline="always")
def _channel(chan: np.ndarray, tan: np.ndarray, j: int, k: int, u: float) -> float:  # pragma: no cover - jit
    return hermite(chan[j, k], chan[j + 1, k], tan[j, 2 * k], tan[j, 2 * k + 1], u)


@njit(nogil=True, cache=True)
def _polar(
    chan: np.ndarray, tan: np.ndarray, j: int, u: float, frame: int, apex: np.ndarray, sign: float, ref: float
) -> tuple[float, float]:  # pragma: no cover - jit
    """Polar angle [rad] (unwrapped nearest ``ref``) and radius [µm] of segment j at u."""
    c = _channel(chan, tan, j, 0, u)
    x = _channel(chan, tan, j, 1, u)
    if frame == SPINDLE:
        return c, x
    y = _channel(chan, tan, j, 2, u)
    cs, sn = math.cos(c), math.sin(c)
    px = cs * x + sn * y - apex[0]
    py = -sn * x + cs * y - apex[1]
    raw = sign * math.atan2(py, px)
    turn = 2.0 * math.pi
    return ref + ((raw - ref + math.pi) % turn) - math.pi, math.hypot(px, py)


@njit(nogil=True, cache=True)
def _root(
    angle: np.ndarray,
    chan: np.ndarray,
    tan: np.ndarray,
    j: int,
    q: float,
    frame: int,
    apex: np.ndarray,
    sign: float,
) -> float:  # pragma: no cover - jit
    """u ∈ [0, 1] where segment j's angle is q (Illinois method in the points' bracket)."""
    a, b = 0.0, 1.0
    fa, fb = angle[j] - q, angle[j + 1] - q
    if fa >= 0.0:
        return 0.0
    if fb <= 0.0:
        return 1.0
    tol = ANGLE_TOLERANCE * max(1.0, abs(q))
    u, side = 0.5, 0
    for _ in range(MAX_ITERATIONS):
        u = (a * fb - b * fa) / (fb - fa)
        f = _polar(chan, tan, j, u, frame, apex, sign, angle[j])[0] - q
        if abs(f) <= tol or b - a <= 1e-16:
            break
        if f * fb > 0.0:
            b, fb = u, f
            if side == -1:
                fa *= 0.5
            side = -1
        else:
            a, fa = u, f
            if side == 1:
                fb *= 0.5
            side = 1
    return u


@njit(nogil=True, cache=True)
def _cubic(
    angle: np.ndarray,
    chan: np.ndarray,
    tan: np.ndarray,
    frame: int,
    apex: np.ndarray,
    sign: float,
    ray_theta: np.ndarray,
    order: np.ndarray,
    seg: np.ndarray,
    pos: np.ndarray,
    w: np.ndarray,
) -> None:  # pragma: no cover - jit
    """Radius and Z of every bracketed crossing: the root of the segment's angle (:func:`_root`)."""
    period = 2.0 * math.pi
    z = chan.shape[1] - 1
    for c in range(seg.shape[1]):  # a revolution at a time, rays in increasing angle: the steps
        for b in range(order.size):  # read stay in the cache, as the bracketing walk reads them
            r = order[b]
            j = seg[r, c]
            if j < 0:
                pos[r, c] = math.nan
                w[r, c] = math.nan
                continue
            q = ray_theta[r] + period * c
            u = _root(angle, chan, tan, j, q, frame, apex, sign)
            pos[r, c] = _polar(chan, tan, j, u, frame, apex, sign, angle[j])[1]
            w[r, c] = _channel(chan, tan, j, z, u)


def crossings(
    angle: np.ndarray,
    chan: np.ndarray,
    tan: np.ndarray,
    ray_theta: np.ndarray,
    frame: int = SPINDLE,
    apex: tuple[float, float] = (0.0, 0.0),
    sign: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where a timed program with cubic segments passes the rays at ``ray_theta`` [rad]
    (model §5): once per revolution of the polar angle, at θ + 2πc. ``angle`` (N,) the
    points' unwrapped polar angle [rad] in the frame, increasing; ``chan`` (N, K) the
    channels (C first, Z last), ``tan`` their tangents (N − 1, 2K). Returns the radius [µm],
    Z [µm] and segment j of each crossing, (R, revolutions) arrays, NaN (−1) where the program
    does not run: as :func:`ftsweep.stages.interpolation.rays.crossings` for linear segments."""
    angle = np.ascontiguousarray(angle, dtype=np.float64)
    g = ray_grid(angle, ray_theta)
    _cubic(
        angle,
        np.ascontiguousarray(chan, dtype=np.float64),
        np.ascontiguousarray(tan, dtype=np.float64),
        frame,
        np.asarray(apex, dtype=np.float64),
        float(sign),
        g.theta,
        g.order,
        g.seg,
        g.pos,
        g.w,
    )
    return g.pos, g.w, g.seg
