"""Tool-nose compensation along sampled radial sections (model §4): the commands of a tool
pass at each node of a ray, from the section's heights and slopes on a regular grid of
nodes (exact by a climb over the grid with a parabolic refinement, slope, or none), for the
line engine. Lengths in µm, slopes dimensionless."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit


@njit(nogil=True, cache=True)
def _lift_table(spacing_um: float, nose_radius_um: float) -> np.ndarray:  # pragma: no cover - jit
    """arc(j·spacing) = Rc − sqrt(Rc² − (j·spacing)²) [µm] for j = 0 … Rc/spacing − 1: the
    arc heights at the grid's offsets, computed once instead of at every hill-climbing step."""
    rc = nose_radius_um
    jmax = int(rc / spacing_um) - 1
    lift = np.empty(max(jmax, 0) + 2)
    for j in range(lift.size):
        d = j * spacing_um
        lift[j] = rc - math.sqrt(max(rc * rc - d * d, 0.0))
    return lift


@njit(nogil=True, cache=True)
def _on_ray(
    g: np.ndarray,
    gp: np.ndarray,
    spacing_um: float,
    rc: float,
    nodes: np.ndarray,
    mode: int,
    lift: np.ndarray,
    out: np.ndarray,
    from_passes: bool,
) -> None:  # pragma: no cover - jit
    """:func:`compensate_on_ray` with the arc heights ``lift`` of :func:`_lift_table`."""
    n_nodes = g.size
    jmax = int(rc / spacing_um) - 1
    per_node = 1.0 / spacing_um
    # the contact offsets of the last two passes, whose line predicts the next one's
    j1 = j2 = 0
    for p in range(nodes.size):
        n = nodes[p]
        if mode == 2:
            out[p] = g[n]
            continue
        if mode == 1:
            out[p] = g[n] + rc * (math.sqrt(1.0 + gp[n] * gp[n]) - 1.0)
            continue
        jlo = max(-jmax, -n)
        jhi = min(jmax, n_nodes - 1 - n)
        if from_passes and p >= 2:
            # consecutive passes touch at offsets that change smoothly, so the line through
            # the last two lands on (or next to) the contact: ~0.3 steps a pass on the
            # reference mesh and ring cases, where the slope's prediction below misses by
            # several nodes on a curved section (the contact moves by Rc·g'·K·Rc/(1 − K·Rc))
            # and each miss costs the climb a mispredicted branch
            j = 2 * j1 - j2
        else:
            j = int(math.floor(0.5 - _slope_offset(gp[n], rc) * per_node))
        # either start only starts the climb, which ends on the same sample from any start on
        # a single-peaked section
        j, out[p] = _climb(g, lift, n, min(max(j, jlo), jhi), jlo, jhi)
        j2, j1 = j1, j


@njit(nogil=True, cache=True, inline="always")
def _slope_offset(q: float, rc: float) -> float:  # pragma: no cover - jit
    """The contact offset s = rc·sinβ [µm] the slope q predicts: outwards (s > 0, smaller n)
    where g rises outwards. Below slope 1/4 the series of β's sine stands in for the square
    root and division (within 2e-5·Rc of it: 2 nm at Rc 83 µm, a fraction of a node)."""
    q2 = q * q
    if q2 < 0.0625:
        return rc * q * (1.0 - q2 * (0.5 - 0.375 * q2))
    return rc * q / math.sqrt(1.0 + q2)


@njit(nogil=True, cache=True, inline="always")
def _climb(
    g: np.ndarray, lift: np.ndarray, n: int, j: int, jlo: int, jhi: int
) -> tuple[Any, ...]:  # pragma: no cover - jit
    """The highest h_j = g[n + j] − lift[|j|] reached by climbing from offset ``j`` within
    [jlo, jhi], refined by the parabola through its neighbours: (j, w [µm])."""
    hj = g[n + j] - lift[abs(j)]
    # the neighbours' h at the final j are what the climb compared last: kept for the
    # parabola instead of evaluated again
    while True:
        hp = g[n + j + 1] - lift[abs(j + 1)] if j + 1 <= jhi else -math.inf
        if hp > hj:
            j += 1
            hj = hp
            continue
        hm = g[n + j - 1] - lift[abs(j - 1)] if j - 1 >= jlo else -math.inf
        if hm > hj:
            j -= 1
            hj = hm
            continue
        break
    if jlo < j < jhi:
        curv = hm - 2.0 * hj + hp
        if curv < 0.0:
            return j, hj - (hp - hm) * (hp - hm) / (8.0 * curv)
    return j, hj


@njit(nogil=True, cache=True)
def compensate_on_ray(
    g: np.ndarray,
    gp: np.ndarray,
    spacing_um: float,
    nose_radius_um: float,
    nodes: np.ndarray,
    mode: int,
    out: np.ndarray,
    from_passes: bool,
) -> None:  # noqa: E501  # pragma: no cover - jit
    """Control values along one sampled radial section (model §4), in place.

    g, gp : section height [µm] and radial slope [-] at nodes r_n = r_0 − n·spacing.
    spacing_um : node spacing [µm] (positive; node index grows inwards).
    nodes : int64 node indices of the tool passes whose commands are wanted, in order.
    mode : 0 exact, 1 slope, 2 none (see ``MODE_CODES``).
    out : float64 array receiving w [µm] for each entry of ``nodes``.
    from_passes : start each climb (after the first two) on the line through the last two
        passes' contacts instead of the slope-predicted contact; only where the section is
        single-peaked (curvature below 1/Rc), where every start ends on the same sample.

    For ``exact`` the sampled h_j = g[n+j] − arc(j·spacing) is hill-climbed from the start
    and refined by the parabola through the best three samples.
    """
    lift = _lift_table(spacing_um, nose_radius_um)
    _on_ray(g, gp, spacing_um, nose_radius_um, nodes, mode, lift, out, from_passes)


@njit(nogil=True, cache=True)
def _commands_kernel(
    g: np.ndarray,
    gp: np.ndarray,
    spacing_um: float,
    rc: float,
    pass_nodes: np.ndarray,
    n_passes: np.ndarray,
    mode: int,
    from_passes: bool,
    out: np.ndarray,
) -> None:  # noqa: E501  # pragma: no cover - jit
    lift = _lift_table(spacing_um, rc)
    for a in range(g.shape[0]):
        k = n_passes[a]
        _on_ray(g[a], gp[a], spacing_um, rc, pass_nodes[:k], mode, lift, out[a, :k], from_passes)


def commands_on_rays(
    g: np.ndarray,
    gp: np.ndarray,
    spacing_um: float,
    nose_radius_um: float,
    pass_nodes: np.ndarray,
    n_passes: np.ndarray,
    mode: int,
    single_peaked: bool = False,
) -> np.ndarray:
    """Commands w [µm] at every pass of every ray of a path grid (model §4): the section
    samples ``g``, ``gp`` (R, G) along each ray, the passes at node indices ``pass_nodes``
    (Kmax,), the same on every ray, ``n_passes`` (R,) of them on each ray. Returns (R, Kmax),
    NaN past the passes. ``single_peaked``: the caller knows every section's h to be
    single-peaked (the surface's curvature bound below 1/Rc), so each climb may start from the
    passes before it (:func:`compensate_on_ray`); the same commands, found in fewer steps."""
    out = np.full((g.shape[0], pass_nodes.size), np.nan)
    _commands_kernel(
        np.ascontiguousarray(g),
        np.ascontiguousarray(gp),
        float(spacing_um),
        float(nose_radius_um),
        np.ascontiguousarray(pass_nodes, dtype=np.int64),
        np.ascontiguousarray(n_passes, dtype=np.int64),
        int(mode),
        bool(single_peaked),
        out,
    )
    return out
