"""Registration of a measured part to its design: the set-up terms that move the design onto
the measured heights, fitted by least squares over the points of an aperture, with their
uncertainties, and the residual they leave (the part's form error).

A part measured off the machine sits on the instrument shifted, tilted and turned. With the
design a surface callable ``f(x, y) -> (f, f_x, f_y)`` (µm, :mod:`ftsweep.stages.sampling`),
the measured height at (x, y) is modelled as the design moved by a decentre (d_x, d_y) and a
rotation γ about the axis, plus piston p, tilt (t_x, t_y) and optionally power c:

    z(x, y) = f(x', y') + p + t_x·x + t_y·y + c·(x² + y²)
    (x', y') = R(−γ)·(x − d_x, y − d_y)                                            (1)

solved by Gauss–Newton: each step linearises (1) about the current terms, with
∂z/∂d_x = −(f_x' cos γ − f_y' sin γ), ∂z/∂d_y = −(f_x' sin γ + f_y' cos γ) and
∂z/∂γ = f_x'·y' − f_y'·x', and solves the linear least-squares problem for the update, its
columns scaled to unit RMS.
The uncertainty of each term is the square root of the diagonal of σ²·(JᵀJ)⁻¹ at the
solution, σ² = RSS/(n − k) the residual variance (n points, k terms): the standard error of
a least-squares estimate under independent residuals of equal variance.

Heights, positions, decentres, piston: µm; tilts: µm/µm; γ: rad; power: 1/µm.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

SurfaceFn = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]

# the terms in the order of the fit's columns; power and rotation are optional
TERMS = ("piston_um", "tilt_x", "tilt_y", "decentre_x_um", "decentre_y_um", "rotation_rad", "power_per_um")


class Registration(NamedTuple):
    """A fitted registration: ``terms`` and ``sigma`` {name: value} in the units of the module
    doc, ``residual`` the measured minus the registered design (NaN where nothing was
    measured or outside the aperture), ``points`` the heights used, ``iterations`` the
    Gauss–Newton steps taken."""

    terms: dict[str, float]
    sigma: dict[str, float]
    residual: np.ndarray
    points: int
    iterations: int


def _model(
    surface: SurfaceFn, x: np.ndarray, y: np.ndarray, values: dict[str, float], names: tuple[str, ...]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Heights of (1) at ``values``, the Jacobian (n, k) over ``names`` and each column's
    bound (the RMS of the most it could be)."""
    dx, dy = values["decentre_x_um"], values["decentre_y_um"]
    g = values["rotation_rad"]
    cg, sg = np.cos(g), np.sin(g)
    u, v = x - dx, y - dy
    xp, yp = cg * u + sg * v, -sg * u + cg * v
    f, fx, fy = surface(xp, yp)
    r2 = x * x + y * y
    z = f + values["piston_um"] + values["tilt_x"] * x + values["tilt_y"] * y + values["power_per_um"] * r2
    columns = {
        "piston_um": np.ones_like(x),
        "tilt_x": x,
        "tilt_y": y,
        "decentre_x_um": -(fx * cg - fy * sg),
        "decentre_y_um": -(fx * sg + fy * cg),
        "rotation_rad": fx * yp - fy * xp,
        "power_per_um": r2,
    }
    grad = np.sqrt(fx * fx + fy * fy)
    # what each column would be at most were the design not symmetric (Cauchy–Schwarz): a
    # column far below its bound is rounding, a term this design does not show
    bounds = {
        "piston_um": 1.0,
        "tilt_x": np.abs(x),
        "tilt_y": np.abs(y),
        "decentre_x_um": grad,
        "decentre_y_um": grad,
        "rotation_rad": grad * np.sqrt(r2),
        "power_per_um": r2,
    }
    jac = np.column_stack([columns[n] for n in names])
    bound = np.array([float(np.sqrt(np.mean(np.square(bounds[n])))) for n in names])
    return z, jac, bound


def _column_scale(jac: np.ndarray, bound: np.ndarray, names: tuple[str, ...]) -> np.ndarray:
    """The RMS of each column, to scale the columns to one size, so that conditioning measures
    how well the terms are told apart, not their units. A column below 1e-9 of its bound is a
    term the design does not show: refused by name."""
    rms = np.sqrt(np.mean(jac * jac, axis=0))
    none = [n for n, r, b in zip(names, rms, bound, strict=True) if not r > 1e-9 * b]
    if none:
        raise ValueError(
            f"the terms {', '.join(names)} cannot be told apart on these points: "
            f"{', '.join(none)} moves no height of this design"
        )
    return rms


def register(
    surface: SurfaceFn,
    x: np.ndarray,
    y: np.ndarray,
    z: np.ndarray,
    inside: np.ndarray,
    *,
    decentre: bool = True,
    rotation: bool = False,
    power: bool = False,
    steps: int = 20,
    tolerance: float = 1e-12,
) -> Registration:
    """Fit (1) to the measured heights ``z`` [µm] at ``x``, ``y`` [µm] (arrays of one shape;
    NaN for a missing height) over the points where ``inside`` is true (the stated aperture).

    Piston and tilt are always fitted; ``decentre``, ``rotation`` and ``power`` add (d_x, d_y),
    γ and c. A rotationally symmetric design has no rotation to find (its column is zero), and
    on a sphere a decentre is a tilt to first order: leave out what the design cannot tell.
    Stops when an update moves no term by more than ``tolerance`` of its own size (plus 1e-15)
    or after ``steps``.
    Raises ValueError when fewer points than terms remain or the terms cannot be told apart
    (a singular normal matrix)."""
    asked = {
        "decentre_x_um": decentre,
        "decentre_y_um": decentre,
        "rotation_rad": rotation,
        "power_per_um": power,
    }
    names = tuple(n for n in TERMS if asked.get(n, True))
    use = inside & np.isfinite(z)
    xs, ys, zs = x[use], y[use], z[use]
    if xs.size <= len(names):
        raise ValueError(f"{xs.size} measured point(s) in the aperture: at least {len(names) + 1} are needed")
    values = dict.fromkeys(TERMS, 0.0)
    taken = 0
    while taken < steps:
        taken += 1
        model, jac, bound = _model(surface, xs, ys, values, names)
        scale = _column_scale(jac, bound, names)
        step, *_ = np.linalg.lstsq(jac / scale, zs - model, rcond=None)
        step = step / scale
        for name, d in zip(names, step, strict=True):
            values[name] += float(d)
        if np.all(np.abs(step) <= tolerance * (np.abs([values[n] for n in names]) + 1e-15)):
            break
    model, jac, bound = _model(surface, xs, ys, values, names)
    rest = zs - model
    scale = _column_scale(jac, bound, names)
    normal = (jac / scale).T @ (jac / scale)
    if np.linalg.cond(normal) > 1e12:
        raise ValueError(f"the terms {', '.join(names)} cannot be told apart on these points")
    variance = float(rest @ rest) / (xs.size - len(names))
    cov = variance * np.linalg.inv(normal) / np.outer(scale, scale)
    residual = np.full(z.shape, np.nan)
    residual[use] = rest
    return Registration(
        terms={n: values[n] for n in names},
        sigma={n: float(np.sqrt(cov[i, i])) for i, n in enumerate(names)},
        residual=residual,
        points=int(xs.size),
        iterations=taken,
    )


def registered_like(
    surface: SurfaceFn, x: np.ndarray, y: np.ndarray, fit: Registration, heights: np.ndarray
) -> np.ndarray:
    """``heights`` [µm] at (x, y) — a predicted form error — registered as the measurement was:
    less their least-squares part in the columns of the terms ``fit`` found, at its solution
    (what the same set-up fit would take of them). NaN where the fit's residual is NaN or
    ``heights`` is."""
    use = np.isfinite(fit.residual) & np.isfinite(heights)
    names = tuple(fit.terms)
    values = dict.fromkeys(TERMS, 0.0) | fit.terms
    _, jac, bound = _model(surface, x[use], y[use], values, names)
    scaled = jac / _column_scale(jac, bound, names)
    coef, *_ = np.linalg.lstsq(scaled, heights[use], rcond=None)
    out = np.full(heights.shape, np.nan)
    out[use] = heights[use] - scaled @ coef
    return out
