"""Bicubic tensor-product B-splines evaluated by numba (the kernel behind height-map surfaces;
FITPACK fits the coefficients, see ftsweep.inputs.usersurfaces). Lengths in µm."""

from __future__ import annotations

import numpy as np
from numba import njit

from ftsweep.stages.sampling.geometry import evaluate_flat


@njit(nogil=True, cache=True, inline="always")
def _span(t: np.ndarray, k: int, u: float) -> int:  # pragma: no cover - jit
    """Knot span l with t[l] ≤ u < t[l+1], clamped to the spline's domain."""
    lo, hi = k, t.size - k - 2
    if u >= t[hi + 1]:
        return hi
    if u <= t[lo]:
        return lo
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if u < t[mid]:
            hi = mid
        else:
            lo = mid
    return lo if u < t[lo + 1] else hi


@njit(nogil=True, cache=True, inline="always")
def _cubic_basis(
    t: np.ndarray,
    span: int,
    u: float,
    n: np.ndarray,
    dn: np.ndarray,
    left: np.ndarray,
    right: np.ndarray,
    b: np.ndarray,
) -> None:  # pragma: no cover - jit
    """Values n[0..3] and derivatives dn[0..3] of the cubic B-splines span−3..span at u (de Boor);
    ``left``, ``right``, ``b`` are scratch arrays of 4 (allocated once by the caller)."""
    for r in range(4):
        b[r] = 0.0
    b[0] = 1.0
    for j in range(1, 4):
        left[j] = u - t[span + 1 - j]
        right[j] = t[span + j] - u
        saved = 0.0
        if j == 3:
            # the quadratic basis gives the cubic's derivative: N'_{i,3} = 3(N_{i,2}/Δ − N_{i+1,2}/Δ')
            for r in range(4):
                dn[r] = 0.0
            for r in range(3):
                den = right[r + 1] + left[3 - r]
                temp = b[r] / den if den != 0.0 else 0.0
                dn[r] -= 3.0 * temp
                dn[r + 1] += 3.0 * temp
        for r in range(j):
            den = right[r + 1] + left[j - r]
            temp = b[r] / den if den != 0.0 else 0.0
            b[r] = saved + right[r + 1] * temp
            saved = left[j - r] * temp
        b[j] = saved
    for r in range(4):
        n[r] = b[r]


@njit(nogil=True, cache=True)
def _bspline2d_kernel(
    x: np.ndarray,
    y: np.ndarray,
    tx: np.ndarray,
    ty: np.ndarray,
    coef: np.ndarray,
    f: np.ndarray,
    fx: np.ndarray,
    fy: np.ndarray,
) -> None:  # pragma: no cover - jit
    nx_ = np.empty(4)
    dnx = np.empty(4)
    ny_ = np.empty(4)
    dny = np.empty(4)
    left = np.empty(4)
    right = np.empty(4)
    scratch = np.empty(4)
    for p in range(x.size):
        lx = _span(tx, 3, x[p])
        ly = _span(ty, 3, y[p])
        _cubic_basis(tx, lx, x[p], nx_, dnx, left, right, scratch)
        _cubic_basis(ty, ly, y[p], ny_, dny, left, right, scratch)
        v = 0.0
        vx = 0.0
        vy = 0.0
        for a in range(4):
            for b in range(4):
                c = coef[lx - 3 + a, ly - 3 + b]
                v += c * nx_[a] * ny_[b]
                vx += c * dnx[a] * ny_[b]
                vy += c * nx_[a] * dny[b]
        f[p] = v
        fx[p] = vx
        fy[p] = vy


def bspline2d(
    x: np.ndarray, y: np.ndarray, *, knots_x: np.ndarray, knots_y: np.ndarray, coefficients: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A bicubic tensor-product B-spline and its gradient: f = Σ_ab c_ab·N_a(x)·N_b(y).

    ``knots_x``, ``knots_y`` [µm] and ``coefficients`` [µm], shape (len(knots_x) − 4,
    len(knots_y) − 4), describe the spline (e.g. as fitted through a height map); outside
    the knots the end pieces continue. Returns f [µm], ∂f/∂x [-], ∂f/∂y [-].
    """
    return evaluate_flat(
        _bspline2d_kernel,
        x,
        y,
        np.ascontiguousarray(knots_x, dtype=np.float64),
        np.ascontiguousarray(knots_y, dtype=np.float64),
        np.ascontiguousarray(coefficients, dtype=np.float64),
    )
