"""A catalog surface's faceted form ([2] eq. 3, the ``fresnel: {facet_height_um}`` key of a
surface entry) and the range it is sliced over: the lowest point inside the aperture ([2]
appendix A.2), the highest height and the reach of the contours about it. Lengths in µm.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ftsweep.stages.paths import fresnel as ff

__all__ = ["sliced_callable", "surface_range"]


def surface_range(fn: Callable[..., Any], aperture: Any, samples: int = 241) -> dict[str, Any]:
    """The surface's lowest point inside the aperture (refined by scipy's bounded L-BFGS-B
    from the best of a ``samples``² grid) and its highest sampled height [µm]; ``interior``
    tells whether the lowest point lies inside (a bowl whose contours close about it)."""
    from scipy.optimize import minimize

    hx, hy = aperture.half_extent_um
    gx, gy = np.meshgrid(np.linspace(-hx, hx, samples), np.linspace(-hy, hy, samples))
    inside = aperture.contains(gx, gy)
    f = fn(gx[inside], gy[inside])[0]
    edge = _aperture_edge(aperture, 4096)
    f_edge = fn(edge[:, 0], edge[:, 1])[0]
    best = int(np.argmin(f))
    start = np.array([gx[inside][best], gy[inside][best]])

    def fun(p: np.ndarray) -> tuple[float, np.ndarray]:
        v, dx, dy = fn(p[:1], p[1:])
        return float(v[0]), np.array([dx[0], dy[0]])

    res = minimize(fun, start, jac=True, method="L-BFGS-B", bounds=[(-hx, hx), (-hy, hy)])
    apex = _newton_minimum(fn, np.asarray(res.x, dtype=np.float64))
    f_ref = min(float(fn(apex[:1], apex[1:])[0][0]), float(f.min()))
    step = 2.0 * max(hx, hy) / (samples - 1)
    interior = bool(aperture.contains(apex[:1], apex[1:])[0]) and float(f_edge.min()) > f_ref
    clear = float(np.min(np.hypot(*(edge - apex).T))) > step
    return {
        "apex_um": apex,
        "f_ref_um": f_ref,
        "max_um": float(max(f.max(), f_edge.max())),
        "interior": interior and clear,
        "reach_um": 1.5 * float(np.max(np.hypot(*(edge - apex).T))),
    }


def _newton_minimum(fn: Callable[..., Any], p: np.ndarray, iterations: int = 6) -> np.ndarray:
    """Newton steps on ∇f = 0 from p [µm] (Hessian by central differences of the analytic
    gradient): the path closes on this point, where eq. 9 follows the gradient's direction
    down to radii of nanometres, so the optimiser's tolerance is not enough."""
    for _ in range(iterations):
        d = 0.5
        xs = p[0] + np.array([0.0, d, -d, 0.0, 0.0])
        ys = p[1] + np.array([0.0, 0.0, 0.0, d, -d])
        _, gx, gy = fn(xs, ys)
        hess = np.array([[gx[1] - gx[2], gx[3] - gx[4]], [gy[1] - gy[2], gy[3] - gy[4]]]) / (2.0 * d)
        try:
            step = np.linalg.solve(0.5 * (hess + hess.T), np.array([gx[0], gy[0]]))
        except np.linalg.LinAlgError:
            return p
        if not np.all(np.isfinite(step)) or np.hypot(*step) > 10.0 * d:
            return p
        p = p - step
    return p


def _aperture_edge(aperture: Any, n: int) -> np.ndarray:
    """``n`` points along the aperture's boundary [µm]."""
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    if aperture.shape == "circle":
        r = aperture.radius_um
        return np.column_stack([r * np.cos(t), r * np.sin(t)])
    hx, hy = aperture.half_extent_um
    # the square's boundary by the unit circle's radial projection
    c, s = np.cos(t), np.sin(t)
    scale = 1.0 / np.maximum(np.abs(c) / hx, np.abs(s) / hy)
    return np.column_stack([c * scale, s * scale])


def sliced_callable(fn: Callable[..., Any], aperture: Any, facet_height_um: float) -> Callable[..., Any]:
    """The Fresnel form of a surface callable ([2] eq. 3), facets counted from the lowest
    point inside the aperture: the catalog's ``fresnel: {facet_height_um}`` transform."""
    rng = surface_range(fn, aperture)
    return ff.fresnel_surface(fn, rng["f_ref_um"], float(facet_height_um))
