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


# --------------------------------------------------------------------------- chebyshev_freeform
@njit(nogil=True, cache=True)
def _chebyshev_kernel(x, y, curv, coef, lx, ly, xb, yb, f, fx, fy):  # pragma: no cover - jit
    ni, nj = coef.shape
    tx = np.empty(max(ni, 2))
    dtx = np.empty(max(ni, 2))
    ty = np.empty(max(nj, 2))
    dty = np.empty(max(nj, 2))
    for p in range(x.size):
        xs = x[p] - xb
        ys = y[p] - yb
        r2 = xs * xs + ys * ys
        root = math.sqrt(max(1.0 - curv * curv * r2, 0.0))
        f[p] = curv * r2 / (1.0 + root)
        # d/dr of the sphere is c·r/sqrt(1 − c²r²): split along x and y
        g = curv / root if root > 0.0 else 0.0
        fx[p] = g * xs
        fy[p] = g * ys
        u = xs / lx
        v = ys / ly
        # T_n by recurrence (valid beyond |u| ≤ 1 too); T_n' = n·U_{n−1}
        tx[0] = 1.0
        tx[1] = u
        dtx[0] = 0.0
        dtx[1] = 1.0
        ua, ub = 1.0, 2.0 * u  # U_0, U_1
        for n in range(2, ni):
            tx[n] = 2.0 * u * tx[n - 1] - tx[n - 2]
            dtx[n] = n * ub
            ua, ub = ub, 2.0 * u * ub - ua
        ty[0] = 1.0
        ty[1] = v
        dty[0] = 0.0
        dty[1] = 1.0
        va, vb = 1.0, 2.0 * v
        for n in range(2, nj):
            ty[n] = 2.0 * v * ty[n - 1] - ty[n - 2]
            dty[n] = n * vb
            va, vb = vb, 2.0 * v * vb - va
        for i in range(ni):
            for j in range(nj):
                c = coef[i, j]
                if c != 0.0:
                    f[p] += c * tx[i] * ty[j]
                    fx[p] += c * dtx[i] * ty[j] / lx
                    fy[p] += c * tx[i] * dty[j] / ly


def chebyshev_freeform(
    x: np.ndarray,
    y: np.ndarray,
    *,
    base_radius_um: float,
    coefficients_um: list[list[float]],
    norm_x_um: float,
    norm_y_um: float,
    offset_x_um: float = 0.0,
    offset_y_um: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Base sphere plus Chebyshev terms (seed 001, eq. 1):

    f = c·(Xs² + Ys²)/(1 + sqrt(1 − c²(Xs² + Ys²))) + Σ_ij C_ij·T_i(Xs/Lx)·T_j(Ys/Ly),
    with (Xs, Ys) = (x − Xb, y − Yb), c = 1/R and T_i(u) = cos(i·arccos u).

    Parameters
    ----------
    base_radius_um : R of the base sphere [µm]; 0 for no sphere (negative: concave).
    coefficients_um : C_ij [µm] as rows i (x order) of columns j (y order).
    norm_x_um, norm_y_um : Lx, Ly [µm].
    offset_x_um, offset_y_um : the off-axis offset (Xb, Yb) [µm].
    """
    shape, xf, yf = _flat_pair(x, y)
    coef = np.atleast_2d(np.asarray(coefficients_um, dtype=np.float64))
    curv = 0.0 if base_radius_um == 0 else 1.0 / base_radius_um
    f, fx, fy = np.empty_like(xf), np.empty_like(xf), np.empty_like(xf)
    _chebyshev_kernel(
        xf,
        yf,
        curv,
        coef,
        float(norm_x_um),
        float(norm_y_um),
        float(offset_x_um),
        float(offset_y_um),
        f,
        fx,
        fy,
    )
    return f.reshape(shape), fx.reshape(shape), fy.reshape(shape)


# --------------------------------------------------------------------------- sinusoidal_mesh
@njit(nogil=True, cache=True)
def _sinusoidal_mesh_kernel(x, y, a1, a2, l_circ, k_rad, f, fx, fy):  # pragma: no cover - jit
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


def sinusoidal_mesh(
    x: np.ndarray,
    y: np.ndarray,
    *,
    h1_um: float,
    h2_um: float,
    periods_circumferential: float,
    periods_radial: float,
    workpiece_radius_um: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Umbrella plus radial sinusoid "complex sinusoidal mesh" surface (seed 003, eq. 6):

    f = (h1/Rw)·r·(sin(l·φ − π/2) − 1) + (h2/Rw)·r·(sin(2π·ω·r/Rw) − 1)

    with l the complete periods around the part and ω those along its radius, as the seed's
    text defines them (its printed eq. 6 garbles both arguments: read literally it would not
    close over 360°). Each term lies within [−2h·r/Rw, 0], so the depth stays within
    2(h1 + h2), the seed's h_max = 0.2 mm for h1 = h2 = h_max/4 (with ω = 32/15 the deepest
    point reached is about 164 µm, near r = 0.82·Rw). Lengths in µm; f ≤ 0 everywhere.
    The gradient is discontinuous at r = 0 (an umbrella's apex), as the published surface.
    """
    shape, xf, yf = _flat_pair(x, y)
    f, fx, fy = np.empty_like(xf), np.empty_like(xf), np.empty_like(xf)
    _sinusoidal_mesh_kernel(
        xf,
        yf,
        h1_um / workpiece_radius_um,
        h2_um / workpiece_radius_um,
        float(periods_circumferential),
        2.0 * math.pi * periods_radial / workpiece_radius_um,
        f,
        fx,
        fy,
    )
    return f.reshape(shape), fx.reshape(shape), fy.reshape(shape)


# --------------------------------------------------------------------------- zernike
def noll_to_nm(j: int) -> tuple[int, int]:
    """Radial order n and signed azimuthal frequency m of Noll index j ≥ 1 (Noll 1976):
    even j carry cos(mφ) (m > 0), odd j sin(mφ) (m < 0 here), m = 0 for rotational terms."""
    if j < 1:
        raise ValueError(f"Noll indices start at 1, got {j}")
    n = 0
    while (n + 1) * (n + 2) // 2 < j:
        n += 1
    k = j - n * (n + 1) // 2 - 1  # position within the order, 0..n
    ms = [m for m in range(n % 2, n + 1, 2) for _ in ((0,) if m == 0 else (0, 1))]
    m = ms[k]
    if m == 0:
        return n, 0
    return n, (m if j % 2 == 0 else -m)


def _radial_coefficients(n: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients and powers of the Zernike radial polynomial R_n^|m|(ρ)."""
    m = abs(m)
    coef, power = [], []
    for s in range((n - m) // 2 + 1):
        coef.append(
            (-1) ** s
            * math.factorial(n - s)
            / (math.factorial(s) * math.factorial((n + m) // 2 - s) * math.factorial((n - m) // 2 - s))
        )
        power.append(n - 2 * s)
    return np.array(coef), np.array(power, dtype=np.int64)


@njit(nogil=True, cache=True)
def _zernike_kernel(
    x, y, curv, conic, rn, amp, ms, norms, rc, rp, offsets, f, fx, fy
):  # pragma: no cover - jit
    for p in range(x.size):
        r2 = x[p] * x[p] + y[p] * y[p]
        r = math.sqrt(r2)
        root = math.sqrt(max(1.0 - (1.0 + conic) * curv * curv * r2, 0.0))
        f[p] = curv * r2 / (1.0 + root)
        g = curv / root if root > 0.0 else 0.0  # d/dr of the conic is c·r/sqrt(1 − (1+k)c²r²)
        fx[p] = g * x[p]
        fy[p] = g * y[p]
        u = r / rn
        if r > 0.0:
            c, s = x[p] / r, y[p] / r
        else:
            c, s = 1.0, 0.0
        phi = math.atan2(y[p], x[p])
        for t in range(amp.size):
            m = ms[t]
            mm = abs(m)
            rad = 0.0
            drad = 0.0
            rad_over_u = 0.0  # R(u)/u, finite because every power is ≥ |m| ≥ 1 when needed
            for q in range(offsets[t], offsets[t + 1]):
                pw = rp[q]
                rad += rc[q] * u**pw
                if pw > 0:
                    drad += rc[q] * pw * u ** (pw - 1)
                    rad_over_u += rc[q] * u ** (pw - 1)
            if m == 0:
                ang, dang = 1.0, 0.0
            elif m > 0:
                ang, dang = math.cos(mm * phi), -mm * math.sin(mm * phi)
            else:
                ang, dang = math.sin(mm * phi), mm * math.cos(mm * phi)
            a = amp[t] * norms[t]
            f[p] += a * rad * ang
            # ∂/∂x = cosφ·∂/∂r − sinφ/r·∂/∂φ, with ∂/∂r = (1/rn)·d/du
            fx[p] += a / rn * (drad * ang * c - rad_over_u * dang * s)
            fy[p] += a / rn * (drad * ang * s + rad_over_u * dang * c)


def zernike(
    x: np.ndarray,
    y: np.ndarray,
    *,
    norm_radius_um: float,
    terms_um: dict[int, float],
    base_radius_um: float = 0.0,
    conic: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Conic base plus Noll-indexed Zernike terms over a normalisation radius:

    f = c·r²/(1 + sqrt(1 − (1+k)·c²·r²)) + Σ_j a_j·Z_j(r/r_n, φ),
    Z_j = N_nm·R_n^|m|(ρ)·{cos(mφ) (even j), sin(|m|φ) (odd j), 1 (m = 0)},
    N_nm = sqrt(n+1) for m = 0, sqrt(2(n+1)) otherwise (Noll's RMS normalisation).

    Parameters
    ----------
    norm_radius_um : r_n [µm]; the polynomials are evaluated beyond it too.
    terms_um : {Noll index j: coefficient a_j [µm]}.
    base_radius_um : 1/c of the conic base [µm] (0: none); conic : k.
    """
    shape, xf, yf = _flat_pair(x, y)
    js = sorted(int(j) for j in terms_um)
    amp = np.array([float(terms_um[j]) for j in js])
    nms = [noll_to_nm(j) for j in js]
    ms = np.array([m for _, m in nms], dtype=np.int64)
    norms = np.array([math.sqrt(n + 1.0) * (1.0 if m == 0 else math.sqrt(2.0)) for n, m in nms])
    polys = [_radial_coefficients(n, m) for n, m in nms]
    offsets = np.cumsum([0] + [c.size for c, _ in polys]).astype(np.int64)
    rc = np.concatenate([c for c, _ in polys]) if polys else np.zeros(0)
    rp = np.concatenate([pw for _, pw in polys]) if polys else np.zeros(0, dtype=np.int64)
    curv = 0.0 if base_radius_um == 0 else 1.0 / base_radius_um
    f, fx, fy = np.empty_like(xf), np.empty_like(xf), np.empty_like(xf)
    _zernike_kernel(
        xf, yf, curv, float(conic), float(norm_radius_um), amp, ms, norms, rc, rp, offsets, f, fx, fy
    )
    return f.reshape(shape), fx.reshape(shape), fy.reshape(shape)


@njit(nogil=True, cache=True, inline="always")
def _span(t, k, u):  # pragma: no cover - jit
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
def _cubic_basis(t, span, u, n, dn, left, right, b):  # pragma: no cover - jit
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
def _bspline2d_kernel(x, y, tx, ty, coef, f, fx, fy):  # pragma: no cover - jit
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
    shape, xf, yf = _flat_pair(x, y)
    f, fx, fy = np.empty_like(xf), np.empty_like(xf), np.empty_like(xf)
    _bspline2d_kernel(
        xf,
        yf,
        np.ascontiguousarray(knots_x, dtype=np.float64),
        np.ascontiguousarray(knots_y, dtype=np.float64),
        np.ascontiguousarray(coefficients, dtype=np.float64),
        f,
        fx,
        fy,
    )
    return f.reshape(shape), fx.reshape(shape), fy.reshape(shape)


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


# --------------------------------------------------------------------------- registry
class Family(NamedTuple):
    """A surface family: its evaluator and an analytic bound of its gradient magnitude (None:
    the bound is estimated by sampling the aperture, see :func:`sampled_gradient_bound`)."""

    evaluate: Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray]]
    gradient_bound: Callable[..., float] | None


FAMILIES: dict[str, Family] = {
    "sinewave2d": Family(sinewave2d, sinewave2d_gradient_bound),
    "lens_array": Family(lens_array, lens_array_gradient_bound),
    "chebyshev_freeform": Family(chebyshev_freeform, None),
    "sinusoidal_mesh": Family(sinusoidal_mesh, None),
    "zernike": Family(zernike, None),
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
