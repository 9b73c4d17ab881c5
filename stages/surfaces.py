"""Surface sampling: design heights, their gradients and apertures (physics.md §7).

Every family is a numba kernel over flat float64 arrays plus a thin numpy wrapper with
keyword parameters in catalog units. All lengths are micrometres [µm], heights are
micrometres along the spindle axis, gradients are dimensionless [µm/µm].

A *surface callable* in the rest of ftsweep is any ``fn(x, y) -> (f, dfdx, dfdy)`` taking
arrays of equal shape in µm; the pipeline builds one from a catalog entry with
``functools.partial(FAMILIES[name].evaluate, **params)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numba import njit

SurfaceFn = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]


def _flat_pair(x: np.ndarray, y: np.ndarray) -> tuple[tuple[int, ...], np.ndarray, np.ndarray]:
    """Broadcast x, y and flatten them to contiguous float64 (one cached numba specialisation;
    a kernel reading mismatched lengths would read past the end)."""
    xb, yb = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
    return xb.shape, np.ascontiguousarray(xb).reshape(-1), np.ascontiguousarray(yb).reshape(-1)


# --------------------------------------------------------------------------- sinewave2d
@njit(nogil=True, cache=True)
def _sinewave2d_kernel(x, y, ax, ay, kx, ky, px, py, f, fx, fy):  # pragma: no cover - jit
    for i in range(x.size):
        argx = kx * x[i] + px
        argy = ky * y[i] + py
        f[i] = ax * math.sin(argx) + ay * math.sin(argy)
        fx[i] = ax * kx * math.cos(argx)
        fy[i] = ay * ky * math.cos(argy)


def sinewave2d(
    x: np.ndarray,
    y: np.ndarray,
    *,
    amplitude_x_um: float,
    amplitude_y_um: float,
    wavelength_x_um: float,
    wavelength_y_um: float,
    phase_x_deg: float,
    phase_y_deg: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Two crossed sine waves, physics.md §7 ``sinewave2d``.

    f = Ax·sin(2πx/λx + φx) + Ay·sin(2πy/λy + φy)

    Parameters
    ----------
    x, y : positions [µm], any equal shape.
    amplitude_x_um, amplitude_y_um : Ax, Ay [µm].
    wavelength_x_um, wavelength_y_um : λx, λy [µm].
    phase_x_deg, phase_y_deg : φx, φy [deg].

    Returns
    -------
    f [µm], ∂f/∂x [-], ∂f/∂y [-], each of the shape of ``x``.
    """
    shape, xf, yf = _flat_pair(x, y)
    f, fx, fy = np.empty_like(xf), np.empty_like(xf), np.empty_like(xf)
    _sinewave2d_kernel(
        xf,
        yf,
        float(amplitude_x_um),
        float(amplitude_y_um),
        2.0 * math.pi / wavelength_x_um,
        2.0 * math.pi / wavelength_y_um,
        math.radians(phase_x_deg),
        math.radians(phase_y_deg),
        f,
        fx,
        fy,
    )
    return f.reshape(shape), fx.reshape(shape), fy.reshape(shape)


def sinewave2d_gradient_bound(
    *,
    amplitude_x_um: float,
    amplitude_y_um: float,
    wavelength_x_um: float,
    wavelength_y_um: float,
    **_: float,
) -> float:
    """Upper bound of |∇f| for :func:`sinewave2d` [-]: sqrt((2πAx/λx)² + (2πAy/λy)²)."""
    gx = 2.0 * math.pi * abs(amplitude_x_um) / wavelength_x_um
    gy = 2.0 * math.pi * abs(amplitude_y_um) / wavelength_y_um
    return math.hypot(gx, gy)


# --------------------------------------------------------------------------- lens_array
@njit(nogil=True, cache=True)
def _lens_array_kernel(x, y, R, h, pitch, nx, ny, f, fx, fy):  # pragma: no cover - jit
    a = math.sqrt(2.0 * h * R - h * h)
    rt = 0.5 * R
    Rt = a * (1.0 + rt / R)
    zc = rt * (R - h) / R  # depth of the torus tube centre below the plane z = 0
    plane = rt * h / R
    cx0 = 0.5 * (nx - 1)
    cy0 = 0.5 * (ny - 1)
    for n in range(x.size):
        # nearest lenslet centre, clipped to the grid of lenslets
        i = math.floor(x[n] / pitch + cx0 + 0.5)
        j = math.floor(y[n] / pitch + cy0 + 0.5)
        i = min(max(i, 0), nx - 1)
        j = min(max(j, 0), ny - 1)
        dx = x[n] - (i - cx0) * pitch
        dy = y[n] - (j - cy0) * pitch
        r = math.sqrt(dx * dx + dy * dy)
        if r <= a:
            root = math.sqrt(R * R - r * r)
            f[n] = R - h - root
            dfdr = r / root
        elif r <= Rt:
            root = math.sqrt(max(rt * rt - (r - Rt) * (r - Rt), 0.0))
            f[n] = root - zc
            dfdr = -(r - Rt) / root if root > 0.0 else 0.0
        else:
            f[n] = plane
            dfdr = 0.0
        if r > 0.0:
            fx[n] = dfdr * dx / r
            fy[n] = dfdr * dy / r
        else:
            fx[n] = 0.0
            fy[n] = 0.0


def lens_array(
    x: np.ndarray,
    y: np.ndarray,
    *,
    radius_um: float,
    sag_um: float,
    pitch_um: float,
    count_x: int,
    count_y: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Square array of spherical lenslets blended by tori, physics.md §7 ``lens_array``.

    With r the distance to the nearest lenslet centre, a = sqrt(2hR − h²), rt = R/2 and
    Rt = a·(1 + rt/R):  r ≤ a: f = R − h − sqrt(R² − r²);  a < r ≤ Rt:
    f = sqrt(rt² − (r − Rt)²) − rt·(R − h)/R;  r > Rt: f = rt·h/R.

    Parameters
    ----------
    x, y : positions [µm].
    radius_um : lenslet radius of curvature R [µm].
    sag_um : lenslet sag h [µm].
    pitch_um : centre-to-centre pitch of the square grid [µm].
    count_x, count_y : lenslets along x and y, centred on the origin.

    Returns
    -------
    f [µm], ∂f/∂x [-], ∂f/∂y [-].
    """
    if not 0.0 < sag_um < radius_um:
        raise ValueError(f"lens_array needs 0 < sag_um < radius_um, got {sag_um}, {radius_um}")
    shape, xf, yf = _flat_pair(x, y)
    f, fx, fy = np.empty_like(xf), np.empty_like(xf), np.empty_like(xf)
    _lens_array_kernel(
        xf, yf, float(radius_um), float(sag_um), float(pitch_um), int(count_x), int(count_y), f, fx, fy
    )
    return f.reshape(shape), fx.reshape(shape), fy.reshape(shape)


def lens_array_gradient_bound(*, radius_um: float, sag_um: float, **_: float) -> float:
    """Upper bound of |∇f| for :func:`lens_array` [-]: the slope at the sphere/torus seam r = a."""
    a = math.sqrt(2.0 * sag_um * radius_um - sag_um**2)
    return a / math.sqrt(radius_um**2 - a**2)


# --------------------------------------------------------------------------- registry
class Family(NamedTuple):
    """A surface family: its evaluator and an analytic bound of its gradient magnitude."""

    evaluate: Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray]]
    gradient_bound: Callable[..., float]


FAMILIES: dict[str, Family] = {
    "sinewave2d": Family(sinewave2d, sinewave2d_gradient_bound),
    "lens_array": Family(lens_array, lens_array_gradient_bound),
}


def radial_section(
    surface: SurfaceFn, r: np.ndarray, cos_t: np.ndarray, sin_t: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Height g and radial slope g' of the section through the spindle axis (physics.md §4).

    g(r) = f(r·cosθ, r·sinθ), g'(r) = ∂f/∂x·cosθ + ∂f/∂y·sinθ. ``r`` [µm] may be negative
    (the section continues through the axis); ``cos_t``, ``sin_t`` are cosθ and sinθ of the
    section angle, passed in because callers evaluate many radii on the same sections.
    Returns g [µm] and g' [-], broadcast to a common shape.
    """
    f, fx, fy = surface(r * cos_t, r * sin_t)
    return f, fx * cos_t + fy * sin_t


# --------------------------------------------------------------------------- apertures
class Aperture(NamedTuple):
    """A centred aperture: ``circle`` of ``radius_um`` or ``rectangle`` ``width_um`` × ``height_um``
    (physics.md §2 and §7). All lengths in µm."""

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
            return np.abs(r) <= self.radius_um
        return (np.abs(r * cos_t) <= 0.5 * self.width_um) & (np.abs(r * sin_t) <= 0.5 * self.height_um)

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
