"""The residual (cusp) budget of a spiral program ([4] eqs. 1–3): the signed radius of
curvature of a radial section, the largest feed [µm/rev] that keeps the cusp between passes
within a budget [µm] for a nose radius [µm], and the cusp a feed leaves."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np


def signed_radius_um(slope: np.ndarray, second: np.ndarray) -> np.ndarray:
    """Radius of curvature [µm] of a radial section z = g(r) ([4] eq. 1), signed as g'':
    positive where the section is concave (a valley, curving up towards the tool), negative
    where convex; ±inf where flat."""
    with np.errstate(divide="ignore"):
        return (1.0 + np.square(slope)) ** 1.5 / np.asarray(second, dtype=np.float64)


def feed_for_cusp(
    cusp_um: float, nose_radius_um: float, radius_um: np.ndarray, slope: np.ndarray
) -> np.ndarray:
    """Largest feed per revolution [µm] (X-slide advance) whose cusp stays within
    ``cusp_um`` = Δres on a section of signed radius ``radius_um`` (:func:`signed_radius_um`)
    and slope ``slope`` ([4] eqs. 2–3, derived for the tool-centre spacing).

    Consecutive tool positions touch the section (locally a circle of radius |R| about O)
    with their arc centres on the offset circle of radius A = |R| + r (convex) or |R| − r
    (concave). With centres d apart and the residual height h between the arcs, the law of
    cosines in the triangle (O, arc centre, cusp) gives

        convex  (R < 0): d = sqrt(h(2r − h)(2|R| + h)(2|R| + 2r + h)) / (|R| + h)
        concave (R > 0): d = sqrt(h(2r − h)(2R − h)(2R − 2r − h)) / (R − h)
        flat    (R = ∞): d = 2·sqrt(h(2r − h))

    (the seed's f3, f2 and f1 with their signs made explicit; both curved forms tend to f1
    as |R| → ∞, and F²/(8r) ≈ h for small h). The centres lie along the section, inclined by
    its slope β, so the X feed is d·cos β. Concave sections of radius R ≤ r + h/2 leave no
    feed (the arc cannot follow them): 0 there.
    """
    h, r = float(cusp_um), float(nose_radius_um)
    R = np.abs(np.asarray(radius_um, dtype=np.float64))
    concave = np.asarray(radius_um) > 0.0
    flat = 2.0 * math.sqrt(h * (2.0 * r - h))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        convex_d = np.sqrt(h * (2.0 * r - h) * (2.0 * R + h) * (2.0 * R + 2.0 * r + h)) / (R + h)
        concave_d = np.sqrt(np.maximum(h * (2.0 * r - h) * (2.0 * R - h) * (2.0 * R - 2.0 * r - h), 0.0)) / (
            R - h
        )
    d = np.where(concave, concave_d, convex_d)
    d = np.where(np.isfinite(R), d, flat)
    d = np.where(concave & (R <= r + 0.5 * h), 0.0, d)
    return d / np.sqrt(1.0 + np.square(slope))


def cusp_for_feed(
    feed_um: float, nose_radius_um: float, radius_um: np.ndarray, slope: np.ndarray
) -> np.ndarray:
    """Residual (cusp) height [µm] that feed ``feed_um`` leaves on a section of signed radius
    ``radius_um`` and slope ``slope``: the inverse of :func:`feed_for_cusp`. The cusp is the
    intersection of the two arcs, on the bisector at distance A·cosγ ± sqrt(r² − A²sin²γ)
    from the section's centre of curvature, sin γ = d/(2A); NaN where the arcs do not meet."""
    r = float(nose_radius_um)
    d = feed_um * np.sqrt(1.0 + np.square(slope))
    R = np.abs(np.asarray(radius_um, dtype=np.float64))
    concave = np.asarray(radius_um) > 0.0
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        a = np.where(concave, R - r, R + r)
        half = d / (2.0 * a)
        lateral = np.sqrt(r * r - np.square(a * half))
        along = a * np.sqrt(1.0 - np.square(half))
        h = np.where(concave, R - (along + lateral), (along - lateral) - R)
    flat = r - np.sqrt(np.maximum(r * r - 0.25 * d * d, 0.0))
    # beyond a million nose radii the section is flat to a part in 1e6, and the difference of
    # large radii above would lose the cusp to rounding
    return np.where(R < 1e6 * r, h, flat)


def section_curvature(
    surface: Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray]],
    rho: np.ndarray,
    ct: np.ndarray,
    st: np.ndarray,
    step_um: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Slope g' [-] and second derivative g'' [1/µm] of radial sections g(r) = f(r cosθ,
    r sinθ) at radii ``rho`` [µm] (directions cos θ = ``ct``, sin θ = ``st``): g' from the
    surface's gradient, g'' by a central difference of g' over ±``step_um``."""

    def slope(r: np.ndarray) -> np.ndarray:
        _, fx, fy = surface(r * ct, r * st)
        return fx * ct + fy * st

    g1 = slope(rho)
    g2 = (slope(rho + step_um) - slope(rho - step_um)) / (2.0 * step_um)
    return g1, g2
