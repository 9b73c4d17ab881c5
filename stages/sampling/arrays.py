"""Surface families of repeated features (model §7): sine waves, lens arrays, sinusoidal
meshes and cylinder arrays. Lengths in µm, gradients dimensionless."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from ftsweep.stages.numerics.trig import sincos, within_reach
from ftsweep.stages.sampling.families import Param, _um, surface_family
from ftsweep.stages.sampling.geometry import evaluate_flat, line_evaluator


# --------------------------------------------------------------------------- sinewave2d
@njit(nogil=True, cache=True, inline="always")
def _sinewave2d_store(
    i: int,
    ax: float,
    ay: float,
    kx: float,
    ky: float,
    sx: float,
    cx: float,
    sy: float,
    cy: float,
    f: np.ndarray,
    fx: np.ndarray,
    fy: np.ndarray,
) -> None:  # pragma: no cover - jit
    """f, ∂f/∂x, ∂f/∂y of :func:`sinewave2d` at point ``i`` from the sines and cosines of its
    two phases (one formula for both passes of ``_sinewave2d_kernel``)."""
    f[i] = ax * sx + ay * sy
    fx[i] = ax * kx * cx
    fy[i] = ay * ky * cy


@njit(nogil=True, cache=True)
def _sinewave2d_kernel(
    x: np.ndarray,
    y: np.ndarray,
    ax: float,
    ay: float,
    kx: float,
    ky: float,
    px: float,
    py: float,
    f: np.ndarray,
    fx: np.ndarray,
    fy: np.ndarray,
) -> None:  # pragma: no cover - jit
    # the vectorisable sincos (stages.trig): the C library's scalar calls were ~80 % of the
    # table's compensation on this family; phases beyond its reach (and NaN) are taken from
    # the C library in a second pass, so the first stays free of branches
    far = False
    for i in range(x.size):
        argx = kx * x[i] + px
        argy = ky * y[i] + py
        far |= not (within_reach(argx) and within_reach(argy))
        sx, cx = sincos(argx)
        sy, cy = sincos(argy)
        _sinewave2d_store(i, ax, ay, kx, ky, sx, cx, sy, cy, f, fx, fy)
    if far:
        for i in range(x.size):
            argx = kx * x[i] + px
            argy = ky * y[i] + py
            if not (within_reach(argx) and within_reach(argy)):
                sx, cx = math.sin(argx), math.cos(argx)
                sy, cy = math.sin(argy), math.cos(argy)
                _sinewave2d_store(i, ax, ay, kx, ky, sx, cx, sy, cy, f, fx, fy)


# Along a radial section the phases kx·x and ky·y advance by a fixed step per node, so sin and
# cos are carried from node to node by the angle-addition rotation and computed afresh only
# every _ANCHOR nodes, since the libm calls dominated sampling; the phase's own rounding
# (|kx·x|·ε), not the rotations, bounds the difference from libm (docs/performance.md,
# "Tuned constants")
_ANCHOR = 128


@njit(nogil=True, cache=True)
def _sinewave2d_lines_kernel(
    first: np.ndarray,
    spacing: float,
    offset: float,
    ct: np.ndarray,
    st: np.ndarray,
    ax: float,
    ay: float,
    kx: float,
    ky: float,
    px: float,
    py: float,
    g: np.ndarray,
    gp: np.ndarray,
) -> None:  # noqa: E501  # pragma: no cover - jit
    n_rays, n_nodes = g.shape
    for i in range(n_rays):
        c = ct[i]
        s = st[i]
        # r falls by one spacing per node
        dx = -kx * (spacing * c)
        dy = -ky * (spacing * s)
        cdx, sdx = math.cos(dx), math.sin(dx)
        cdy, sdy = math.cos(dy), math.sin(dy)
        sx = cx = sy = cy = 0.0
        for j in range(n_nodes):
            if j % _ANCHOR == 0:
                r = first[i] - (j - offset) * spacing
                argx = kx * (r * c) + px
                argy = ky * (r * s) + py
                sx, cx = math.sin(argx), math.cos(argx)
                sy, cy = math.sin(argy), math.cos(argy)
            else:
                sx, cx = sx * cdx + cx * sdx, cx * cdx - sx * sdx
                sy, cy = sy * cdy + cy * sdy, cy * cdy - sy * sdy
            g[i, j] = ax * sx + ay * sy
            gp[i, j] = ax * kx * cx * c + ay * ky * cy * s


def _sinewave2d_args(
    *,
    amplitude_x_um: float,
    amplitude_y_um: float,
    wavelength_x_um: float,
    wavelength_y_um: float,
    phase_x_deg: float,
    phase_y_deg: float,
) -> tuple[float, ...]:
    """The kernels' arguments (Ax, Ay, kx, ky, φx, φy) of :func:`sinewave2d`'s parameters."""
    return (
        float(amplitude_x_um),
        float(amplitude_y_um),
        2.0 * math.pi / wavelength_x_um,
        2.0 * math.pi / wavelength_y_um,
        math.radians(phase_x_deg),
        math.radians(phase_y_deg),
    )


sinewave2d_lines = line_evaluator(
    _sinewave2d_lines_kernel,
    _sinewave2d_args,
    """:func:`sinewave2d` on the radial sections of a path grid (:func:`evaluate_lines`):
    height g [µm] and radial slope g' [-], (R, n_nodes), with sin and cos carried along each
    section by rotation (model §7 ``sinewave2d``).""",
)


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


def sinewave2d_curvature_bound(
    *,
    amplitude_x_um: float,
    amplitude_y_um: float,
    wavelength_x_um: float,
    wavelength_y_um: float,
    **_: float,
) -> float:
    """Bound of ‖∇²f‖ for :func:`sinewave2d` [1/µm]: the Hessian is diagonal,
    diag(−Ax·kx²·sin, −Ay·ky²·sin), so its norm is at most max(|Ax|·kx², |Ay|·ky²), k = 2π/λ."""
    kx = 2.0 * math.pi / wavelength_x_um
    ky = 2.0 * math.pi / wavelength_y_um
    return max(abs(amplitude_x_um) * kx * kx, abs(amplitude_y_um) * ky * ky)


@surface_family(
    "sinewave2d",
    {
        "amplitude_x_um": Param(float, _um("amplitude Ax along x")),
        "amplitude_y_um": Param(float, _um("amplitude Ay along y")),
        "wavelength_x_um": Param(float, _um("wavelength λx"), positive=True),
        "wavelength_y_um": Param(float, _um("wavelength λy"), positive=True),
        "phase_x_deg": Param(float, "phase φx [deg]", 0.0),
        "phase_y_deg": Param(float, "phase φy [deg]", 0.0),
    },
    gradient_bound=sinewave2d_gradient_bound,
    curvature_bound=sinewave2d_curvature_bound,
    lines=sinewave2d_lines,
)
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
    """Two crossed sine waves, model §7 ``sinewave2d``.

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
    args = _sinewave2d_args(
        amplitude_x_um=amplitude_x_um,
        amplitude_y_um=amplitude_y_um,
        wavelength_x_um=wavelength_x_um,
        wavelength_y_um=wavelength_y_um,
        phase_x_deg=phase_x_deg,
        phase_y_deg=phase_y_deg,
    )
    return evaluate_flat(_sinewave2d_kernel, x, y, *args)


# --------------------------------------------------------------------------- lens_array
@njit(nogil=True, cache=True, inline="always", error_model="numpy")
def _lens_point(
    x: float, y: float, R: float, h: float, pitch: float, nx: int, ny: int
) -> tuple[Any, ...]:  # pragma: no cover - jit
    """Height [µm] and gradient [-] of the lens array at one point (see :func:`lens_array`).

    Both the sphere's and the torus's expressions are formed and the point's own is
    selected, with no branch: a loop over points then runs four at a time (square roots
    included). Divisions are the dearest vector operation after the square roots, so the
    point's one quotient (q below) divides selected operands, and the lenslet index
    multiplies by the reciprocal pitch (hoisted out of a loop)."""
    a = math.sqrt(2.0 * h * R - h * h)
    rt = 0.5 * R
    Rt = a * (1.0 + rt / R)
    cx0 = 0.5 * (nx - 1)
    cy0 = 0.5 * (ny - 1)
    per_pitch = 1.0 / pitch
    # nearest lenslet centre, clipped to the grid of lenslets
    i = min(max(np.floor(x * per_pitch + cx0 + 0.5), 0.0), nx - 1.0)
    j = min(max(np.floor(y * per_pitch + cy0 + 0.5), 0.0), ny - 1.0)
    dx = x - (i - cx0) * pitch
    dy = y - (j - cy0) * pitch
    r = math.sqrt(dx * dx + dy * dy)
    # ∂f/∂x = f'(r)·dx/r with q = f'(r)/r: sphere (r ≤ a) 1/sqrt(R² − r²); torus (a < r ≤ Rt)
    # −(r − Rt)/(root·r), 0 where its root vanishes; plane 0
    sphere = r <= a
    torus = r <= Rt
    u = r - Rt
    # a point needs the sphere's root or the torus's, never both: one square root of the
    # selected radicand
    root = math.sqrt(max((R * R - r * r) if sphere else (rt * rt - u * u), 0.0))
    f = (R - h - root) if sphere else ((root - rt * (R - h) / R) if torus else rt * h / R)
    # one division of selected operands: r ≤ a < R keeps the sphere's root > 0, and a torus
    # point whose root vanishes (or a plane point) gets 0/1
    curved = torus and root > 0.0
    num = 1.0 if sphere else (-u if curved else 0.0)
    den = root if sphere else (root * r if curved else 1.0)
    q = num / den
    return f, q * dx, q * dy


@njit(nogil=True, cache=True, error_model="numpy")
def _lens_array_kernel(
    x: np.ndarray,
    y: np.ndarray,
    R: float,
    h: float,
    pitch: float,
    nx: int,
    ny: int,
    f: np.ndarray,
    fx: np.ndarray,
    fy: np.ndarray,
) -> None:  # pragma: no cover - jit
    for n in range(x.size):
        f[n], fx[n], fy[n] = _lens_point(x[n], y[n], R, h, pitch, nx, ny)


@njit(nogil=True, cache=True, error_model="numpy")
def _lens_array_lines_kernel(
    first: np.ndarray,
    spacing: float,
    offset: float,
    ct: np.ndarray,
    st: np.ndarray,
    R: float,
    h: float,
    pitch: float,
    nx: int,
    ny: int,
    g: np.ndarray,
    gp: np.ndarray,
) -> None:  # noqa: E501  # pragma: no cover - jit
    n_rays, n_nodes = g.shape
    # the nodes' offsets from the first pass, the same products every ray: AVX2 has no vector
    # conversion of int64 to float, so forming them in the loop took four scalar ones a step
    along = np.empty(n_nodes)
    for j in range(n_nodes):
        along[j] = (j - offset) * spacing
    for i in range(n_rays):
        c = ct[i]
        s = st[i]
        for j in range(n_nodes):
            r = first[i] - along[j]
            f, fx, fy = _lens_point(r * c, r * s, R, h, pitch, nx, ny)
            g[i, j] = f
            gp[i, j] = fx * c + fy * s


def _lens_array_args(
    *, radius_um: float, sag_um: float, pitch_um: float, count_x: int, count_y: int
) -> tuple[float, float, float, int, int]:
    """The kernels' arguments (R, h, pitch, nx, ny) of :func:`lens_array`'s parameters."""
    if not 0.0 < sag_um < radius_um:
        raise ValueError(f"lens_array needs 0 < sag_um < radius_um, got {sag_um}, {radius_um}")
    return float(radius_um), float(sag_um), float(pitch_um), int(count_x), int(count_y)


lens_array_lines = line_evaluator(
    _lens_array_lines_kernel,
    _lens_array_args,
    """:func:`lens_array` on the radial sections of a path grid (:func:`evaluate_lines`):
    height g [µm] and radial slope g' [-], (R, n_nodes), in one pass (model §7 ``lens_array``).""",
)


def lens_array_gradient_bound(*, radius_um: float, sag_um: float, **_: float) -> float:
    """Upper bound of |∇f| for :func:`lens_array` [-]: the slope at the sphere/torus seam r = a."""
    a = math.sqrt(2.0 * sag_um * radius_um - sag_um**2)
    return a / math.sqrt(radius_um**2 - a**2)


def lens_array_curvature_bound(*, radius_um: float, sag_um: float, **_: float) -> float:
    """Bound of ‖∇²f‖ for :func:`lens_array` [1/µm] (model §7). Around each lenslet the surface
    is one of revolution in r, with principal second derivatives f'' (radial) and f'/r
    (circumferential). Sphere (r ≤ a): f'' = R²/(R² − r²)^1.5 ≥ f'/r, largest at r = a. Torus
    (a < r ≤ Rt, tube rt = R/2, Rt − a = a·rt/R): |f''| = rt²/(rt² − (r − Rt)²)^1.5, largest
    at r = a, and f'/r below the sphere's. Plane: 0. The bound is the larger of the two."""
    r, h = radius_um, sag_um
    a = math.sqrt(2.0 * h * r - h * h)
    rt = 0.5 * r
    u = a * rt / r
    return max(r * r / (r * r - a * a) ** 1.5, rt * rt / (rt * rt - u * u) ** 1.5)


@surface_family(
    "lens_array",
    {
        "radius_um": Param(float, _um("radius R of the spherical lenslets"), positive=True),
        "sag_um": Param(float, _um("sag of a lenslet"), positive=True),
        "pitch_um": Param(float, _um("lenslet pitch of the square grid"), positive=True),
        "count_x": Param(int, "lenslets along x", positive=True),
        "count_y": Param(int, "lenslets along y", positive=True),
    },
    gradient_bound=lens_array_gradient_bound,
    curvature_bound=lens_array_curvature_bound,
    lines=lens_array_lines,
)
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
    """Square array of spherical lenslets blended by tori, model §7 ``lens_array``.

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
    args = _lens_array_args(
        radius_um=radius_um, sag_um=sag_um, pitch_um=pitch_um, count_x=count_x, count_y=count_y
    )
    return evaluate_flat(_lens_array_kernel, x, y, *args)


# --------------------------------------------------------------------------- sinusoidal_mesh
@njit(nogil=True, cache=True)
def _sinusoidal_mesh_kernel(
    x: np.ndarray,
    y: np.ndarray,
    a1: float,
    a2: float,
    l_circ: float,
    k_rad: float,
    f: np.ndarray,
    fx: np.ndarray,
    fy: np.ndarray,
) -> None:  # pragma: no cover - jit
    for p in range(x.size):
        r = math.sqrt(x[p] * x[p] + y[p] * y[p])
        phi = math.atan2(y[p], x[p])
        s1 = math.sin(l_circ * phi - 0.5 * math.pi)
        c1 = math.cos(l_circ * phi - 0.5 * math.pi)
        s2 = math.sin(k_rad * r)
        c2 = math.cos(k_rad * r)
        f[p] = a1 * r * (s1 - 1.0) + a2 * r * (s2 - 1.0)
        dfdr = a1 * (s1 - 1.0) + a2 * (s2 - 1.0 + k_rad * r * c2)
        # (1/r)·∂f/∂φ stays finite at r = 0: the r factor cancels
        dfdphi_r = a1 * l_circ * c1
        if r > 0.0:
            c, s = x[p] / r, y[p] / r
        else:
            c, s = 1.0, 0.0
        fx[p] = dfdr * c - dfdphi_r * s
        fy[p] = dfdr * s + dfdphi_r * c


@surface_family(
    "sinusoidal_mesh",
    {
        "h1_um": Param(float, _um("umbrella height h1")),
        "h2_um": Param(float, _um("sinusoid amplitude h2")),
        "periods_circumferential": Param(float, "periods l around the axis", positive=True),
        "radial_wavelength_um": Param(float, _um("radial wavelength ω"), positive=True),
        "workpiece_radius_um": Param(float, _um("workpiece radius"), positive=True),
    },
)
def sinusoidal_mesh(
    x: np.ndarray,
    y: np.ndarray,
    *,
    h1_um: float,
    h2_um: float,
    periods_circumferential: float,
    radial_wavelength_um: float,
    workpiece_radius_um: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Umbrella plus radial sinusoid "complex sinusoidal mesh" surface ([4], eq. 6):

    f = (h1/Rw)·r·(sin(l·φ − π/2) − 1) + (h2/Rw)·r·(sin(2π·r/ω) − 1)

    with l the complete periods around the part and ω the radial wavelength. The printed
    eq. 6 is garbled (it puts φ in both sines and 2πRw/l before the first); this reading is
    the one the seed's own numbers support: with ω = 32/15 mm, Rw = 8 mm and h1 = h2 =
    h_max/4 both sines reach −1 together at the rim (8/ω = 3.75 periods), so the part is
    exactly h_max = 0.2 mm deep there, and its curvature gives the residual-budget feed of
    the seed's Table 1 (see README). Each term lies within [−2h·r/Rw, 0]. Lengths in µm;
    f ≤ 0 everywhere. The gradient is discontinuous at r = 0 (an umbrella's apex), as the
    published surface.
    """
    return evaluate_flat(
        _sinusoidal_mesh_kernel,
        x,
        y,
        h1_um / workpiece_radius_um,
        h2_um / workpiece_radius_um,
        float(periods_circumferential),
        2.0 * math.pi / radial_wavelength_um,
    )


# --------------------------------------------------------------------------- cylinder array
@njit(nogil=True, cache=True)
def _cylinder_array_kernel(
    x: np.ndarray,
    y: np.ndarray,
    pitch: float,
    radius: float,
    count: int,
    ca: float,
    sa: float,
    f: np.ndarray,
    fx: np.ndarray,
    fy: np.ndarray,
) -> None:  # pragma: no cover - jit
    r_abs = abs(radius)
    sense = 1.0 if radius > 0.0 else -1.0
    for p in range(x.size):
        # across the cylinders' axes, measured from the array's centre
        u = x[p] * ca + y[p] * sa
        # the cylinder's number as a float (np.floor: no int round trip, see trig.sincos)
        k = min(max(np.floor(u / pitch + 0.5 * count), 0.0), count - 1.0)
        xi = u - (k + 0.5 - 0.5 * count) * pitch
        root = math.sqrt(r_abs * r_abs - xi * xi) if xi * xi < r_abs * r_abs else math.nan
        f[p] = sense * (r_abs - root)
        g = sense * xi / root
        fx[p] = g * ca
        fy[p] = g * sa


def _check_cylinders(params: dict[str, Any]) -> None:
    if params["radius_um"] == 0.0:
        raise ValueError("radius_um must be non-zero (positive: concave, negative: convex)")
    if not 0.5 * params["pitch_um"] < abs(params["radius_um"]):
        raise ValueError("a cylinder must be wider than its pitch: |radius_um| > pitch_um / 2")
    if params["count"] < 1:
        raise ValueError(f"count must be at least 1, got {params['count']}")


def cylinder_array_gradient_bound(*, pitch_um: float, radius_um: float, **_: Any) -> float:
    """|∇f| of :func:`cylinder_array` inside the array [-]: the slope at a cylinder's edge."""
    half = 0.5 * pitch_um
    return half / math.sqrt(radius_um * radius_um - half * half)


@surface_family(
    "cylinder_array",
    {
        "pitch_um": Param(float, _um("width of each cylinder across its axis"), positive=True),
        "radius_um": Param(float, _um("radius of each cylinder; positive: concave, negative: convex")),
        "count": Param(int, "number of cylinders, centred on the origin"),
        "axis_deg": Param(float, "direction of the cylinders' axes from +x [deg]", 90.0),
    },
    gradient_bound=cylinder_array_gradient_bound,
    check=_check_cylinders,
)
def cylinder_array(
    x: np.ndarray,
    y: np.ndarray,
    *,
    pitch_um: float,
    radius_um: float,
    count: int,
    axis_deg: float = 90.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An integral mirror of ``count`` cylindrical facets side by side ([5] §3, fig. 6b):
    with u the coordinate across the axes (direction axis_deg − 90°) and ξ = u − u_k its
    offset from the nearest facet's centre line u_k = (k + ½ − count/2)·pitch,
    f = sign(R)·(|R| − sqrt(R² − ξ²)). Facets meet in straight ridges (slope jumps) along the
    axes; beyond the array the outer facets continue. Lengths in µm."""
    _check_cylinders({"pitch_um": pitch_um, "radius_um": radius_um, "count": count})
    across = math.radians(axis_deg - 90.0)
    return evaluate_flat(
        _cylinder_array_kernel,
        x,
        y,
        float(pitch_um),
        float(radius_um),
        int(count),
        math.cos(across),
        math.sin(across),
    )
