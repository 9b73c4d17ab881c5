"""Where a program's path crosses the simulator's rays (model §5): the envelope stage reads
the path's radius and command Z at every crossing of a ray θ, once per revolution of the polar
angle, at θ + 2πc. One bracketing walk finds the step j of the program (from point j to
j + 1) that holds each crossing; a program's segments then give the crossing inside its step:
linear here (:func:`crossings`), cubic in time for PVT programs
(:func:`ftsweep.stages.interpolation.timed_path.crossings`). Angles in rad, lengths in µm.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit


@njit(nogil=True, cache=True, inline="always")
def step_of(angle: np.ndarray, q: float, j: int, last: int) -> int:  # pragma: no cover - jit
    """The step j (from point j to j + 1) of angles ``angle`` holding ``q``: a bisection for a
    revolution's first ray (j < 0), then a walk on from the previous ray's step. A
    revolution's rays come in increasing angle: a bisection per crossing cost 20 steps where a
    revolution holds ~500 points for ~600 rays."""
    if j < 0:
        return min(int(np.searchsorted(angle[1:], q)), last)
    while j < last and angle[j + 1] < q:
        j += 1
    return j


class RayGrid(NamedTuple):
    """The rays' angles on a program's first revolution, their order, the revolutions to
    cross, and the (R, revolutions) outputs: radius, Z [µm] and step of every crossing."""

    theta: np.ndarray
    order: np.ndarray
    n_rev: int
    pos: np.ndarray
    w: np.ndarray
    seg: np.ndarray


def ray_grid(angle: np.ndarray, ray_theta: np.ndarray) -> RayGrid:
    """The crossings to find of a program whose polar angles are ``angle`` [rad] (increasing)
    with the rays at ``ray_theta`` [rad], their steps bracketed (:func:`_bracket`; −1 where
    the program does not run); radius and Z still to be filled."""
    n_rev = int(math.ceil((angle[-1] - angle[0]) / (2.0 * math.pi))) + 2
    base = math.floor(angle[0] / (2.0 * math.pi))
    theta = np.asarray(ray_theta, dtype=np.float64) + 2.0 * math.pi * base
    shape = (theta.size, n_rev)
    order = np.argsort(theta, kind="stable")
    grid = RayGrid(theta, order, n_rev, np.empty(shape), np.empty(shape), np.empty(shape, dtype=np.int64))
    _bracket(angle, grid.theta, grid.order, grid.n_rev, grid.seg)
    return grid


@njit(nogil=True, cache=True)
def _bracket(
    angle: np.ndarray, ray_theta: np.ndarray, order: np.ndarray, n_rev: int, seg: np.ndarray
) -> None:  # pragma: no cover - jit
    """The step of every crossing at θ + 2πc, rays in increasing angle within a revolution."""
    period = 2.0 * math.pi
    lo, hi, last = angle[0], angle[-1], angle.size - 2
    for c in range(n_rev):
        j = -1
        for b in range(order.size):
            r = order[b]
            q = ray_theta[r] + period * c
            if q < lo or q > hi:
                seg[r, c] = -1
                continue
            j = step_of(angle, q, j, last)
            seg[r, c] = j


@njit(nogil=True, cache=True)
def _linear(
    phi: np.ndarray,
    rho: np.ndarray,
    z: np.ndarray,
    ray_theta: np.ndarray,
    order: np.ndarray,
    seg: np.ndarray,
    pos: np.ndarray,
    w: np.ndarray,
) -> None:  # pragma: no cover - jit
    period = 2.0 * math.pi
    for c in range(seg.shape[1]):  # a revolution at a time, rays in increasing angle: the steps
        for b in range(order.size):  # read stay in the cache, as the bracketing walk reads them
            r = order[b]
            j = seg[r, c]
            if j < 0:
                pos[r, c] = math.nan
                w[r, c] = math.nan
                continue
            q = ray_theta[r] + period * c
            s = (q - phi[j]) / (phi[j + 1] - phi[j])
            pos[r, c] = rho[j] + s * (rho[j + 1] - rho[j])
            w[r, c] = z[j] + s * (z[j + 1] - z[j])


def crossings(
    phi: np.ndarray, rho: np.ndarray, z: np.ndarray, ray_theta: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where the program passes the rays at ``ray_theta`` [rad] (model §5): once per
    revolution, at φ = θ + 2πc; the radius [µm] and Z [µm] there, linear between the program's
    points as the machine moves, and the program step j (between points j and j + 1) it falls
    in. (R, revolutions) arrays, NaN (step −1) where the program does not run."""
    phi = np.asarray(phi, np.float64)
    g = ray_grid(phi, ray_theta)
    _linear(phi, np.asarray(rho, np.float64), np.asarray(z, np.float64), g.theta, g.order, g.seg, g.pos, g.w)
    return g.pos, g.w, g.seg
