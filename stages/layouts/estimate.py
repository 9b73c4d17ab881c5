"""First-order estimate of the form error of a table layout, without simulating (model §3, §5).

Bilinear interpolation (eq. 2) of a smooth f over a cell of pitches Δ₁, Δ₂ deviates from f by

    e(t, u) ≈ ½·[t(1 − t)·Δ₁²·∂₁₁f + u(1 − u)·Δ₂²·∂₂₂f],   t, u ∈ [0, 1]

(the interpolant lies above a convex f), which spans, over the cell,
⅛·(Δ₁²·min(∂₁₁f, 0) + Δ₂²·min(∂₂₂f, 0)) … ⅛·(Δ₁²·max(∂₁₁f, 0) + Δ₂²·max(∂₂₂f, 0)).
For rings the coordinates are (ρ [µm], θ [rad]); for meshes (x, y) [µm]. The predicted P-V
is the span of e over the part plus the feed cusp F²/(8·Rc) (eq. 6), which the tool arc
leaves on top of any table. The second derivatives come from central differences of the
surface's analytic gradient on a sampling grid over the aperture, once per surface; every
(N, α) of a sweep plane then costs one pass over the samples (:func:`interp_span_nm`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ftsweep.stages.sampling.geometry import Aperture, SurfaceFn


def ring_second_derivatives(
    surface: SurfaceFn, aperture: Aperture, n_rho: int = 200, n_theta: int = 720, step_um: float = 0.05
) -> tuple[np.ndarray, np.ndarray]:
    """∂²f/∂ρ² [1/µm] and ∂²f/∂θ² [µm/rad²] on a polar grid over the aperture (flattened).

    ∂²f/∂ρ² is the central difference of the radial slope over ±``step_um``; ∂²f/∂θ² the
    central difference of ∂f/∂θ = ρ·(−f_x sinθ + f_y cosθ) over ±``step_um``/ρ radians (the
    same arc length). Points outside the aperture are dropped.
    """
    rho = np.linspace(0.0, aperture.outer_radius_um, n_rho + 1)[1:]
    theta = np.linspace(0.0, 2.0 * math.pi, n_theta, endpoint=False)
    r, t = (a.reshape(-1) for a in np.meshgrid(rho, theta, indexing="ij"))
    c, s = np.cos(t), np.sin(t)
    inside = aperture.contains_polar(r, c, s)
    r, t, c, s = r[inside], t[inside], c[inside], s[inside]

    def radial_slope(rr: np.ndarray) -> np.ndarray:
        _, fx, fy = surface(rr * c, rr * s)
        return fx * c + fy * s

    f_rr = (radial_slope(r + step_um) - radial_slope(r - step_um)) / (2.0 * step_um)

    def angular_slope(tt: np.ndarray) -> np.ndarray:
        ct, st = np.cos(tt), np.sin(tt)
        _, fx, fy = surface(r * ct, r * st)
        return r * (fy * ct - fx * st)

    dt = step_um / r
    f_tt = (angular_slope(t + dt) - angular_slope(t - dt)) / (2.0 * dt)
    return f_rr, f_tt


def mesh_second_derivatives(
    surface: SurfaceFn, aperture: Aperture, n: int = 400, step_um: float = 0.05
) -> tuple[np.ndarray, np.ndarray]:
    """∂²f/∂x² and ∂²f/∂y² [1/µm] on an n × n grid over the aperture's bounding box
    (flattened, points outside the aperture dropped), by central differences of f_x and f_y."""
    hw, hh = aperture.half_extent_um
    x, y = (a.reshape(-1) for a in np.meshgrid(np.linspace(-hw, hw, n), np.linspace(-hh, hh, n)))
    inside = aperture.contains(x, y)
    x, y = x[inside], y[inside]
    _, fx_p, _ = surface(x + step_um, y)
    _, fx_m, _ = surface(x - step_um, y)
    _, _, fy_p = surface(x, y + step_um)
    _, _, fy_m = surface(x, y - step_um)
    return (fx_p - fx_m) / (2.0 * step_um), (fy_p - fy_m) / (2.0 * step_um)


@njit(nogil=True, cache=True)
def _span_kernel(
    d11: np.ndarray, d22: np.ndarray, p1: np.ndarray, p2: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover - jit
    for k in range(p1.size):
        w1 = p1[k] * p1[k] / 8.0
        w2 = p2[k] * p2[k] / 8.0
        hi = -math.inf
        lo = math.inf
        for i in range(d11.size):
            a = d11[i]
            b = d22[i]
            top = w1 * max(a, 0.0) + w2 * max(b, 0.0)
            bottom = w1 * min(a, 0.0) + w2 * min(b, 0.0)
            if top > hi:
                hi = top
            if bottom < lo:
                lo = bottom
        out[k] = hi - lo


def _pareto_front(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Indices of the points (a_i, b_i) no other point dominates (a ≥ and b ≥): the maximum
    of w₁·a + w₂·b with w₁, w₂ ≥ 0 is always attained on them."""
    order = np.lexsort((-b, -a))  # a descending, ties by b descending
    b_sorted = b[order]
    best_before = np.maximum.accumulate(np.concatenate(([-np.inf], b_sorted[:-1])))
    return order[b_sorted > best_before]


def extreme_samples(d11: np.ndarray, d22: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The samples that can set the span for some pitches: the Pareto fronts of the positive
    parts (the top of the error) and of the negated negative parts (its bottom). The span of
    :func:`interp_span_nm` over them equals that over all samples, bit for bit, in a few
    samples instead of ~10⁵."""
    a, b = np.asarray(d11, dtype=np.float64), np.asarray(d22, dtype=np.float64)
    if a.size == 0:
        return a, b
    top = _pareto_front(np.maximum(a, 0.0), np.maximum(b, 0.0))
    bottom = _pareto_front(-np.minimum(a, 0.0), -np.minimum(b, 0.0))
    keep = np.union1d(top, bottom)
    return a[keep], b[keep]


def interp_span_nm(d11: np.ndarray, d22: np.ndarray, pitch1: np.ndarray, pitch2: np.ndarray) -> np.ndarray:
    """Span [nm] of the first-order bilinear error over the part for each pair of pitches.

    d11, d22 : sampled second derivatives along the two table coordinates (see the module).
    pitch1, pitch2 : arrays of equal shape, pitches in the same coordinates (µm; rad for θ).
    """
    p1 = np.ascontiguousarray(pitch1, dtype=np.float64).reshape(-1)
    p2 = np.ascontiguousarray(pitch2, dtype=np.float64).reshape(-1)
    out = np.empty(p1.size)
    a, b = extreme_samples(d11, d22)
    _span_kernel(np.ascontiguousarray(a), np.ascontiguousarray(b), p1, p2, out)
    return (out * 1e3).reshape(np.shape(pitch1))


def cusp_nm(feed_um: float, nose_radius_um: float) -> float:
    """Feed cusp height F²/(8·Rc) [nm] (model §5, eq. 6)."""
    return feed_um * feed_um / (8.0 * nose_radius_um) * 1e3
