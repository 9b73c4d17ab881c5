"""Tool-nose radius compensation: what the table must store (model §4).

The cutting edge is a circular arc of nose radius Rc in the feed plane. The exact control
value is the height of the arc's lowest point such that the arc touches the radial section
g(r) = f(r cosθ, r sinθ) from above:

    w(ρ, θ) = max over |s| < Rc of [ g(ρ + s) − (Rc − sqrt(Rc² − s²)) ]            (§4)

Two solvers implement it:

* :func:`compensate` works on arbitrary points with a surface callable (control tables).
  With G ≥ |g'| on the section, every stationary point of the bracket lies in
  |s| ≤ Rc·G/sqrt(1 + G²). Where the surface's curvature bound K satisfies K·Rc < 1,
  h(s) is strictly concave there and a safeguarded secant (Newton) iteration from the
  slope-predicted contact finds its maximum in a few evaluations; elsewhere a scan of the
  window, dense enough for 0.01 nm when K is known, is refined by a bracketed (Illinois)
  root search.
* :func:`compensate_on_ray` works on a section already sampled on a uniform grid (the
  tool path's evaluation grid) by hill-climbing the sampled h and a parabolic refinement.

Modes: ``exact`` (above), ``slope`` (w = f + Rc·(1/cosβ − 1), β = atan|g'|, the literature
approximation) and ``none`` (w = f).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from ftsweep.stages.numerics.trig import cos_sin
from ftsweep.stages.sampling.surfaces import SurfaceFn, radial_section

MODES = ("exact", "slope", "none")
MODE_CODES = {"exact": 0, "slope": 1, "none": 2}


def arc_lift(s: np.ndarray | float, nose_radius_um: float) -> np.ndarray | float:
    """Height [µm] of the tool arc above its lowest point at lateral offset ``s`` [µm]:
    Rc − sqrt(Rc² − s²) (model §4, §5)."""
    return nose_radius_um - np.sqrt(nose_radius_um**2 - np.square(s))


def contact_window_um(gradient_bound: float, nose_radius_um: float) -> float:
    """Half-width [µm] of the offsets |s| where the arc can touch a section whose slope is
    bounded by ``gradient_bound`` [-]: Rc·G/sqrt(1 + G²) (where the arc's slope equals G)."""
    g = abs(gradient_bound)
    return min(nose_radius_um * g / math.sqrt(1.0 + g * g), 0.999 * nose_radius_um)


def slope_compensation(f: np.ndarray, slope: np.ndarray, nose_radius_um: float) -> np.ndarray:
    """Approximate compensation w = f + Rc·(1/cosβ − 1), β = atan|g'| (model §4) [µm]."""
    return f + nose_radius_um * (np.sqrt(1.0 + np.square(slope)) - 1.0)


# Largest amount [µm] by which the scan solver's result may fall below the true maximum of
# eq. (3) when the surface's curvature is bounded: 1e-5 µm = 0.01 nm, far below any metric.
SCAN_TOL_UM = 1e-5
MAX_SCAN = 4097
SOLVERS = ("auto", "newton", "scan")


def _check_arguments(mode: str, solver: str, nose_radius_um: float) -> None:
    if mode not in MODES:
        raise ValueError(f"unknown compensation mode {mode!r}; expected one of {MODES}")
    if solver not in SOLVERS:
        raise ValueError(f"unknown compensation solver {solver!r}; expected one of {SOLVERS}")
    if not nose_radius_um > 0.0:
        raise ValueError(f"nose_radius_um must be positive, got {nose_radius_um!r}")


def compensate(
    surface: SurfaceFn,
    rho: np.ndarray,
    theta: np.ndarray,
    nose_radius_um: float,
    mode: str = "exact",
    gradient_bound: float = 0.0,
    n_scan: int = 5,
    tol_um: float = 1e-4,
    max_iter: int = 60,
    curvature_bound: float = math.inf,
    solver: str = "auto",
) -> tuple[np.ndarray, np.ndarray]:
    """Control values w [µm] at radial positions ``rho`` [µm] on sections at ``theta`` [rad].

    Parameters
    ----------
    surface : surface callable (see :mod:`ftsweep.stages.sampling.surfaces`).
    rho, theta : arrays of equal shape: radial position and section angle of each point.
    nose_radius_um : tool nose radius Rc [µm].
    mode : ``exact``, ``slope`` or ``none`` (model §4, eq. 3 and 4).
    gradient_bound : an upper bound G of |∇f| [-] over the part (``exact`` only); a section
        found steeper raises, since the contact window would be too narrow.
    n_scan : samples of the coarse scan when the curvature is not bounded (``exact`` only).
    tol_um : convergence tolerance on the contact offset [µm]; near the optimum h is
        quadratic, so an offset error δ changes w by only ½·|h''|·δ² (~1e-10 µm at 1e-4).
    curvature_bound : an upper bound K [1/µm] of the Hessian's spectral norm ‖∇²f‖ over the
        part (inf: unknown). It bounds every section's g'' in both directions.
    solver : ``newton``: safeguarded secant (Newton) iteration on h'(s) = 0 from the
        slope-predicted contact, a few surface evaluations per point, exact where h is
        strictly concave (K·Rc < 1); ``scan``: a scan of the contact window refined by a
        bracketed root search, dense enough for a 0.01 nm guarantee when K is known (see
        :func:`scan_samples`); ``auto``: ``newton`` when K·Rc < 1, else ``scan``.

    Returns
    -------
    w : control values [µm], shape of ``rho``.
    gouge : bool array, True where the section within the contact window is concave with
        a radius of curvature below Rc, so no single contact exists (§4). With K·Rc < 1 no
        section can be, and none is flagged.
    """
    _check_arguments(mode, solver, nose_radius_um)
    rho, theta = np.broadcast_arrays(np.asarray(rho, dtype=np.float64), np.asarray(theta, dtype=np.float64))
    shape = rho.shape
    rho, theta = (np.ascontiguousarray(a).reshape(-1) for a in (rho, theta))
    ct, st = cos_sin(theta)
    if mode != "exact":
        f, gp = radial_section(surface, rho, ct, st)
        w = f if mode == "none" else slope_compensation(f, gp, nose_radius_um)
        return w.reshape(shape), np.zeros(shape, dtype=bool)

    rc = float(nose_radius_um)
    half = contact_window_um(gradient_bound, rc)
    newton = solver == "newton" or (solver == "auto" and curvature_bound * rc < 1.0)
    if newton and half > 0.0:
        w = _secant_max(surface, rho, ct, st, rc, half, (gradient_bound, curvature_bound), tol_um, max_iter)
        return w.reshape(shape), np.zeros(shape, dtype=bool)
    count = scan_samples(half, rc, curvature_bound, n_scan)
    w, gouge = _scan_max(surface, rho, ct, st, rc, half, count, gradient_bound, tol_um, max_iter)
    return w.reshape(shape), gouge.reshape(shape)


def scan_samples(half_um: float, nose_radius_um: float, curvature_bound: float, n_scan: int) -> int:
    """Samples of the scan over the contact window |s| ≤ half [µm].

    Between samples δ apart, h(s) = g(ρ+s) − arc(s) exceeds the larger sample by at most
    L·δ²/8 with L ≥ −h'' = arc''(s) − g''(ρ+s) ≤ Rc²/(Rc² − half²)^1.5 + K. With K known the
    scan is made dense enough for L·δ²/8 ≤ :data:`SCAN_TOL_UM` (at most :data:`MAX_SCAN`
    samples), so the refined best sample is within 0.01 nm of eq. (3) even where the section
    has several local maxima (gouging, K·Rc ≥ 1). Where K·Rc < 1, h is strictly concave and
    the bracket around the best of ``n_scan`` samples holds its one maximum; with K unknown,
    ``n_scan`` samples too (the pre-bound behaviour).
    """
    if half_um <= 0.0:
        return 1
    if not math.isfinite(curvature_bound) or curvature_bound * nose_radius_um < 1.0:
        # unknown K, or h strictly concave: the coarse scan brackets its one maximum
        return max(3, n_scan)
    rc = nose_radius_um
    lipschitz = rc * rc / (rc * rc - half_um * half_um) ** 1.5 + curvature_bound
    step = math.sqrt(8.0 * SCAN_TOL_UM / lipschitz)
    return int(min(MAX_SCAN, max(n_scan, 3, math.ceil(2.0 * half_um / step) + 1)))


def _check_slope(gp: np.ndarray, gradient_bound: float) -> None:
    """Refuse radial slopes ``gp`` steeper than the gradient bound (see :func:`_check_steepest`)."""
    _check_steepest(float(np.max(np.abs(gp))) if gp.size else 0.0, gradient_bound)


def _secant_max(
    surface: SurfaceFn,
    rho: np.ndarray,
    ct: np.ndarray,
    st: np.ndarray,
    rc: float,
    half: float,
    bounds: tuple[Any, ...],
    tol_um: float,
    max_iter: int,
) -> np.ndarray:
    """Maximise h(s) = g(ρ+s) − arc(s) over |s| ≤ half where h is strictly concave: the root
    of the decreasing h'(s) = g'(ρ+s) − s/sqrt(Rc² − s²) by secant steps, bracketed by
    [−half, half] (where h' ≥ 0 ≥ h' because |g'| ≤ G) and bisected when a step leaves the
    bracket. Starts at s = 0 and the slope-predicted contact Rc·g'/sqrt(1 + g'²). The surface
    is evaluated once per iteration on the points still moving, at the places the previous
    kernel pass left in (x, y); the rest of an iteration is one pass of
    :func:`_secant_update` (numpy temporaries between them cost as much as the update)."""
    gradient_bound, curvature_bound = bounds
    f0, fx0, fy0 = surface(rho * ct, rho * st)
    n = rho.size
    best = np.empty(n)
    idx = np.empty(n, dtype=np.int64)
    s, s_prev, d_prev, gp_prev, a, b = (np.empty(n) for _ in range(6))
    x, y = np.empty(n), np.empty(n)
    state = (idx, s, s_prev, d_prev, gp_prev, a, b)
    n, steepest = _secant_start(f0, fx0, fy0, rho, ct, st, rc, half, best, *state, x, y)
    _check_steepest(steepest, gradient_bound)
    for _ in range(max_iter):
        if n == 0:
            break
        f, fx, fy = surface(x[:n], y[:n])
        n, worst, steepest = _secant_update(
            f, fx, fy, rho, ct, st, rc, tol_um, curvature_bound, state, best, x, y
        )
        _check_steepest(steepest, gradient_bound)
        if worst > 0.0:
            raise ValueError(
                f"surface curvature {worst:.4g} /µm exceeds the curvature bound {curvature_bound:.4g} "
                "/µm given to exact compensation; raise or remove the bound"
            )
    return best


def _check_steepest(steepest: float, gradient_bound: float) -> None:
    """Refuse a largest radial slope |g'| [-] above the gradient bound G given to exact
    compensation: the contact window, sized by G, would miss contacts."""
    if steepest > gradient_bound * (1.0 + 1e-9) + 1e-12:
        raise ValueError(
            f"surface slope {steepest:.4g} exceeds the gradient bound {gradient_bound:.4g} given to "
            "exact compensation; raise the bound (the contact window would miss contacts)"
        )


@njit(nogil=True, cache=True)
def _secant_start(
    f0: np.ndarray,
    fx0: np.ndarray,
    fy0: np.ndarray,
    rho: np.ndarray,
    ct: np.ndarray,
    st: np.ndarray,
    rc: float,
    half: float,
    best: np.ndarray,
    idx: np.ndarray,
    s: np.ndarray,
    s_prev: np.ndarray,
    d_prev: np.ndarray,
    gp_prev: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
) -> tuple[Any, ...]:  # noqa: E501  # pragma: no cover - jit
    """The state of :func:`_secant_max` after its evaluation at s = 0 (heights ``f0`` and
    gradients at ρ on sections (ct, st)): h(0) in ``best``; the points whose slope g' is not
    0 packed to the front of the state arrays with their bracket, h'(0) = g', the
    slope-predicted contact s and its place (x, y) [µm] at ρ + s. Returns their number and
    the largest |g'| (NaN ignored)."""
    n = 0
    steepest = 0.0
    for p in range(f0.size):
        g = fx0[p] * ct[p] + fy0[p] * st[p]
        steepest = max(steepest, abs(g))
        best[p] = f0[p]
        if g != 0.0:
            ap = 0.0 if g > 0.0 else -half
            bp = half if g > 0.0 else 0.0
            idx[n] = p
            a[n] = ap
            b[n] = bp
            s_prev[n] = 0.0
            d_prev[n] = g
            gp_prev[n] = g
            s[n] = min(max(rc * g / math.sqrt(1.0 + g * g), ap), bp)
            _place(rho, ct, st, p, s[n], n, x, y)
            n += 1
    return n, steepest


@njit(nogil=True, cache=True, inline="always")
def _place(
    rho: np.ndarray, ct: np.ndarray, st: np.ndarray, p: int, s: float, i: int, x: np.ndarray, y: np.ndarray
) -> None:  # pragma: no cover - jit
    """x[i], y[i] [µm]: point ``p`` moved by s [µm] along its section (as radial_section)."""
    r = rho[p] + s
    x[i] = r * ct[p]
    y[i] = r * st[p]


@njit(nogil=True, cache=True)
def _secant_update(
    f: np.ndarray,
    fx: np.ndarray,
    fy: np.ndarray,
    rho: np.ndarray,
    ct: np.ndarray,
    st: np.ndarray,
    rc: float,
    tol_um: float,
    curvature_bound: float,
    state: tuple[np.ndarray, ...],
    best: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
) -> tuple[Any, ...]:  # pragma: no cover - jit
    """One secant iteration of :func:`_secant_max` on its ``f.size`` active points, in place:
    forms each point's radial slope g' from the gradient (fx, fy) on its section, records h
    at s in ``best``, moves s, and packs the points still moving to the front of the state
    arrays, with their next place (x, y) [µm]. Returns their number, the largest difference
    quotient |Δg'/Δs| found above the curvature bound K (0 when none: by the mean value
    theorem it is at most sup|g''| ≤ K, so a larger one proves the declared bound, and the
    concavity the solver relies on, wrong), and the largest |g'| (for the gradient bound's
    check)."""
    idx, s, s_prev, d_prev, gp_prev, a, b = state
    n_keep = 0
    worst = 0.0
    steepest = 0.0
    for i in range(f.size):
        p = idx[i]
        gpi = fx[i] * ct[p] + fy[i] * st[p]
        steepest = max(steepest, abs(gpi))
        si, ds = s[i], s[i] - s_prev[i]
        change = abs(gpi - gp_prev[i])
        # rounding of g' (~1e-16) divided by a small step must not read as curvature
        if change - 1e-12 > curvature_bound * (1.0 + 1e-6) * abs(ds):
            worst = max(worst, change / abs(ds) if ds != 0.0 else math.inf)
        root = math.sqrt(rc * rc - si * si)
        h = f[i] - (rc - root)
        if h > best[p] or h != h:
            best[p] = h
        d = gpi - si / root
        ai = si if d > 0.0 else a[i]
        bi = si if d < 0.0 else b[i]
        step = d * ds / (d - d_prev[i]) if d != d_prev[i] else math.nan
        s_new = si - step
        inside = math.isfinite(s_new) and ai < s_new < bi
        # a secant step below tol means s is within ~tol of the contact: w is then off by at
        # most ½·|h''|·tol² (~1e-10 µm), so that step is not evaluated
        done = (inside and abs(step) < tol_um) or d == 0.0 or bi - ai < tol_um
        if not done:
            idx[n_keep] = p
            s_prev[n_keep] = si
            d_prev[n_keep] = d
            gp_prev[n_keep] = gpi
            a[n_keep] = ai
            b[n_keep] = bi
            s[n_keep] = s_new if inside else 0.5 * (ai + bi)
            _place(rho, ct, st, p, s[n_keep], n_keep, x, y)
            n_keep += 1
    return n_keep, worst, steepest


def _scan_max(
    surface: SurfaceFn,
    rho: np.ndarray,
    ct: np.ndarray,
    st: np.ndarray,
    rc: float,
    half: float,
    count: int,
    gradient_bound: float,
    tol_um: float,
    max_iter: int,
) -> tuple[Any, ...]:
    """Scan-and-refine: ``count`` samples of h over |s| ≤ half, streamed so that memory stays
    O(points) however dense the scan; the bracket around the best sample is refined by
    :func:`_illinois_max` where h' changes sign in it. Also flags gouging (§4): concave
    curvature g''/(1 + g'²)^1.5 above 1/Rc between neighbouring samples."""
    offsets = np.linspace(-half, half, count) if count > 1 else np.zeros(1)
    n = rho.size
    best_h = np.full(n, -np.inf)
    best_q = np.full(n, -1, dtype=np.int64)
    dh_lo, dh_hi = np.zeros(n), np.zeros(n)
    prev_dh, prev_gp = np.zeros(n), np.zeros(n)
    gouge = np.zeros(n, dtype=bool)
    step = offsets[1] - offsets[0] if count > 1 else 0.0
    for q, s in enumerate(offsets):
        f, gp = radial_section(surface, rho + s, ct, st)
        _check_slope(gp, gradient_bound)
        h = f - arc_lift(s, rc)
        dh = gp - s / math.sqrt(rc * rc - s * s)
        if q > 0:
            mid2 = 1.0 + 0.25 * np.square(gp + prev_gp)
            gouge |= (gp - prev_gp) * rc > step * mid2 * np.sqrt(mid2)
        after_best = best_q == q - 1  # this sample is the right neighbour of the best so far
        dh_hi[after_best] = dh[after_best]
        better = h > best_h  # strict: the first of equal samples stays, as argmax would
        best_h[better] = h[better]
        best_q[better] = q
        dh_lo[better] = (prev_dh if q > 0 else dh)[better]
        dh_hi[better] = dh[better]  # stands if the best is the last sample
        prev_dh, prev_gp = dh, gp
    w = best_h
    if count == 1:
        return w, gouge
    a = offsets[np.maximum(best_q - 1, 0)]
    b = offsets[np.minimum(best_q + 1, count - 1)]
    # only a sign change of h' brackets an interior maximum; elsewhere the scan value stands
    active = np.flatnonzero((dh_lo > 0.0) & (dh_hi < 0.0))
    bracket = (a[active], b[active], dh_lo[active], dh_hi[active])
    refined = _illinois_max(surface, rho[active], ct[active], st[active], rc, *bracket, tol_um, max_iter)
    w[active] = np.maximum(w[active], refined)
    return w, gouge


def _illinois_max(
    surface: SurfaceFn,
    rho: np.ndarray,
    ct: np.ndarray,
    st: np.ndarray,
    rc: float,
    a: np.ndarray,
    b: np.ndarray,
    fa: np.ndarray,
    fb: np.ndarray,
    tol_um: float,
    max_iter: int,
) -> np.ndarray:
    """Maximise h(s) = g(ρ+s) − arc(s) on [a, b] where h'(a) > 0 > h'(b) (vectorised Illinois)."""
    best_h = np.full(rho.size, -np.inf)
    s_prev = np.full(rho.size, np.nan)
    idx = np.arange(rho.size)
    side = np.zeros(rho.size, dtype=np.int8)
    for _ in range(max_iter):
        if idx.size == 0:
            break
        s = (a * fb - b * fa) / (fb - fa)
        f, gp = radial_section(surface, rho[idx] + s, ct[idx], st[idx])
        hs = f - (rc - np.sqrt(rc * rc - s * s))
        fs = gp - s / np.sqrt(rc * rc - s * s)
        best_h[idx] = np.maximum(best_h[idx], hs)
        done = (np.abs(s - s_prev[idx]) < tol_um) | (fs == 0.0) | (np.abs(b - a) < tol_um)
        s_prev[idx] = s
        right = fs < 0.0  # root lies left of s: s becomes the new b
        # Illinois: halve the stale end's value when the same side moves twice in a row.
        new_side = np.where(right, 1, -1).astype(np.int8)
        stale = side[idx] == new_side
        fa = np.where(right & stale, 0.5 * fa, np.where(right, fa, fs))
        fb = np.where(~right & stale, 0.5 * fb, np.where(right, fs, fb))
        a = np.where(right, a, s)
        b = np.where(right, s, b)
        side[idx] = new_side
        keep = ~done
        idx, a, b, fa, fb = idx[keep], a[keep], b[keep], fa[keep], fb[keep]
    return best_h
