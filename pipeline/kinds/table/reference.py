"""A brute-force evaluation of a table case, straight from the model (§1–§6):
the yardstick the simulator is checked and timed against.

Nothing here searches, sorts arcs into a hull, shares work between rays or stops early:

- every control value is the maximum of eq. (3) over a dense scan of the contact window
  (model §4), refined by the parabola through the best sample and its neighbours;
- every pass's command is the bilinear blend of its cell (§3) with the controller's edge
  conventions (rows clamped; ring columns wrapping);
- every node's machined height is the minimum over *every* pass within Rc of it, on its own
  ray and on the opposite one (§5);
- the metrics are the model's (§6) over the nodes inside the aperture and the fully machined
  zone (the second pass moved inwards by the contact window), P-V over nodes only.

It shares with the simulator only the case's inputs (the resolved layout, the design surface
callable, the aperture, the feed, the nose radius and the gradient bound the contact window
follows from) and the sampled spindle angles (:func:`ftsweep.stages.interpolation.tables.line_angles`),
so the two are compared on the same lines. Memory stays bounded (blocks of about
:data:`BLOCK` values); the cost is that of brute force: every node against about 2·Rc/F
passes. Pure numpy; the table kinds' ``reference`` (docs/architecture.md, "The program-kind
contract"), for tests and ``ftsweep bench --reference``.
"""

from __future__ import annotations

import math
import time
from typing import Any, Optional

import numpy as np

from ftsweep.engine.cost import angular_samples
from ftsweep.engine.planning import ResolvedCase
from ftsweep.stages.interpolation.compensation import contact_window_um
from ftsweep.stages.interpolation.tables import line_angles

# values held at once in a block of the brute-force arrays (float64: 8 MB)
BLOCK = 1_000_000
# scan step of eq. (3) [µm]: the parabola through the best sample and its neighbours leaves an
# error of order h'''·step³ (about 10⁻⁷ µm on the catalog's sine waves)
SCAN_STEP_UM = 0.1


def _lift(s: np.ndarray, rc: float) -> np.ndarray:
    """Height of the nose arc above its lowest point at offset ``s`` [µm] (model §4)."""
    return np.asarray(rc - np.sqrt(np.maximum(rc * rc - s * s, 0.0)))


def exact_commands(surface: Any, rho: np.ndarray, theta: np.ndarray, rc: float, window: float) -> np.ndarray:
    """w = max over |s| ≤ ``window`` of g(ρ + s) − (Rc − sqrt(Rc² − s²)) (model §4, eq. 3) [µm]
    at radii ``rho`` [µm] along angles ``theta`` [rad], by a dense scan (:data:`SCAN_STEP_UM`)
    refined by the parabola through the best sample and its neighbours."""
    n_s = int(math.ceil(window / SCAN_STEP_UM))
    s = np.arange(-n_s, n_s + 1) * (window / max(n_s, 1))
    lift = _lift(s, rc)
    out = np.empty(rho.size)
    per = max(1, BLOCK // s.size)
    for a in range(0, rho.size, per):
        r = rho[a : a + per, None] + s[None, :]
        th = theta[a : a + per, None]
        h = surface(r * np.cos(th), r * np.sin(th))[0] - lift[None, :]
        out[a : a + per] = _refined_max(h)
    return out


def _refined_max(h: np.ndarray) -> np.ndarray:
    """The maximum of each row of samples ``h``, refined by the parabola through the best
    sample and its neighbours where it is interior and the parabola opens downwards."""
    b = np.argmax(h, axis=1)
    rows = np.arange(h.shape[0])
    best = h[rows, b]
    inner = (b > 0) & (b < h.shape[1] - 1)
    lo, hi = np.where(inner, b - 1, b), np.where(inner, b + 1, b)
    hm, hp = h[rows, lo], h[rows, hi]
    curv = hm - 2.0 * best + hp
    vertex = best - (hp - hm) ** 2 / np.where(curv < 0.0, 8.0 * curv, -1.0)
    return np.asarray(np.where(inner & (curv < 0.0), vertex, best))


def control_table(rcase: ResolvedCase, window: float) -> np.ndarray:
    """The compensated table [µm] of a ring or mesh layout (model §2, §4): each point's radial
    section through the part's centre (θ = atan2(y, x) for a mesh)."""
    layout = rcase.layout
    n0, n1 = layout.shape
    i, j = np.meshgrid(np.arange(n0), np.arange(n1), indexing="ij")
    if layout.kind == "ring":
        rho = i * layout.pitch[0]
        theta = np.radians(j * layout.pitch[1])
    else:
        x = layout.origin[0] + i * layout.pitch[0]
        y = layout.origin[1] + j * layout.pitch[1]
        rho, theta = np.hypot(x, y), np.arctan2(y, x)
    w = exact_commands(rcase.surface, rho.ravel().astype(float), theta.ravel(), rcase.nose_radius_um, window)
    return w.reshape(layout.shape)


def _cell(q: np.ndarray, n: int, periodic: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lower index, upper index and fraction of fractional indices ``q`` in ``n`` entries:
    wrapping when ``periodic``, else clamped to the edge cell (the controller holds the
    edge value)."""
    i = np.floor(q)
    t = q - i
    if periodic:
        lo = i.astype(np.int64) % n
        return lo, (lo + 1) % n, t
    below, above = i < 0, i > n - 2
    t = np.where(below, 0.0, np.where(above, 1.0, t))
    lo = np.clip(i, 0, n - 2).astype(np.int64)
    return lo, lo + 1, t


def bilinear(layout: Any, table: np.ndarray, rho: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """The controller's command at radii ``rho`` [µm] and angles ``theta`` [rad] (model §3)."""
    if layout.kind == "ring":
        q0 = rho / layout.pitch[0]
        q1 = np.degrees(np.mod(theta, 2.0 * math.pi)) / layout.pitch[1]
    else:
        q0 = (rho * np.cos(theta) - layout.origin[0]) / layout.pitch[0]
        q1 = (rho * np.sin(theta) - layout.origin[1]) / layout.pitch[1]
    i, i1, t = _cell(q0, table.shape[0], False)
    j, j1, u = _cell(q1, table.shape[1], layout.kind == "ring")
    value = (
        (1 - t) * (1 - u) * table[i, j]
        + t * (1 - u) * table[i1, j]
        + t * u * table[i1, j1]
        + (1 - t) * u * table[i, j1]
    )
    return np.asarray(value)


def envelope(pos: np.ndarray, w: np.ndarray, rc: float, x: np.ndarray) -> np.ndarray:
    """z(x) = min over every pass with |x − p| < Rc of w + Rc − sqrt(Rc² − (x − p)²) (model §5)
    [µm] at positions ``x`` along a line whose passes sit at ``pos`` (ascending) [µm]."""
    lo = np.searchsorted(pos, x - rc, side="right")
    hi = np.searchsorted(pos, x + rc, side="left")
    width = int((hi - lo).max(initial=0))
    out = np.full(x.size, np.inf)
    per = max(1, BLOCK // max(width, 1))
    for a in range(0, x.size, per):
        k = lo[a : a + per, None] + np.arange(width)[None, :]
        held = k < hi[a : a + per, None]
        k = np.minimum(k, pos.size - 1)
        d = x[a : a + per, None] - pos[k]
        arcs = np.where(held, w[k] + _lift(d, rc), np.inf)
        out[a : a + per] = arcs.min(axis=1, initial=np.inf)
    return out


class _Line:
    """One feed-plane line at ``theta`` [rad] (model §5): the passes of its ray and of the
    opposite ray (positions +ρ_k and −ρ'_k along the line), and the evaluation nodes of both
    rays in the fully machined zone, ``per_feed`` a feed."""

    def __init__(self, rcase: ResolvedCase, theta: float, per_feed: int, window: float) -> None:
        feed, rho0 = rcase.feed_um, rcase.rho0_um
        pos, ang, nodes, node_ang = [], [], [], []
        for sign, psi in ((1.0, theta), (-1.0, theta + math.pi)):
            first = rho0 - feed * psi / (2.0 * math.pi)
            rho = first - feed * np.arange(int(math.floor(first / feed + 1e-9)) + 1)
            pos.append(sign * rho)
            ang.append(np.full(rho.size, psi))
            start = int(math.ceil((feed + window) / (feed / per_feed) - 1e-9))
            r = first - (feed / per_feed) * np.arange(start, int(math.floor(first / (feed / per_feed))) + 1)
            r = r[r >= 0.0]
            nodes.append(sign * r)
            node_ang.append(np.full(r.size, psi))
        order = np.argsort(np.concatenate(pos), kind="stable")
        self.pos = np.concatenate(pos)[order]
        self.pass_rho = np.abs(self.pos)
        self.pass_theta = np.concatenate(ang)[order]
        self.x = np.concatenate(nodes)
        self.node_theta = np.concatenate(node_ang)


def _line_errors(
    rcase: ResolvedCase, table: np.ndarray, line: _Line, window: float, interp: bool
) -> tuple[np.ndarray, Optional[np.ndarray]]:
    """The form error e = z − f [µm] on a line's nodes inside the aperture (model §6), and the
    interpolation-only error z − z_exact there (None unless ``interp``)."""
    rc = rcase.nose_radius_um
    r = np.abs(line.x)
    c, s = np.cos(line.node_theta), np.sin(line.node_theta)
    inside = rcase.aperture.contains_polar(r, c, s)
    x = line.x[inside]
    w = bilinear(rcase.layout, table, line.pass_rho, line.pass_theta)
    z = envelope(line.pos, w, rc, x)
    f = rcase.surface(r[inside] * c[inside], r[inside] * s[inside])[0]
    if not interp:
        return z - f, None
    w_exact = exact_commands(rcase.surface, line.pass_rho, line.pass_theta, rc, window)
    return z - f, z - envelope(line.pos, w_exact, rc, x)


def reference_case(
    rcase: ResolvedCase, per_feed: Optional[int] = None, interp: bool = True
) -> dict[str, float]:
    """P-V, RMS about the mean and the interpolation-only P-V [nm] of a resolved ring or mesh
    case by brute force (this module's list), on the simulator's spindle angles and
    ``per_feed`` evaluation nodes a feed (default: the case's ``points_per_feed``); with its
    seconds and the nodes evaluated. Its P-V is over the nodes alone: the simulator's adds the
    exact cusp peaks between them, so it lies above by up to a cusp's rise over a quarter feed."""
    t = time.perf_counter()
    kind = rcase.kind
    res = rcase.case.resolution
    window = contact_window_um(rcase.gradient_bound, rcase.nose_radius_um)
    table = control_table(rcase, window)
    n_theta = angular_samples(kind.angular_cells, rcase.layout, rcase.rho0_um, res)
    e_lo = d_lo = math.inf
    e_hi = d_hi = -math.inf
    count, total, squares = 0, 0.0, 0.0
    for theta in line_angles(n_theta):
        line = _Line(rcase, float(theta), per_feed or res.points_per_feed, window)
        e, d = _line_errors(rcase, table, line, window, interp and res.interp_error)
        if e.size:
            e_lo, e_hi = min(e_lo, float(e.min())), max(e_hi, float(e.max()))
            count, total, squares = count + e.size, total + float(e.sum()), squares + float(e @ e)
        if d is not None and d.size:
            d_lo, d_hi = min(d_lo, float(d.min())), max(d_hi, float(d.max()))
    mean = total / count if count else math.nan
    return {
        "pv_nm": (e_hi - e_lo) * 1e3 if count else math.nan,
        "rms_nm": math.sqrt(max(squares / count - mean * mean, 0.0)) * 1e3 if count else math.nan,
        "pv_interp_nm": (d_hi - d_lo) * 1e3 if d_hi >= d_lo else math.nan,
        "n_eval": count,
        "seconds": time.perf_counter() - t,
    }
