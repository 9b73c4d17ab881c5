"""The controller's bilinear interpolation (model §3) along the spiral tool path (§1).

The tool feeds from the outer edge ρ0 to the centre along ρ(φ) = ρ0 − F·φ/2π. Along one
spindle angle θ ∈ [0, 2π) it therefore passes once per revolution, at
ρ_k = ρ0 − F·(k + θ/2π), k = 0, 1, ... while ρ_k ≥ 0 (§5). The simulation samples the
part on *feed-plane lines*: a line at θ holds the passes of the ray θ (positions +ρ_k) and
of the opposite ray θ + π (positions −ρ'_k), since near the centre the arcs of both reach
across the axis.

Each ray also carries a uniform *node grid* r_n = ρ_0(θ) − n·F/ppf (ppf evaluation points
per feed): the passes sit on nodes n = k·ppf, so feed cusps midway between passes are
sampled exactly, and the same nodes serve the exact compensation along the path.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple, TypeAlias

import numpy as np
from numba import njit

from ftsweep.stages.interpolation.spiral_passes import pass_commands_kernel
from ftsweep.stages.interpolation.spiral_program import SpiralPath, phi_on_path, spiral_commands
from ftsweep.stages.layouts.grids import Layout

# a program the controller executes: a table (bilinear, model §3) or a spiral path (linear
# in the spindle angle between consecutive points, [4])
Program: TypeAlias = Layout | SpiralPath


@njit(nogil=True, cache=True, inline="always")
def _first_index(u: float, n0: int) -> tuple[Any, ...]:  # pragma: no cover - jit
    """Cell i and fraction t of the first index ``u``, clamped to a table of ``n0`` rows
    (the controller holds the edge value)."""
    # floored as a float (np.floor; math.floor's int would be converted back for u − i)
    fi = np.floor(u)
    if fi > n0 - 2.0:
        return n0 - 2, 1.0
    if fi >= 0.0:
        return int(fi), u - fi
    # before the first row; a NaN index reads row 0 (never an index made from a NaN) with a
    # NaN fraction, so its value is NaN
    return 0, (0.0 if fi < 0.0 else u)


@njit(nogil=True, cache=True, inline="always")
def _second_index(v: float, n1: int, periodic: bool) -> tuple[Any, ...]:  # pragma: no cover - jit
    """Columns j, j1 and fraction s of the second index ``v``: wrapped when ``periodic``
    (column n1−1 neighbours column 0), else clamped."""
    fj = np.floor(v)
    s = v - fj
    j = int(fj)
    if periodic:
        return j % n1, (j % n1 + 1) % n1, s
    if fj > n1 - 2.0:
        return n1 - 2, n1 - 1, 1.0
    if fj >= 0.0:
        return j, j + 1, s
    return 0, 1, (0.0 if fj < 0.0 else v)  # NaN as in _first_index


@njit(nogil=True, cache=True, inline="always")
def _blend(table: np.ndarray, i: int, t: float, j: int, j1: int, s: float) -> float:  # pragma: no cover - jit
    """Eq. (2) in cell (i, j) at fractions (t, s)."""
    return (
        (1.0 - t) * (1.0 - s) * table[i, j]
        + t * (1.0 - s) * table[i + 1, j]
        + t * s * table[i + 1, j1]
        + (1.0 - t) * s * table[i, j1]
    )


@njit(nogil=True, cache=True, inline="always")
def _bilinear_at(table: np.ndarray, u: float, v: float, periodic: bool) -> float:  # pragma: no cover - jit
    """Eq. (2) at fractional indices (u, v): u clamped, v wrapped when ``periodic``."""
    n0, n1 = table.shape
    i, t = _first_index(u, n0)
    j, j1, s = _second_index(v, n1, periodic)
    return _blend(table, i, t, j, j1, s)


@njit(nogil=True, cache=True)
def _bilinear_kernel(
    table: np.ndarray, u: np.ndarray, v: np.ndarray, periodic: bool, out: np.ndarray
) -> None:  # pragma: no cover - jit
    for p in range(u.size):
        out[p] = _bilinear_at(table, u[p], v[p], periodic)


@njit(nogil=True, cache=True, error_model="numpy")
def _pass_commands_kernel(
    table: np.ndarray,
    polar: bool,
    o0: float,
    o1: float,
    p0: float,
    p1: float,
    periodic: bool,
    first: np.ndarray,
    k0: int,
    step: float,
    ray_a: np.ndarray,
    ray_b: np.ndarray,
    out: np.ndarray,
) -> None:  # noqa: E501  # pragma: no cover - jit
    # the tool positions ρ_k = max(first − (k + k0)·step, 0) (column k is the spiral's pass
    # k + k0, see path_grid) and their table indices are formed here, ray by ray, instead of
    # as (rays × passes) arrays; the arithmetic is that of pass_rho and table_indices, so the
    # commands are the same to the last bit. A ray's indices come first in a loop of their own,
    # free of branches and lookups, which runs four passes at a time (the divisions included;
    # ``error_model="numpy"`` keeps a zero pitch from adding a branch), then the lookups
    n0, n1 = table.shape
    n_k = out.shape[1]
    pass_k = np.empty(n_k)  # the pass numbers as floats: no int64 conversion in the loop
    for k in range(n_k):
        pass_k[k] = k + k0
    us, vs = np.empty(n_k), np.empty(n_k)
    for a in range(out.shape[0]):
        f, ca, sa = first[a], ray_a[a], ray_b[a]
        if polar:
            # a ray keeps its angle: its columns are found once (the modulo of a wrapped
            # index cost as much as the rest of a pass)
            j, j1, s = _second_index(ca, n1, periodic)
            for k in range(n_k):
                us[k] = (max(f - pass_k[k] * step, 0.0) - o0) / p0
            for k in range(n_k):
                i, t = _first_index(us[k], n0)
                out[a, k] = _blend(table, i, t, j, j1, s)
            continue
        for k in range(n_k):
            rho = max(f - pass_k[k] * step, 0.0)
            us[k] = (rho * ca - o0) / p0
            vs[k] = (rho * sa - o1) / p1
        for k in range(n_k):
            out[a, k] = _bilinear_at(table, us[k], vs[k], periodic)


def bilinear(table: np.ndarray, u: np.ndarray, v: np.ndarray, periodic: bool) -> np.ndarray:
    """Bilinear interpolation in fractional table indices (model §3).

    w = (1−t)(1−u)·w[i,j] + t(1−u)·w[i+1,j] + t·u·w[i+1,j+1] + (1−t)·u·w[i,j+1]

    ``u`` (first index) is clamped to the table; ``v`` wraps modulo the second dimension
    when ``periodic`` (θ for rings: column Np−1 neighbours column 0), else it is clamped.
    ``u`` and ``v`` broadcast against each other; returns values in the table's unit.
    """
    u, v = np.broadcast_arrays(u, v)
    shape = np.shape(u)
    uf = np.ascontiguousarray(u, dtype=np.float64).reshape(-1)
    vf = np.ascontiguousarray(v, dtype=np.float64).reshape(-1)
    out = np.empty_like(uf)
    _bilinear_kernel(np.ascontiguousarray(table, dtype=np.float64), uf, vf, bool(periodic), out)
    return out.reshape(shape)


def table_indices(layout: Layout, rho: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fractional table indices (u, v) of tool positions ρ [µm], θ [rad] (model §2–3)."""
    if layout.periodic:  # rings: polar (ρ, θ) indices
        u = (rho - layout.origin[0]) / layout.pitch[0]
        v = (np.degrees(theta) - layout.origin[1]) / layout.pitch[1]
        return u, v
    x, y = rho * np.cos(theta), rho * np.sin(theta)
    return (x - layout.origin[0]) / layout.pitch[0], (y - layout.origin[1]) / layout.pitch[1]


def interpolate(layout: Program, table: np.ndarray, rho: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """FTS command w [µm] at tool positions ρ [µm], θ [rad]: the controller's lookup (§3),
    or for a spiral program its linear interpolation along the path at the positions'
    place on the spiral (:func:`ftsweep.stages.interpolation.spiral_program.phi_on_path`)."""
    if isinstance(layout, SpiralPath):
        return spiral_commands(layout, table, phi_on_path(layout, np.asarray(rho), np.asarray(theta)))
    u, v = table_indices(layout, rho, theta)
    return bilinear(table, u, v, layout.periodic)


def pass_commands(layout: Program, table: np.ndarray, grid: PathGrid) -> np.ndarray:
    """FTS commands w [µm] of every pass of ``grid`` (R, Kmax): :func:`interpolate` at the
    tool positions ρ_k = max(ρ_0 − k·F, 0) of each ray, in one pass without the position and
    index arrays, bit for bit equal to ``interpolate(layout, table, max(grid.pass_rho, 0),
    grid.ray_theta[:, None])`` (model §1, §3). Entries k ≥ n_passes are meaningless.

    For a spiral program (``table`` its commands at its points), pass k of the ray at θ is
    the tool at accumulated angle φ = 2πk + θ, where the controller interpolates between the
    points around φ: linearly, or by the path's cubic segments
    (:mod:`ftsweep.stages.interpolation.segments`)."""
    if isinstance(layout, SpiralPath):
        out = np.empty((grid.ray_theta.size, int(grid.n_passes.max())))
        none = np.empty(0)
        pass_commands_kernel(
            np.ascontiguousarray(layout.phi, dtype=np.float64),
            np.ascontiguousarray(table, dtype=np.float64),
            none if layout.d0 is None else np.ascontiguousarray(layout.d0, dtype=np.float64),
            none if layout.d1 is None else np.ascontiguousarray(layout.d1, dtype=np.float64),
            np.ascontiguousarray(grid.ray_theta, dtype=np.float64),
            int(grid.first_revolution),
            out,
        )
        return out
    theta = grid.ray_theta[:, None]
    if layout.periodic:
        ray_a = ((np.degrees(theta) - layout.origin[1]) / layout.pitch[1]).ravel()
        ray_b = ray_a
    else:
        ray_a, ray_b = np.cos(theta).ravel(), np.sin(theta).ravel()
    out = np.empty((grid.ray_theta.size, int(grid.n_passes.max())))
    _pass_commands_kernel(
        np.ascontiguousarray(table, dtype=np.float64),
        bool(layout.periodic),
        float(layout.origin[0]),
        float(layout.origin[1]),
        float(layout.pitch[0]),
        float(layout.pitch[1]),
        bool(layout.periodic),
        grid.first_pass,
        int(grid.first_revolution),
        grid.spacing_um * grid.ppf,
        ray_a,
        ray_b,
        out,
    )
    return out


class PathGrid(NamedTuple):
    """Sampling of a batch of feed-plane lines (see module docstring). Lengths in µm.

    ray_theta : (R,) angle [rad] of each ray; rays 2l and 2l+1 form line l (θ and θ + π).
    first_pass : (R,) radius of the spiral's pass 0 on each ray, ρ0 − F·θ/2π [µm].
    n_passes : (R,) passes held on each ray: those with ρ_k ≥ 0 from pass
        ``first_revolution`` on (column k of pass arrays is the spiral's pass k + k0).
    node_offset : index of the first pass held in the node arrays; nodes before it lie
        outside it, so exact compensation sees the section beyond it.
    spacing_um : node spacing F/ppf [µm].
    ppf : evaluation nodes per feed.
    node_r : (R, G) radius of every node [µm] (negative past the axis).
    first_revolution : k0, the spiral's passes left out before the first one held (they lie
        beyond the reach of everything simulated, see :func:`path_grid`).
    """

    ray_theta: np.ndarray
    first_pass: np.ndarray
    n_passes: np.ndarray
    node_offset: int
    spacing_um: float
    ppf: int
    node_r: np.ndarray
    first_revolution: int = 0

    @property
    def origin_node(self) -> int:
        """Index of the spiral's pass 0 in the node arrays (negative when passes are left
        out): node j lies at first_pass − (j − origin_node)·spacing."""
        return self.node_offset - self.first_revolution * self.ppf

    @property
    def pass_node_index(self) -> np.ndarray:
        """(Kmax,) node index of pass k, the same on every ray."""
        return self.node_offset + np.arange(int(self.n_passes.max()), dtype=np.int64) * self.ppf

    @property
    def pass_nodes(self) -> np.ndarray:
        """(R, Kmax) node index of each pass (valid for k < n_passes)."""
        return np.broadcast_to(self.pass_node_index, (self.ray_theta.size, int(self.n_passes.max())))

    @property
    def pass_rho(self) -> np.ndarray:
        """(R, Kmax) radius ρ_k of each pass [µm] (meaningless for k ≥ n_passes)."""
        k = np.arange(int(self.n_passes.max())) + self.first_revolution
        return self.first_pass[:, None] - k[None, :] * (self.spacing_um * self.ppf)


@njit(nogil=True, cache=True, error_model="numpy")
def _hermite_kernel(
    g: np.ndarray,
    gp: np.ndarray,
    first_pass: np.ndarray,
    node_offset: int,
    spacing: float,
    r: np.ndarray,
    out: np.ndarray,
) -> None:  # pragma: no cover - jit
    n_rays, n_nodes = g.shape
    top = n_nodes - 2.0
    n_c = r.shape[1]
    # a ray's node coordinates first, in a loop of their own that runs four at a time (the
    # division included), then the lookups
    xis = np.empty(n_c)
    origin = float(node_offset)
    for a in range(n_rays):
        fa = first_pass[a]
        for c in range(n_c):
            # node index grows inwards: r lies between nodes j (outer) and j + 1
            xis[c] = (fa - r[a, c]) / spacing + origin
        for c in range(n_c):
            xi = xis[c]
            if math.isnan(xi):  # a NaN radius
                out[a, c] = math.nan
                continue
            # floored and clamped as a float (np.floor, not math.floor's int), so the fraction
            # needs no conversion back from an integer
            fj = min(max(np.floor(xi), 0.0), top)
            j = int(fj)
            t = xi - fj
            # Hermite basis in the node coordinate ξ, where d/dξ = −spacing·d/dr
            h00 = (1.0 + 2.0 * t) * (1.0 - t) * (1.0 - t)
            h10 = t * (1.0 - t) * (1.0 - t)
            h01 = t * t * (3.0 - 2.0 * t)
            h11 = t * t * (t - 1.0)
            out[a, c] = h00 * g[a, j] + h01 * g[a, j + 1] - spacing * (h10 * gp[a, j] + h11 * gp[a, j + 1])


@njit(nogil=True, cache=True)
def nonfinite_passes(w: np.ndarray, n_passes: np.ndarray) -> tuple[Any, ...]:  # pragma: no cover - jit
    """NaN or inf among the passes of (rays, passes) commands ``w`` [µm], the first
    ``n_passes[a]`` of row a (the rest is padding): (their number, the flat index of the
    first, −1 when none), read in place."""
    count = 0
    for a in range(w.shape[0]):
        for k in range(n_passes[a]):
            count += not math.isfinite(w[a, k])  # no branch: the row runs four at a time
    if count:
        for a in range(w.shape[0]):
            for k in range(n_passes[a]):
                if not math.isfinite(w[a, k]):
                    return count, a * w.shape[1] + k
    return count, -1


def sample_on_nodes(grid: PathGrid, g: np.ndarray, gp: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Section height [µm] at radii ``r`` (R, C) [µm] between the nodes of ``grid``, by cubic
    Hermite interpolation of the node samples g [µm] and radial slopes g' [-].

    NaN radii stay NaN. The error is O(spacing^4 · fourth derivative of g) on smooth sections (far below a
    picometre at the default spacing) and O(spacing^2 · jump of curvature) at seams.
    """
    out = np.empty(r.shape)
    _hermite_kernel(g, gp, grid.first_pass, grid.origin_node, grid.spacing_um, r, out)
    return out


def first_machined_node(grid: PathGrid, contact_window_um: float) -> int:
    """First node of the fully machined zone (model §6) on every ray of ``grid``.

    A point is fully machined once passes touch the design on both sides of it. The arc of
    pass k touches at ρ_k + s* with |s*| ≤ the contact window, so the zone starts at the
    second pass moved inwards by the contact window: r ≤ ρ_0 − F − window. Outside it the
    point is shaped by the flank of the first arc, not by the layout.
    """
    return grid.node_offset + grid.ppf + int(math.ceil(contact_window_um / grid.spacing_um - 1e-9))


def line_angles(n_theta: int) -> np.ndarray:
    """Angles θ_l = (l + ½)·2π/n_theta [rad] of the n_theta/2 feed-plane lines.

    Together with their opposite rays they sample n_theta spindle angles evenly, offset by
    half a step so no sample sits on a table column."""
    if n_theta < 2 or n_theta % 2:
        raise ValueError(f"n_theta must be an even number ≥ 2, got {n_theta}")
    return (np.arange(n_theta // 2) + 0.5) * (2.0 * math.pi / n_theta)


def path_grid(
    line_theta: np.ndarray,
    rho0_um: float,
    feed_um: float,
    ppf: int,
    margin_um: float,
    reach_um: float = math.inf,
) -> PathGrid:
    """Pass positions and node grids for feed-plane lines at ``line_theta`` [rad] (§1, §5).

    Parameters
    ----------
    line_theta : angles of the lines [rad] in [0, π).
    rho0_um : radius where the spiral starts [µm].
    feed_um : feed per revolution F [µm/rev].
    ppf : evaluation nodes per feed (≥ 1).
    margin_um : how far the node grid extends beyond the first pass held and past the axis
        [µm]; at least the contact window of the compensation.
    reach_um : the leading revolutions whose passes lie beyond this radius [µm] on every
        ray are left out (with their nodes): the caller's bound beyond which no pass can
        touch what it evaluates. Nodes and passes held are those of the whole spiral, to the
        last bit.
    """
    if ppf < 1:
        raise ValueError(f"points per feed must be ≥ 1, got {ppf}")
    ray_theta = np.empty(2 * line_theta.size)
    ray_theta[0::2] = line_theta
    ray_theta[1::2] = line_theta + math.pi
    first = rho0_um - feed_um * ray_theta / (2.0 * math.pi)
    n_passes = np.floor(first / feed_um + 1e-9).astype(np.int64) + 1
    # pass k lies beyond the reach on every ray when min(first) − k·F > reach
    beyond = (float(first.min()) - reach_um) / feed_um if math.isfinite(reach_um) else 0.0
    k0 = min(max(int(math.ceil(beyond)), 0), int(n_passes.min()) - 1)
    spacing = feed_um / ppf
    offset = int(math.ceil(margin_um / spacing))
    n_nodes = offset + int(math.ceil((rho0_um + margin_um) / spacing)) + 1 - k0 * ppf
    # the nodes' offsets along a ray once, then one pass over the grid (the same products)
    along = (np.arange(n_nodes) + (k0 * ppf - offset)) * spacing
    node_r = first[:, None] - along[None, :]
    return PathGrid(ray_theta, first, n_passes - k0, offset, spacing, ppf, node_r, k0)
