"""The least-time timesteps of a program whose points are fixed, and a lower bound on them
(docs/kinds.md "Time-optimal timing"; the difference scheme of :mod:`.axes`, [2] eq. 14).

A program's points q (P × A, SI) are fixed; its P − 1 timesteps T_k are free. In speeds
s_k = 1/T_k, with d_k = q_{k+1} − q_k and per axis the limits V and A (already divided by the
safety factor), the program meets its limits when

- every step: |d_k| s_k ≤ V, i.e. s_k ≤ cap_k = min over axes of V/|d_k|;
- every interior point i: |d_i s_i − d_{i−1} s_{i−1}| ≤ (A/2)·(1/s_{i−1} + 1/s_i) (eq. 14
  times the mean step), two inequalities per axis, each of the form
  α·y − β·x ≤ c/x + c/y with x = s_{i−1}, y = s_i, c = A/2, (α, β) = ±(d_i, d_{i−1}).

Where α > 0 the left side grows with y, so a point caps y given x: y ≤ root(β·x + c/x), the
positive root of α·y² − R·y − c = 0 (:func:`pair_y_cap`); where β < 0 it caps x given y in the
same way (:func:`pair_x_cap`); where α ≤ 0 and β ≥ 0 it always holds.

*Fastest profile* (:func:`fastest`, an upper bound): speeds start at their caps and are only
ever lowered, as in the forward-backward passes of time-optimal path parametrisation. A point
where an axis reverses (α > 0 > β) first caps both steps at the equal speed that meets it,
sqrt(2c/(α − β)). A backward pass lowers each s_{k−1} to what s_k allows, a forward pass each
s_k to what s_{k−1} allows; where the forward cap leaves the point's backward inequality
unmet, the pair is solved together (the greatest x ≤ s_{k−1} whose forward cap lets x stand,
by bisection), which takes the passes from hundreds to a few. Passes stop when the total
changes by less than ``tol``; the caller checks the result on every point (eq. 14) and
scales it where rounding left a point above a limit.

*Lower bound*: :mod:`ftsweep.stages.kinematics.certificate`, from the same pair caps with the
relaxation σ > 0 of :func:`pair_y_cap` and :func:`pair_x_cap`.

Units: positions in SI (m, rad), speeds s in 1/s, times in s.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(nogil=True, cache=True)
def speed_caps(
    d: np.ndarray, velocity: np.ndarray, shortest_s: float
) -> np.ndarray:  # pragma: no cover - jit
    """cap_k [1/s]: the greatest speed 1/T_k at which no axis of step k (displacements
    ``d`` (P − 1, A), SI) exceeds its ``velocity`` limit (A,); 1/``shortest_s`` for a step no
    limited axis moves over (time must still pass)."""
    n, m = d.shape
    cap = np.empty(n)
    for k in range(n):
        best = math.inf
        for j in range(m):
            move = abs(d[k, j])
            if move > 0.0 and move * best > velocity[j]:
                best = velocity[j] / move
        cap[k] = best if best < math.inf else 1.0 / shortest_s
    return cap


@njit(nogil=True, cache=True, inline="always")
def _root(coef: float, rhs: float, c: float) -> float:  # pragma: no cover - jit
    """The positive root of coef·z² − rhs·z − c = 0 (coef, c > 0): the greatest z with
    coef·z − c/z ≤ rhs."""
    return (rhs + math.sqrt(rhs * rhs + 4.0 * coef * c)) / (2.0 * coef)


@njit(nogil=True, cache=True)
def pair_y_cap(
    d0: np.ndarray, d1: np.ndarray, x: float, accel: np.ndarray, y: float, sigma: float
) -> float:  # pragma: no cover - jit
    """min(y, the caps on y the point's inequalities with α > 0 set given x); with σ > 0 the
    relaxed caps U (:mod:`ftsweep.stages.kinematics.certificate`: the sup over x' in [σ, x])."""
    for j in range(d0.size):
        if not accel[j] < math.inf:
            continue
        c = 0.5 * accel[j]
        for sign in (1.0, -1.0):
            alpha, beta = sign * d1[j], sign * d0[j]
            if alpha > 0.0:
                rhs = beta * x + c / x
                if sigma > 0.0:
                    slow = beta * sigma + c / sigma
                    rhs = max(rhs, slow) if beta > 0.0 else slow
                y = min(y, _root(alpha, rhs, c))
    return y


@njit(nogil=True, cache=True)
def pair_x_cap(
    d0: np.ndarray, d1: np.ndarray, y: float, accel: np.ndarray, x: float, sigma: float
) -> float:  # pragma: no cover - jit
    """min(x, the caps on x the point's inequalities with β < 0 set given y); with σ > 0 the
    relaxed caps W. The point read backwards: its inequalities with the steps swapped and
    the sign turned, (α, β) → (−β, −α), are those :func:`pair_y_cap` takes (both signs)."""
    return pair_y_cap(d1, d0, y, accel, x, sigma)


@njit(nogil=True, cache=True)
def _reversal_caps(d: np.ndarray, accel: np.ndarray, s: np.ndarray) -> None:  # pragma: no cover - jit
    """Cap both steps of every point where an axis reverses (α > 0 > β) at the equal speed
    that meets it: (α − β)·s = 2c/s."""
    for i in range(1, d.shape[0]):
        for j in range(d.shape[1]):
            if not accel[j] < math.inf:
                continue
            for sign in (1.0, -1.0):
                alpha, beta = sign * d[i, j], sign * d[i - 1, j]
                if alpha > 0.0 and beta < 0.0:
                    m = math.sqrt(accel[j] / (alpha - beta))
                    s[i] = min(s[i], m)
                    s[i - 1] = min(s[i - 1], m)


@njit(nogil=True, cache=True)
def _joint(
    d0: np.ndarray, d1: np.ndarray, accel: np.ndarray, x: float, y: float
) -> float:  # pragma: no cover - jit
    """The greatest x' in [x/2, x] whose forward cap min(y, cap(x')) lets x' meet the point's
    backward inequalities (bisection, 60 halvings); −1 when x/2 does not."""

    def short(z: float) -> bool:
        return pair_x_cap(d0, d1, pair_y_cap(d0, d1, z, accel, y, 0.0), accel, z, 0.0) < z

    lo, hi = 0.5 * x, x
    if short(lo):
        return -1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if short(mid):
            hi = mid
        else:
            lo = mid
    return lo


@njit(nogil=True, cache=True)
def _total(s: np.ndarray) -> float:  # pragma: no cover - jit
    out = 0.0
    for k in range(s.size):
        out += 1.0 / s[k]
    return out


@njit(nogil=True, cache=True)
def fastest(
    d: np.ndarray, cap: np.ndarray, accel: np.ndarray, tol: float, passes: int
) -> np.ndarray:  # pragma: no cover - jit
    """Speeds s (P − 1) [1/s] of the fastest profile the passes reach (module docstring) for
    step displacements ``d`` (P − 1, A) SI, speed caps ``cap`` and acceleration limits
    ``accel`` (A,); at most ``passes`` backward-forward passes, fewer once the total time
    changes by less than ``tol`` (relative) in one."""
    n = cap.size
    s = cap.copy()
    _reversal_caps(d, accel, s)
    total = _total(s)
    for _ in range(passes):
        for i in range(n - 1, 0, -1):
            s[i - 1] = pair_x_cap(d[i - 1], d[i], s[i], accel, s[i - 1], 0.0)
        for i in range(1, n):
            s[i] = pair_y_cap(d[i - 1], d[i], s[i - 1], accel, s[i], 0.0)
            if pair_x_cap(d[i - 1], d[i], s[i], accel, s[i - 1], 0.0) < s[i - 1]:
                x = _joint(d[i - 1], d[i], accel, s[i - 1], s[i])
                if x > 0.0:
                    s[i - 1] = x
                    s[i] = pair_y_cap(d[i - 1], d[i], x, accel, s[i], 0.0)
        new = _total(s)
        if abs(new - total) <= tol * new:
            break
        total = new
    return s


# measured on the Fresnel parts of docs/kinds.md: the fastest profile settles in 2-4 passes
FASTEST_TOL = 1e-12
MAX_PASSES = 200
SHORTEST_S = 1e-6


def least_time_steps(q: np.ndarray, velocity: np.ndarray, accel: np.ndarray) -> np.ndarray:
    """Timesteps T (P − 1) [s] of positions q (P, A) SI that reach each step as fast as the
    limits ``velocity`` and ``accel`` (A,) SI allow by the passes of :func:`fastest`
    (module docstring), checked at every step and point by the scheme of
    :mod:`ftsweep.stages.kinematics.axes` and scaled uniformly where rounding left a point
    above a limit (a uniform scale λ divides accelerations by λ², velocities by λ)."""
    from ftsweep.stages.kinematics import axes

    q = np.ascontiguousarray(q, dtype=np.float64)
    d = np.ascontiguousarray(np.diff(q, axis=0))
    velocity = np.ascontiguousarray(velocity, dtype=np.float64)
    accel = np.ascontiguousarray(accel, dtype=np.float64)
    cap = speed_caps(d, velocity, SHORTEST_S)
    steps = 1.0 / fastest(d, cap, accel, FASTEST_TOL, MAX_PASSES)
    over = max(_worst(axes.accelerations(q, steps), accel) ** 0.5, _worst(d / steps[:, None], velocity))
    return steps * max(1.0, over * (1.0 + 1e-12))


def _worst(values: np.ndarray, limit: np.ndarray) -> float:
    """The largest |value|/limit over rows and axes (axes without a limit left out)."""
    finite = np.isfinite(limit)
    return float(np.max(np.abs(values[:, finite]) / limit[finite], initial=0.0))
