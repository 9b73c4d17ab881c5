"""Geometry every surface shares (model §2, §4, §7): the centred aperture, the radial
section through the spindle axis, and a sampled bound of the slope. Lengths in µm."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
from numba import njit

SurfaceFn = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]


def flat_pair(x: np.ndarray, y: np.ndarray) -> tuple[tuple[int, ...], np.ndarray, np.ndarray]:
    """Broadcast x, y and flatten them to contiguous float64 (one cached numba specialisation;
    a kernel reading mismatched lengths would read past the end)."""
    xb, yb = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
    return xb.shape, np.ascontiguousarray(xb).reshape(-1), np.ascontiguousarray(yb).reshape(-1)


def evaluate_flat(
    kernel: Callable[..., None], x: np.ndarray, y: np.ndarray, *args: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Run a surface kernel ``kernel(xf, yf, *args, f, fx, fy)`` over x, y [µm] broadcast and
    flattened (:func:`flat_pair`), its outputs allocated here, and return f [µm], ∂f/∂x [-],
    ∂f/∂y [-] in the broadcast shape of x and y: the wrapper every surface family shares."""
    shape, xf, yf = flat_pair(x, y)
    f, fx, fy = np.empty_like(xf), np.empty_like(xf), np.empty_like(xf)
    kernel(xf, yf, *args, f, fx, fy)
    return f.reshape(shape), fx.reshape(shape), fy.reshape(shape)


def evaluate_lines(
    kernel: Callable[..., None],
    first_um: np.ndarray,
    spacing_um: float,
    offset: int,
    n_nodes: int,
    cos_t: np.ndarray,
    sin_t: np.ndarray,
    *args: Any,
) -> tuple[np.ndarray, np.ndarray]:
    """Run a family's line kernel ``kernel(first, spacing, offset, cos_t, sin_t, *args, g, gp)``
    over radial sections sampled at r_ij = first_i − (j − offset)·spacing [µm], j < ``n_nodes``
    (the node grid of :func:`ftsweep.stages.interpolation.tables.path_grid`), and return the section
    height g [µm] and radial slope g' [-], each (R, n_nodes): :func:`radial_section` on that
    grid in one pass, the wrapper every family's ``lines`` evaluator shares (model §4, §5)."""
    first = np.ascontiguousarray(first_um, dtype=np.float64).reshape(-1)
    c = np.ascontiguousarray(cos_t, dtype=np.float64).reshape(-1)
    s = np.ascontiguousarray(sin_t, dtype=np.float64).reshape(-1)
    if not first.size == c.size == s.size:
        raise ValueError(f"line sampling needs one cos and sin per ray, got {first.size}, {c.size}, {s.size}")
    g = np.empty((first.size, int(n_nodes)))
    gp = np.empty_like(g)
    kernel(first, float(spacing_um), int(offset), c, s, *args, g, gp)
    return g, gp


def line_evaluator(
    kernel: Callable[..., None], kernel_args: Callable[..., tuple[Any, ...]], doc: str
) -> Callable[..., tuple[np.ndarray, np.ndarray]]:
    """A family's ``lines`` evaluator ``fn(first, spacing, offset, n_nodes, cos_t, sin_t,
    **params) -> (g, g')``: :func:`evaluate_lines` of ``kernel`` with the kernel arguments
    ``kernel_args(**params)`` (which also checks the parameters), documented by ``doc``."""

    def lines(
        first_um: np.ndarray,
        spacing_um: float,
        offset: int,
        n_nodes: int,
        cos_t: np.ndarray,
        sin_t: np.ndarray,
        **params: Any,
    ) -> tuple[np.ndarray, np.ndarray]:
        args = kernel_args(**params)
        return evaluate_lines(kernel, first_um, spacing_um, offset, n_nodes, cos_t, sin_t, *args)

    lines.__doc__ = doc
    return lines


def sampled_gradient_bound(
    surface: SurfaceFn, half_width_um: float, n: int = 401, margin: float = 1.25
) -> float:
    """An estimate of max |∇f| [-] over the square |x|, |y| ≤ half_width: the largest sampled
    gradient times ``margin`` (for families without an analytic bound). Compensation raises if
    a section is ever steeper, so an estimate that is too low fails loudly, never silently."""
    g = np.linspace(-half_width_um, half_width_um, n)
    x, y = np.meshgrid(g, g)
    _, fx, fy = surface(x, y)
    return float(np.nanmax(np.hypot(fx, fy))) * margin


def radial_section(
    surface: SurfaceFn, r: np.ndarray, cos_t: np.ndarray, sin_t: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Height g and radial slope g' of the section through the spindle axis (model §4).

    g(r) = f(r·cosθ, r·sinθ), g'(r) = ∂f/∂x·cosθ + ∂f/∂y·sinθ. ``r`` [µm] may be negative
    (the section continues through the axis); ``cos_t``, ``sin_t`` are cosθ and sinθ of the
    section angle, passed in because callers evaluate many radii on the same sections.
    Returns g [µm] and g' [-], broadcast to a common shape.
    """
    f, fx, fy = surface(r * cos_t, r * sin_t)
    return f, fx * cos_t + fy * sin_t


# --------------------------------------------------------------------------- apertures
@njit(nogil=True, cache=True)
def _inside_rectangle_rows(
    r: np.ndarray, ct: np.ndarray, st: np.ndarray, hw: float, hh: float, out: np.ndarray
) -> None:  # pragma: no cover - jit
    for i in range(r.shape[0]):
        c, s = ct[i], st[i]
        for j in range(r.shape[1]):
            # ``&``, not ``and``: no short-circuit branch, so the row runs four nodes at a time
            out[i, j] = (abs(r[i, j] * c) <= hw) & (abs(r[i, j] * s) <= hh)


@njit(nogil=True, cache=True)
def _inside_circle_flat(r: np.ndarray, radius: float, out: np.ndarray) -> None:  # pragma: no cover - jit
    for i in range(r.size):
        out[i] = abs(r[i]) <= radius


class Aperture(NamedTuple):
    """A centred aperture: ``circle`` of ``radius_um`` or ``rectangle`` ``width_um`` × ``height_um``
    (model §2 and §7). All lengths in µm."""

    shape: str
    radius_um: float = 0.0
    width_um: float = 0.0
    height_um: float = 0.0

    def contains(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """True where (x, y) [µm] lies inside the aperture (the evaluation region of §6)."""
        if self.shape == "circle":
            return x * x + y * y <= self.radius_um * self.radius_um
        return (np.abs(x) <= 0.5 * self.width_um) & (np.abs(y) <= 0.5 * self.height_um)

    def contains_polar(self, r: np.ndarray, cos_t: np.ndarray, sin_t: np.ndarray) -> np.ndarray:
        """:meth:`contains` for points at radius ``r`` [µm] on sections of angle θ (cos, sin)."""
        if self.shape == "circle":
            if r.ndim == 2 and r.flags.c_contiguous:
                # the case runner's (rays, nodes) grids: one pass, no |r| array
                inside = np.empty(r.shape, dtype=np.bool_)
                _inside_circle_flat(r.reshape(-1), float(self.radius_um), inside.reshape(-1))
                return inside
            return np.abs(r) <= self.radius_um
        hw, hh = 0.5 * self.width_um, 0.5 * self.height_um
        if r.ndim == 2 and np.shape(cos_t) == np.shape(sin_t) == (r.shape[0], 1):
            # the case runner's (rays, nodes) grids: one pass instead of six array operations
            out = np.empty(r.shape, dtype=np.bool_)
            _inside_rectangle_rows(
                np.ascontiguousarray(r), cos_t[:, 0].copy(), sin_t[:, 0].copy(), hw, hh, out
            )
            return out
        return (np.abs(r * cos_t) <= hw) & (np.abs(r * sin_t) <= hh)

    def extent_along_um(self, cos_t: np.ndarray, sin_t: np.ndarray) -> np.ndarray:
        """Farthest radius [µm] of the aperture along each direction θ (cos, sin) from its
        centre (the same along θ + π): where a ray leaves it."""
        c, s = np.abs(np.asarray(cos_t, dtype=np.float64)), np.abs(np.asarray(sin_t, dtype=np.float64))
        if self.shape == "circle":
            return np.full(np.broadcast(c, s).shape, float(self.radius_um))
        with np.errstate(divide="ignore"):
            return np.minimum(0.5 * self.width_um / c, 0.5 * self.height_um / s)

    @property
    def half_extent_um(self) -> tuple[float, float]:
        """Half width and half height [µm] of the aperture's bounding box."""
        if self.shape == "circle":
            return float(self.radius_um), float(self.radius_um)
        return 0.5 * self.width_um, 0.5 * self.height_um

    @property
    def outer_radius_um(self) -> float:
        """Radius [µm] of the smallest centred circle holding the aperture: where the spiral starts."""
        if self.shape == "circle":
            return float(self.radius_um)
        return 0.5 * math.hypot(self.width_um, self.height_um)

    @property
    def inner_radius_um(self) -> float:
        """Radius [µm] of the largest centred circle inside the aperture (sets the zone split)."""
        if self.shape == "circle":
            return float(self.radius_um)
        return 0.5 * min(self.width_um, self.height_um)
