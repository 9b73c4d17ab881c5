"""Envelope prediction: the surface the tool leaves behind (model §5).

Along one feed-plane line the machined height is the lower envelope of the tool arcs:

    z(r) = min over k with |r − ρ_k| < Rc of [ w_k + Rc − sqrt(Rc² − (r − ρ_k)²) ]

All arcs are translates of one strictly convex function, so two of them cross at most once
and, ordered by position, the winning arc is monotone in r. The lower envelope is therefore
built like a convex-hull trick: arcs enter in position order, and an arc is dropped as soon
as its neighbours cross before it would win. Two arcs of equal radius meet on the
perpendicular bisector of their centres, which gives the crossing in closed form. Each pass
is pushed and popped at most once, so a line costs O(passes + nodes): only the passes that
can win at a point are ever compared there.

The envelope of the exact commands serves only the extremes of the interpolation-only error
(model §6); :func:`interp_extrema_lines` evaluates it on the lines where a bound says those
extremes can still move.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit


@njit(nogil=True, cache=True, inline="always")
def _crossing(pa: float, wa: float, pb: float, wb: float, rc: float) -> float:  # pragma: no cover - jit
    """Position where arc b (pb > pa) starts to lie below arc a; ±inf when they never cross."""
    dp = pb - pa
    dw = wb - wa
    d2 = dp * dp + dw * dw
    if d2 >= 4.0 * rc * rc or dp <= 0.0:
        # disjoint circles (or coincident positions): one arc is below the other throughout
        return -math.inf if wb <= wa else math.inf
    d = math.sqrt(d2)
    return 0.5 * (pa + pb) + math.sqrt(rc * rc - 0.25 * d2) * dw / d


@njit(nogil=True, cache=True, inline="always")
def _hull(
    pos: np.ndarray, w: np.ndarray, rc: float, stack: np.ndarray, breaks: np.ndarray
) -> int:  # pragma: no cover - jit
    """The winning arcs of :func:`lower_envelope`, in order, into ``stack[:n]`` with where
    each takes over in ``breaks[1:n]``; returns n."""
    top = -1
    for k in range(pos.size):
        push = True
        x = -math.inf
        while top >= 0:
            x = _crossing(pos[stack[top]], w[stack[top]], pos[k], w[k], rc)
            if x == math.inf:
                push = False  # arc k never wins against the current top
                break
            if x <= breaks[top]:
                top -= 1  # the top arc is beaten before it would start to win
                continue
            break
        if not push:
            continue
        top += 1
        stack[top] = k
        breaks[top] = -math.inf if top == 0 else x
    return top + 1


@njit(nogil=True, cache=True, inline="always")
def _arc_at(
    r: float,
    m: int,
    n_arcs: int,
    pos: np.ndarray,
    w: np.ndarray,
    rc: float,
    stack: np.ndarray,
    breaks: np.ndarray,
) -> tuple[Any, ...]:  # pragma: no cover - jit
    """Height of the envelope at ``r`` [µm] ≥ the previous query, the winning arc's slot
    ``m`` advanced to it; returns (height, m)."""
    while m < n_arcs - 1 and breaks[m + 1] <= r:
        m += 1
    k = stack[m]
    d = r - pos[k]
    return w[k] + rc - math.sqrt(max(rc * rc - d * d, 0.0)), m


@njit(nogil=True, cache=True)
def lower_envelope(
    pos: np.ndarray,
    w: np.ndarray,
    rc: float,
    query: np.ndarray,
    out: np.ndarray,
    stack: np.ndarray,
    breaks: np.ndarray,
) -> int:  # pragma: no cover - jit
    """Lower envelope of arcs at ``pos`` [µm] (ascending) with lowest points ``w`` [µm],
    evaluated at ``query`` [µm] (ascending) into ``out`` [µm] (model §5).

    ``stack`` (int64) and ``breaks`` (float64) are scratch arrays of at least ``pos.size``;
    on return ``stack[:n]`` holds the winning arcs in order and ``breaks[1:n]`` where each
    takes over (the cusp peaks). Returns n.
    """
    n_arcs = _hull(pos, w, rc, stack, breaks)
    m = 0
    for q in range(query.size):
        out[q], m = _arc_at(query[q], m, n_arcs, pos, w, rc, stack, breaks)
    return n_arcs


@njit(nogil=True, cache=True, inline="always")
def _line_passes(
    node_r: np.ndarray,
    pass_w: np.ndarray,
    n_passes: np.ndarray,
    node_offset: int,
    ppf: int,
    line: int,
    pos: np.ndarray,
    w: np.ndarray,
) -> int:  # pragma: no cover - jit
    """The passes of ``line`` (rays 2·line, at θ, and 2·line + 1, at θ + π) in ascending
    position into ``pos``, ``w``: the opposite ray's at −ρ', then the own ray's; returns their
    number."""
    own, opp = 2 * line, 2 * line + 1
    n = 0
    for k in range(n_passes[opp]):
        pos[n] = -node_r[opp, node_offset + k * ppf]
        w[n] = pass_w[opp, k]
        n += 1
    for k in range(n_passes[own] - 1, -1, -1):
        pos[n] = node_r[own, node_offset + k * ppf]
        w[n] = pass_w[own, k]
        n += 1
    return n


@njit(nogil=True, cache=True, inline="always")
def _line_scratch(kmax: int) -> tuple[Any, ...]:  # pragma: no cover - jit
    """Scratch arrays for a line of up to 2·``kmax`` passes: positions, commands, and the
    hull's stack and breaks (:func:`_hull`)."""
    return np.empty(2 * kmax), np.empty(2 * kmax), np.empty(2 * kmax, dtype=np.int64), np.empty(2 * kmax)


@njit(nogil=True, cache=True, inline="always")
def _line_span(node_r: np.ndarray, first: int, line: int) -> tuple[Any, ...]:  # pragma: no cover - jit
    """The evaluation nodes of ``line``: from ``first`` inwards while r ≥ 0 on each ray;
    returns the end (exclusive) on the opposite and on the own ray."""
    n_nodes = node_r.shape[1]
    last_opp = first
    while last_opp < n_nodes and node_r[2 * line + 1, last_opp] >= 0.0:
        last_opp += 1
    last_own = first
    while last_own < n_nodes and node_r[2 * line, last_own] >= 0.0:
        last_own += 1
    return last_opp, last_own


@njit(nogil=True, cache=True)
def envelope_lines(
    node_r: np.ndarray,
    pass_w: np.ndarray,
    n_passes: np.ndarray,
    node_offset: int,
    ppf: int,
    eval_start: int,
    rc: float,
    z: np.ndarray,
    cusp_r: np.ndarray,
    cusp_z: np.ndarray,
) -> None:  # noqa: E501  # pragma: no cover - jit
    """Machined height z [µm] on the node grids of a batch of feed-plane lines (§5).

    node_r : (R, G) node radii [µm]; rays 2l (θ) and 2l+1 (θ + π) form line l.
    pass_w : (R, Kmax) commands w_k [µm] of the passes (pass k sits on node
        ``node_offset + k·ppf``).
    n_passes : (R,) passes per ray.
    eval_start : first evaluation node; nodes from there inwards down to the axis are
        evaluated (see :func:`ftsweep.stages.interpolation.tables.first_machined_node`).
    z : (R, G) output; filled on the evaluation nodes, NaN elsewhere.
    cusp_r, cusp_z : (R, C) outputs: radius [µm] and height [µm] of the cusp peaks (where
        one arc takes over from the next) inside the evaluated part of each ray, in order,
        NaN-padded; C ≥ Kmax + 1 suffices. Nodes sample the cusps only where they happen to
        fall; these are the exact peaks, which move off the nodes by about Rc·slope.
    """
    n_rays, n_nodes = node_r.shape
    pos, w, stack, breaks = _line_scratch(pass_w.shape[1])
    first = eval_start
    for line in range(n_rays // 2):
        own, opp = 2 * line, 2 * line + 1
        n = _line_passes(node_r, pass_w, n_passes, node_offset, ppf, line, pos, w)
        last_opp, last_own = _line_span(node_r, first, line)
        z[opp, :first] = np.nan
        z[opp, last_opp:] = np.nan
        z[own, :first] = np.nan
        z[own, last_own:] = np.nan
        # the nodes in ascending position: the opposite ray's at −r (j upwards), then the own
        # ray's (j downwards)
        n_arcs = _hull(pos[:n], w[:n], rc, stack, breaks)
        m = 0
        for j in range(first, last_opp):
            z[opp, j], m = _arc_at(-node_r[opp, j], m, n_arcs, pos, w, rc, stack, breaks)
        for j in range(last_own - 1, first - 1, -1):
            z[own, j], m = _arc_at(node_r[own, j], m, n_arcs, pos, w, rc, stack, breaks)
        r_opp = node_r[opp, first] if first < n_nodes else -1.0
        r_own = node_r[own, first] if first < n_nodes else -1.0
        opp_rows, own_rows = (cusp_r[opp], cusp_z[opp]), (cusp_r[own], cusp_z[own])
        _line_cusps(stack, breaks, n_arcs, pos, w, rc, r_opp, r_own, opp_rows, own_rows)
    for a in range(2 * (n_rays // 2), n_rays):  # an odd last ray belongs to no line
        cusp_r[a, :] = np.nan
        cusp_z[a, :] = np.nan


@njit(nogil=True, cache=True, inline="always")
def _line_cusps(
    stack: np.ndarray,
    breaks: np.ndarray,
    n_arcs: int,
    pos: np.ndarray,
    w: np.ndarray,
    rc: float,
    r_opp: float,
    r_own: float,
    opp_rows: tuple[Any, ...],
    own_rows: tuple[Any, ...],
) -> None:  # noqa: E501  # pragma: no cover - jit
    """The cusp peaks of a line's hull (:func:`envelope_lines`) into its rays' rows (radius,
    height), each NaN-padded: the takeovers at −r_opp ≤ x < 0 on the opposite ray (at −x),
    those at 0 ≤ x ≤ r_own on the own ray. The breaks ascend, so each ray's are one run of
    slots, and the runs' loops are free of branches (they run four at a time)."""
    opp_r, opp_z = opp_rows
    own_r, own_z = own_rows
    m = 1
    while m < n_arcs and breaks[m] < 0.0 and breaks[m] < -r_opp:
        m += 1
    lo = m
    while m < n_arcs and breaks[m] < 0.0:
        m += 1
    c_opp = _cusp_run(stack, breaks, pos, w, rc, lo, min(m, lo + opp_r.size), -1.0, opp_r, opp_z)
    lo = m
    while m < n_arcs and breaks[m] <= r_own:
        m += 1
    c_own = _cusp_run(stack, breaks, pos, w, rc, lo, min(m, lo + own_r.size), 1.0, own_r, own_z)
    opp_r[c_opp:] = np.nan
    opp_z[c_opp:] = np.nan
    own_r[c_own:] = np.nan
    own_z[c_own:] = np.nan


@njit(nogil=True, cache=True, inline="always")
def _cusp_run(
    stack: np.ndarray,
    breaks: np.ndarray,
    pos: np.ndarray,
    w: np.ndarray,
    rc: float,
    lo: int,
    hi: int,
    sign: float,
    out_r: np.ndarray,
    out_z: np.ndarray,
) -> int:  # pragma: no cover - jit
    """Cusp peaks of hull slots lo … hi−1 into ``out_r`` (at sign·x [µm]) and ``out_z`` (the
    height where arc stack[m] takes over [µm]) from index 0; returns their number."""
    for m in range(lo, hi):
        x = breaks[m]
        d = x - pos[stack[m]]
        out_r[m - lo] = sign * x
        out_z[m - lo] = w[stack[m]] + rc - math.sqrt(max(rc * rc - d * d, 0.0))
    return max(hi - lo, 0)


def machined_lines(
    node_r: np.ndarray,
    pass_w: np.ndarray,
    n_passes: np.ndarray,
    node_offset: int,
    ppf: int,
    eval_start: int,
    nose_radius_um: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`envelope_lines` with its outputs allocated: machined height z (R, G) [µm] and the
    exact cusp peaks' radius and height (R, Kmax + 2) [µm] (model §5)."""
    z = np.empty(node_r.shape)
    cusp_shape = (node_r.shape[0], int(n_passes.max()) + 2)
    cusp_r, cusp_z = np.empty(cusp_shape), np.empty(cusp_shape)
    envelope_lines(node_r, pass_w, n_passes, node_offset, ppf, eval_start, nose_radius_um, z, cusp_r, cusp_z)
    return z, cusp_r, cusp_z


@njit(nogil=True, cache=True, inline="always")
def _row_arcs(
    pos: np.ndarray, w: np.ndarray, a: int, n: int, rc: float, stack: np.ndarray, breaks: np.ndarray
) -> tuple[Any, ...]:  # pragma: no cover - jit
    """The first ``n`` passes of row ``a`` (positions, commands) and their hull's arc count
    (:func:`_hull`, into ``stack`` and ``breaks``)."""
    p = pos[a, :n]
    ww = w[a, :n]
    return p, ww, _hull(p, ww, rc, stack, breaks)


@njit(nogil=True, cache=True)
def envelope_rows(
    pos: np.ndarray,
    w: np.ndarray,
    n_valid: np.ndarray,
    rc: float,
    query: np.ndarray,
    z: np.ndarray,
    cusp_r: np.ndarray,
    cusp_z: np.ndarray,
) -> None:  # pragma: no cover - jit
    """Machined height z [µm] along a batch of rays whose passes are given directly (§5):
    the same lower envelope as :func:`envelope_lines`, for programs whose passes do not
    follow the spiral (e.g. the cuts of a D path, [5]).

    pos, w : (R, K) pass positions [µm] (the first ``n_valid[a]`` ascending) and commands [µm].
    query : (R, G) evaluation radii [µm], ascending along each row; NaN: not evaluated.
    z : (R, G) output (NaN where the query is NaN). cusp_r, cusp_z : (R, K) outputs: where one
    arc takes over from the next and the height there [µm], NaN-padded.
    """
    n_rays = pos.shape[0]
    kmax = pos.shape[1]
    stack = np.empty(kmax, dtype=np.int64)
    breaks = np.empty(kmax)
    cusp_r[:, :] = np.nan
    cusp_z[:, :] = np.nan
    for a in range(n_rays):
        n = n_valid[a]
        if n == 0:
            z[a, :] = np.nan
            continue
        p, ww, n_arcs = _row_arcs(pos, w, a, n, rc, stack, breaks)
        m = 0
        for q in range(query.shape[1]):
            r = query[a, q]
            if math.isnan(r):
                z[a, q] = math.nan
                continue
            z[a, q], m = _arc_at(r, m, n_arcs, p, ww, rc, stack, breaks)
        for c in range(1, n_arcs):
            x = breaks[c]
            k = stack[c]
            d = x - p[k]
            cusp_r[a, c - 1] = x
            cusp_z[a, c - 1] = ww[k] + rc - math.sqrt(max(rc * rc - d * d, 0.0))


def machined_rows(
    pos: np.ndarray, w: np.ndarray, n_valid: np.ndarray, rc: float, query: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`envelope_rows` with its outputs allocated: machined height z at ``query`` [µm]
    along each ray, and the cusp peaks (radius, height) [µm] between the passes (§5)."""
    z = np.empty(query.shape)
    cusp_r = np.empty(pos.shape)
    cusp_z = np.empty(pos.shape)
    envelope_rows(
        np.ascontiguousarray(pos, dtype=np.float64),
        np.ascontiguousarray(w, dtype=np.float64),
        np.ascontiguousarray(n_valid, dtype=np.int64),
        float(rc),
        np.ascontiguousarray(query, dtype=np.float64),
        z,
        cusp_r,
        cusp_z,
    )
    return z, cusp_r, cusp_z


# The interpolation-only error d = z − z_exact (model §6) is needed only through its extremes.
# At any r, with j the pass whose arc wins z and k the one that wins z_exact,
#     z(r) ≤ w_k + arc_k(r) = z_exact(r) + δ_k   and   z_exact(r) ≤ e_j + arc_j(r) = z(r) − δ_j,
# δ = w − e the commands' difference, so d(r) ∈ [δ_j, δ_k] ⊂ [min δ, max δ] over the passes of
# the line. A line whose δ lie within the extremes already found cannot extend them and its
# exact envelope is not evaluated: the extremes are those of evaluating every line. This needs
# the envelope to be the least of the arcs that reach r, which the hull guarantees where the
# passes lie less than Rc apart and the nodes within Rc/2 of the outermost ones (on the path
# grids, a feed apart); a line that is not covered so is always evaluated. The bound is
# widened by the rounding of the heights and crossings (a few ulp of |w| + Rc, ~1e-14 µm at
# 100 µm): 1e-9 µm plus 1e-12 of |w| + Rc keeps three orders of margin.
_BOUND_TOL_UM = 1e-9
_BOUND_TOL_REL = 1e-12


@njit(nogil=True, cache=True, inline="always")
def _delta_range(
    w: np.ndarray, exact_w: np.ndarray, n: int, lo: float, hi: float, big: float
) -> tuple[Any, ...]:  # pragma: no cover - jit
    """(lo, hi, big) extended by the first ``n`` passes of one row: the least and greatest
    δ = w − exact_w [µm] and the largest |w| or |exact_w| [µm]."""
    for k in range(n):
        d = w[k] - exact_w[k]
        # plain comparisons: the loop runs over every pass of the batch
        if d < lo:
            lo = d
        if d > hi:
            hi = d
        if abs(w[k]) > big:
            big = abs(w[k])
        if abs(exact_w[k]) > big:
            big = abs(exact_w[k])
    return lo, hi, big


@njit(nogil=True, cache=True, inline="always")
def _difference_range(
    pos: np.ndarray, w: np.ndarray, exact_w: np.ndarray, n: int, rc: float, q_lo: float, q_hi: float
) -> tuple[Any, ...]:  # pragma: no cover - jit
    """(min δ, max δ, scale) of the first ``n`` passes at ``pos`` [µm], δ = w − exact_w [µm],
    with scale the largest |w| + Rc; (−inf, inf, scale) where the bound does not hold: passes
    Rc or more apart, or evaluation nodes [q_lo, q_hi] [µm] beyond Rc/2 of the outermost."""
    lo, hi, big = _delta_range(w, exact_w, n, math.inf, -math.inf, 0.0)
    covered = n > 0 and q_lo >= pos[0] - 0.5 * rc and q_hi <= pos[n - 1] + 0.5 * rc
    for k in range(1, n):
        if pos[k] - pos[k - 1] >= rc:
            covered = False
    if not covered:
        return -math.inf, math.inf, big + rc
    return lo, hi, big + rc


@njit(nogil=True, cache=True, inline="always")
def _line_difference_range(
    node_r: np.ndarray,
    pass_w: np.ndarray,
    exact_w: np.ndarray,
    n_passes: np.ndarray,
    node_offset: int,
    ppf: int,
    line: int,
    rc: float,
) -> tuple[Any, ...]:  # noqa: E501  # pragma: no cover - jit
    """:func:`_difference_range` of a line of a path grid, read from its rays' rows: along a
    ray the passes lie ``ppf`` nodes apart, the innermost ones of the two rays face each other
    across the axis, and the evaluation nodes lie inside both rays' first passes."""
    own, opp = 2 * line, 2 * line + 1
    lo, hi, big = _delta_range(pass_w[own], exact_w[own], n_passes[own], math.inf, -math.inf, 0.0)
    lo, hi, big = _delta_range(pass_w[opp], exact_w[opp], n_passes[opp], lo, hi, big)
    scale = big + rc
    n_own, n_opp = n_passes[own], n_passes[opp]
    if n_own < 2 or n_opp < 2:
        return -math.inf, math.inf, scale
    step = node_r[own, node_offset] - node_r[own, node_offset + ppf]
    across = node_r[own, node_offset + (n_own - 1) * ppf] + node_r[opp, node_offset + (n_opp - 1) * ppf]
    if step >= rc or across >= rc:
        return -math.inf, math.inf, scale
    return lo, hi, scale


@njit(nogil=True, cache=True, inline="always")
def _worth_evaluating(
    lo_b: float, hi_b: float, tol: float, ext: np.ndarray
) -> bool:  # pragma: no cover - jit
    """Whether a line or row with commands' differences in [lo_b, hi_b] [µm] can extend the
    extremes ``ext`` = [min, max] of d found so far."""
    return lo_b - tol < ext[0] or hi_b + tol > ext[1]


@njit(nogil=True, cache=True, inline="always")
def _evaluation_order(lo_b: np.ndarray, hi_b: np.ndarray) -> np.ndarray:  # pragma: no cover - jit
    """Lines (or rows) in the order that settles the extremes soonest: the one of the lowest
    δ first, then by descending highest δ."""
    order = np.argsort(-hi_b)
    low = np.argmin(lo_b)
    out = np.empty(order.size, dtype=np.int64)
    out[0] = low
    n = 1
    for i in order:
        if i != low:
            out[n] = i
            n += 1
    return out


@njit(nogil=True, cache=True)
def interp_extrema_lines(
    node_r: np.ndarray,
    pass_w: np.ndarray,
    exact_w: np.ndarray,
    n_passes: np.ndarray,
    node_offset: int,
    ppf: int,
    eval_start: int,
    rc: float,
    z: np.ndarray,
    inside: np.ndarray,
    ext: np.ndarray,
) -> int:  # noqa: E501  # pragma: no cover - jit
    """Extremes of the interpolation-only error d = z − z_exact [µm] (model §6) over the
    ``inside`` evaluation nodes of a batch of lines, z_exact being the envelope (§5) of the
    exact commands ``exact_w`` on the grid of :func:`envelope_lines` (same arguments; ``z``
    the envelope of ``pass_w``). Added into ``ext`` = [min, max] [µm] in place; lines that
    provably cannot extend it are skipped (see above), so the result is that of every line.
    Returns the number of lines whose exact envelope was evaluated."""
    n_lines = node_r.shape[0] // 2
    if n_lines == 0:
        return 0
    pos, we, stack, breaks = _line_scratch(pass_w.shape[1])
    first = eval_start
    lo_b = np.empty(n_lines)
    hi_b = np.empty(n_lines)
    scale = rc
    for line in range(n_lines):
        lo_b[line], hi_b[line], s = _line_difference_range(
            node_r, pass_w, exact_w, n_passes, node_offset, ppf, line, rc
        )
        scale = max(scale, s)
    tol = _BOUND_TOL_UM + _BOUND_TOL_REL * scale
    evaluated = 0
    for line in _evaluation_order(lo_b, hi_b):
        if not _worth_evaluating(lo_b[line], hi_b[line], tol, ext):
            continue
        evaluated += 1
        own, opp = 2 * line, 2 * line + 1
        n = _line_passes(node_r, exact_w, n_passes, node_offset, ppf, line, pos, we)
        last_opp, last_own = _line_span(node_r, first, line)
        n_arcs = _hull(pos[:n], we[:n], rc, stack, breaks)
        m = 0
        for j in range(first, last_opp):
            if inside[opp, j] and not math.isnan(z[opp, j]):
                ze, m = _arc_at(-node_r[opp, j], m, n_arcs, pos, we, rc, stack, breaks)
                ext[0] = min(ext[0], z[opp, j] - ze)
                ext[1] = max(ext[1], z[opp, j] - ze)
        for j in range(last_own - 1, first - 1, -1):
            if inside[own, j] and not math.isnan(z[own, j]):
                ze, m = _arc_at(node_r[own, j], m, n_arcs, pos, we, rc, stack, breaks)
                ext[0] = min(ext[0], z[own, j] - ze)
                ext[1] = max(ext[1], z[own, j] - ze)
    return evaluated


@njit(nogil=True, cache=True)
def interp_extrema_rows(
    pos: np.ndarray,
    pass_w: np.ndarray,
    exact_w: np.ndarray,
    n_valid: np.ndarray,
    rc: float,
    query: np.ndarray,
    z: np.ndarray,
    inside: np.ndarray,
    ext: np.ndarray,
) -> int:  # pragma: no cover - jit
    """:func:`interp_extrema_lines` for rows whose passes are given directly, on the grid of
    :func:`envelope_rows` (same ``pos``, ``n_valid``, ``rc``, ``query``; ``z`` the envelope
    of ``pass_w``): the extremes of d = z − z_exact [µm] over the ``inside`` nodes into
    ``ext`` = [min, max] in place. Returns the number of rows evaluated."""
    n_rows, kmax = pos.shape
    if n_rows == 0:
        return 0
    lo_b = np.empty(n_rows)
    hi_b = np.empty(n_rows)
    scale = rc
    for a in range(n_rows):
        q_lo, q_hi = math.inf, -math.inf
        for q in range(query.shape[1]):
            if not math.isnan(query[a, q]):
                q_lo = min(q_lo, query[a, q])
                q_hi = max(q_hi, query[a, q])
        lo_b[a], hi_b[a], s = _difference_range(pos[a], pass_w[a], exact_w[a], n_valid[a], rc, q_lo, q_hi)
        scale = max(scale, s)
    tol = _BOUND_TOL_UM + _BOUND_TOL_REL * scale
    stack = np.empty(kmax, dtype=np.int64)
    breaks = np.empty(kmax)
    evaluated = 0
    for a in _evaluation_order(lo_b, hi_b):
        n = n_valid[a]
        if n == 0 or not _worth_evaluating(lo_b[a], hi_b[a], tol, ext):
            continue
        evaluated += 1
        p, ww, n_arcs = _row_arcs(pos, exact_w, a, n, rc, stack, breaks)
        m = 0
        for q in range(query.shape[1]):
            r = query[a, q]
            if math.isnan(r) or not inside[a, q] or math.isnan(z[a, q]):
                continue
            ze, m = _arc_at(r, m, n_arcs, p, ww, rc, stack, breaks)
            ext[0] = min(ext[0], z[a, q] - ze)
            ext[1] = max(ext[1], z[a, q] - ze)
    return evaluated
