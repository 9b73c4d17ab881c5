"""The spiral's commands at the simulator's passes (model §1, §3): the controller's
interpolation between a spiral program's points (linear or the cubic segments of
:mod:`ftsweep.stages.interpolation.segments`) evaluated where the tool crosses each feed-plane line."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ftsweep.stages.interpolation import segments


@njit(nogil=True, cache=True, inline="always")
def _interval_from(xp: np.ndarray, x: float, j: int, jump: int) -> int:  # pragma: no cover - jit
    """The largest j with xp[j] ≤ x (xp ascending, xp[0] ≤ x ≤ xp[-1]), searched from the
    guess ``j + jump`` outwards by doubling steps, then by bisection."""
    n = xp.size
    g = min(max(j + jump, 0), n - 1)
    if xp[g] <= x:
        lo, step = g, 1
        hi = min(g + step, n - 1)
        while hi < n - 1 and xp[hi] <= x:
            lo = hi
            step *= 2
            hi = min(hi + step, n - 1)
        if xp[hi] <= x:
            return hi
    else:
        hi, step = g, 1
        lo = max(g - step, 0)
        while lo > 0 and xp[lo] > x:
            hi = lo
            step *= 2
            lo = max(lo - step, 0)
    while hi - lo > 1:  # xp[lo] ≤ x < xp[hi]
        mid = (lo + hi) // 2
        if xp[mid] <= x:
            lo = mid
        else:
            hi = mid
    return lo


@njit(nogil=True, cache=True, inline="always")
def _segment_value(
    xp: np.ndarray, fp: np.ndarray, d0: np.ndarray, d1: np.ndarray, j: int, x: float
) -> float:  # pragma: no cover - jit
    """The command at ``x`` in segment j (xp[j] < x < xp[j + 1]): linear as ``np.interp``
    computes it (no tangents), else the cubic Hermite of the segment's tangents."""
    if d0.size:
        return segments.hermite(fp[j], fp[j + 1], d0[j], d1[j], (x - xp[j]) / (xp[j + 1] - xp[j]))
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    value = slope * (x - xp[j]) + fp[j]
    if value != value:
        value = slope * (x - xp[j + 1]) + fp[j + 1]
        if value != value and fp[j] == fp[j + 1]:
            value = fp[j]
    return value


@njit(nogil=True, cache=True)
def pass_commands_kernel(
    xp: np.ndarray,
    fp: np.ndarray,
    d0: np.ndarray,
    d1: np.ndarray,
    ray_theta: np.ndarray,
    first_revolution: int,
    out: np.ndarray,
) -> None:  # pragma: no cover - jit
    """:func:`spiral_commands` at the passes φ = 2π·(k + ``first_revolution``) + θ of each ray
    (row of ``out``, one column a pass): with empty tangents ``d0``, ``d1`` value for value
    what ``np.interp`` gives (its interval, slope and end rules), else the cubic segments.
    Passes of a ray are a revolution apart, so each search starts a revolution's worth of
    points on from the last (O(1) a pass where a bisection over the whole path takes ~20
    cache-missing steps)."""
    n = xp.size
    for a in range(out.shape[0]):
        j = 0
        jump = 0
        for k in range(out.shape[1]):
            x = 2.0 * math.pi * (k + first_revolution) + ray_theta[a]
            if x != x:
                out[a, k] = x
            elif x < xp[0]:
                out[a, k] = fp[0]
            elif x >= xp[n - 1]:
                out[a, k] = fp[n - 1]
            else:
                found = _interval_from(xp, x, j, jump)
                jump = found - j if k > 0 else 0
                j = found
                out[a, k] = fp[j] if xp[j] == x else _segment_value(xp, fp, d0, d1, j, x)
