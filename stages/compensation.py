"""Tool-nose radius compensation: what the table must store (model §4).

The cutting edge is a circular arc of nose radius Rc in the feed plane. The exact control
value is the height of the arc's lowest point such that the arc touches the radial section
g(r) = f(r cosθ, r sinθ) from above:

    w(ρ, θ) = max over |s| < Rc of [ g(ρ + s) − (Rc − sqrt(Rc² − s²)) ]            (§4)

Two solvers implement it:

* :func:`compensate` works on arbitrary points with a surface callable (control tables).
  With G ≥ |g'| on the section, every stationary point of the bracket lies in
  |s| ≤ Rc·G/sqrt(1 + G²), so a coarse scan of that window followed by a bracketed
  (Illinois) root search of h'(s) = 0 finds the global maximum wherever h is unimodal,
  which holds wherever the section has no concave radius below Rc.
* :func:`compensate_on_ray` works on a section already sampled on a uniform grid (the
  tool path's evaluation grid) by hill-climbing the sampled h and a parabolic refinement.

Modes: ``exact`` (above), ``slope`` (w = f + Rc·(1/cosβ − 1), β = atan|g'|, the literature
approximation) and ``none`` (w = f).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .surfaces import SurfaceFn, radial_section

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
) -> tuple[np.ndarray, np.ndarray]:
    """Control values w [µm] at radial positions ``rho`` [µm] on sections at ``theta`` [rad].

    Parameters
    ----------
    surface : surface callable (see :mod:`ftsweep.stages.surfaces`).
    rho, theta : arrays of equal shape: radial position and section angle of each point.
    nose_radius_um : tool nose radius Rc [µm].
    mode : ``exact``, ``slope`` or ``none`` (model §4).
    gradient_bound : an upper bound G of |∇f| [-] over the part (``exact`` only); a scan
        that meets a larger slope raises, since the contact window would be too narrow.
    n_scan : samples of the coarse scan over the contact window (``exact`` only).
    tol_um : convergence tolerance on the contact offset [µm]; near the optimum h is
        quadratic, so an offset error δ changes w by only ½·|h''|·δ² (~1e-10 µm at 1e-4).

    Returns
    -------
    w : control values [µm], shape of ``rho``.
    gouge : bool array, True where the section within the contact window is concave with
        a radius of curvature below Rc, so no single contact exists (§4).
    """
    if mode not in MODES:
        raise ValueError(f"unknown compensation mode {mode!r}; expected one of {MODES}")
    if not nose_radius_um > 0.0:
        raise ValueError(f"nose_radius_um must be positive, got {nose_radius_um!r}")
    rho, theta = np.broadcast_arrays(np.asarray(rho, dtype=np.float64), np.asarray(theta, dtype=np.float64))
    shape = rho.shape
    rho = np.ascontiguousarray(rho).reshape(-1)
    theta = np.ascontiguousarray(theta).reshape(-1)
    ct, st = np.cos(theta), np.sin(theta)
    if mode != "exact":
        f, gp = radial_section(surface, rho, ct, st)
        w = f if mode == "none" else slope_compensation(f, gp, nose_radius_um)
        return w.reshape(shape), np.zeros(shape, dtype=bool)

    rc = float(nose_radius_um)
    half = contact_window_um(gradient_bound, rc)
    offsets = np.linspace(-half, half, max(3, n_scan)) if half > 0.0 else np.zeros(1)
    n_off, n = offsets.size, rho.size
    h = np.empty((n_off, n))
    dh = np.empty((n_off, n))
    slopes = np.empty((n_off, n))
    for q, s in enumerate(offsets):
        f, gp = radial_section(surface, rho + s, ct, st)
        h[q] = f - arc_lift(s, rc)
        dh[q] = gp - s / math.sqrt(rc * rc - s * s)
        slopes[q] = gp
    steepest = float(np.max(np.abs(slopes))) if n else 0.0
    if steepest > gradient_bound * (1.0 + 1e-9) + 1e-12:
        raise ValueError(
            f"surface slope {steepest:.4g} exceeds the gradient bound {gradient_bound:.4g} given to "
            "exact compensation; raise the bound (the contact window would miss contacts)"
        )

    gouge = np.zeros(n, dtype=bool)
    if n_off > 1:
        # concave curvature g''/(1 + g'^2)^1.5 above 1/Rc between neighbouring scan samples
        step = offsets[1] - offsets[0]
        for q in range(n_off - 1):
            mid2 = 1.0 + 0.25 * np.square(slopes[q + 1] + slopes[q])
            gouge |= (slopes[q + 1] - slopes[q]) * rc > step * mid2 * np.sqrt(mid2)

    best = np.argmax(h, axis=0)
    cols = np.arange(n)
    w = h[best, cols]
    if n_off == 1:
        return w.reshape(shape), gouge.reshape(shape)
    lo_i = np.maximum(best - 1, 0)
    hi_i = np.minimum(best + 1, n_off - 1)
    a, b = offsets[lo_i], offsets[hi_i]
    fa, fb = dh[lo_i, cols], dh[hi_i, cols]
    # Only a sign change of h' brackets an interior maximum; elsewhere the scan value stands.
    active = np.flatnonzero((fa > 0.0) & (fb < 0.0))
    refined = _illinois_max(
        surface,
        rho[active],
        ct[active],
        st[active],
        rc,
        a[active],
        b[active],
        fa[active],
        fb[active],
        tol_um,
        max_iter,
    )
    # The refined maximum can only raise w; max() guards the non-unimodal corner cases.
    w[active] = np.maximum(w[active], refined)
    return w.reshape(shape), gouge.reshape(shape)


def _illinois_max(surface, rho, ct, st, rc, a, b, fa, fb, tol_um, max_iter):
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


@njit(nogil=True, cache=True)
def compensate_on_ray(g, gp, spacing_um, nose_radius_um, nodes, mode, out):  # pragma: no cover - jit
    """Control values along one sampled radial section (model §4), in place.

    g, gp : section height [µm] and radial slope [-] at nodes r_n = r_0 − n·spacing.
    spacing_um : node spacing [µm] (positive; node index grows inwards).
    nodes : int64 node indices of the tool passes whose commands are wanted.
    mode : 0 exact, 1 slope, 2 none (see ``MODE_CODES``).
    out : float64 array receiving w [µm] for each entry of ``nodes``.

    For ``exact`` the sampled h_j = g[n+j] − arc(j·spacing) is hill-climbed from the
    slope-predicted contact and refined by the parabola through the best three samples.
    """
    rc = nose_radius_um
    n_nodes = g.size
    jmax = int(rc / spacing_um) - 1
    for p in range(nodes.size):
        n = nodes[p]
        if mode == 2:
            out[p] = g[n]
            continue
        if mode == 1:
            out[p] = g[n] + rc * (math.sqrt(1.0 + gp[n] * gp[n]) - 1.0)
            continue
        # contact offset s = rc·sinβ lies outwards (s > 0, smaller n) where g rises outwards
        s0 = rc * gp[n] / math.sqrt(1.0 + gp[n] * gp[n])
        j = int(round(-s0 / spacing_um))
        jlo = max(-jmax, -n)
        jhi = min(jmax, n_nodes - 1 - n)
        j = min(max(j, jlo), jhi)
        dj = j * spacing_um
        hj = g[n + j] - (rc - math.sqrt(rc * rc - dj * dj))
        while True:
            moved = False
            if j + 1 <= jhi:
                d = (j + 1) * spacing_um
                hn = g[n + j + 1] - (rc - math.sqrt(rc * rc - d * d))
                if hn > hj:
                    j += 1
                    hj = hn
                    moved = True
                    continue
            if j - 1 >= jlo:
                d = (j - 1) * spacing_um
                hn = g[n + j - 1] - (rc - math.sqrt(rc * rc - d * d))
                if hn > hj:
                    j -= 1
                    hj = hn
                    moved = True
            if not moved:
                break
        best = hj
        if jlo < j < jhi:
            d1 = (j + 1) * spacing_um
            d0 = (j - 1) * spacing_um
            hp = g[n + j + 1] - (rc - math.sqrt(rc * rc - d1 * d1))
            hm = g[n + j - 1] - (rc - math.sqrt(rc * rc - d0 * d0))
            curv = hm - 2.0 * hj + hp
            if curv < 0.0:
                best = hj - (hp - hm) * (hp - hm) / (8.0 * curv)
        out[p] = best


def commands_on_rays(
    g: np.ndarray,
    gp: np.ndarray,
    spacing_um: float,
    nose_radius_um: float,
    pass_nodes: np.ndarray,
    n_passes: np.ndarray,
    mode: int,
) -> np.ndarray:
    """Commands w [µm] at every pass of every ray of a path grid (model §4): the section
    samples ``g``, ``gp`` (R, G) along each ray, the passes at node indices ``pass_nodes``
    (R, Kmax), ``n_passes`` (R,) of them on each ray. Returns (R, Kmax), NaN past the passes."""
    out = np.full(pass_nodes.shape, np.nan)
    for a in range(g.shape[0]):
        k = int(n_passes[a])
        compensate_on_ray(g[a], gp[a], spacing_um, nose_radius_um, pass_nodes[a, :k], mode, out[a, :k])
    return out
