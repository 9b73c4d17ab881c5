"""A path program as its controller commands it, read from a file rather than planned
(docs/controllers.md, "Predicting any program"): any lathe path of C [rad], X [µm] and the tool
tip's Z [µm] in one or several cuts, its feed varying, its spindle either way, its segments
linear or cubic (PVT, SPLINE1), and where it crosses the simulator's rays (model §5). No
spiral of constant feed is assumed: the envelope stage takes every pass the path makes over
a ray, as it does for a D path's cuts ([5]).
"""

from __future__ import annotations

import math
from typing import NamedTuple, Optional

import numpy as np

from ftsweep.stages.interpolation import rays, timed_path


class CommandedPath(NamedTuple):
    """A program's path in the simulator's units.

    angle : (N,) the tool's polar angle on the part [rad], ``sense`` × C, increasing within
        each cut.
    rho : (N,) its radius [µm] (X).
    starts : (cuts,) the first point of each cut, 0 first; the segment into a cut's first
        point is an approach, never cut.
    sense : +1 for C increasing (the part's angle θ = C), −1 for C decreasing (θ = −C).
    tangents : (N − 1, 6) the cubic segments' tangents of the channels angle, ρ and Z [units
        per segment] (PVT, SPLINE1), or None for linear segments.
    seconds : (N − 1,) segment times [s] (NaN into a cut's first point).
    """

    kind: str
    angle: np.ndarray
    rho: np.ndarray
    starts: np.ndarray
    sense: float
    interpolation: str
    tangents: Optional[np.ndarray]
    seconds: np.ndarray

    @property
    def n_points(self) -> int:
        return int(self.angle.size)

    def cuts(self) -> list[tuple[int, int]]:
        """(first, stop) point indices of every cut."""
        edges = [*self.starts.tolist(), self.n_points]
        return list(zip(edges[:-1], edges[1:], strict=True))

    def feeds(self) -> np.ndarray:
        """The radial advance per revolution [µm] at every point that has a point a
        revolution on in its cut: |ρ(φ) − ρ(φ + 2π)|, ρ linear in φ between points."""
        out = []
        for lo, hi in self.cuts():
            a, r = self.angle[lo:hi], self.rho[lo:hi]
            on = a + 2.0 * math.pi <= a[-1]
            out.append(np.abs(r[on] - np.interp(a[on] + 2.0 * math.pi, a, r)))
        return np.concatenate(out) if out else np.empty(0)

    @property
    def feed_um(self) -> float:
        """The median feed per revolution [µm] (:meth:`feeds`; one cut's mean drop per
        revolution for a path of less than a revolution)."""
        f = self.feeds()
        if f.size:
            return float(np.median(f))
        lo, hi = self.cuts()[0]
        turns = (self.angle[hi - 1] - self.angle[lo]) / (2.0 * math.pi)
        return float(abs(self.rho[hi - 1] - self.rho[lo]) / turns) if turns > 0 else math.nan

    @property
    def feed_max_um(self) -> float:
        """The largest feed per revolution [µm] but for the 1 % of points of least regular
        motion (a lead-in block that jumps across the part is not a revolution's feed)."""
        f = self.feeds()
        return float(np.quantile(f, 0.99)) if f.size else self.feed_um

    @property
    def rho0_um(self) -> float:
        return float(self.rho.max())

    @property
    def revolutions(self) -> float:
        return float(sum(self.angle[hi - 1] - self.angle[lo] for lo, hi in self.cuts()) / (2.0 * math.pi))

    @property
    def dphi_deg(self) -> float:
        steps = np.concatenate([np.diff(self.angle[lo:hi]) for lo, hi in self.cuts()])
        return float(np.degrees(np.median(steps))) if steps.size else math.nan

    @property
    def ds_um(self) -> float:
        steps = [
            np.hypot(
                np.diff(self.rho[lo:hi]),
                0.5 * (self.rho[lo + 1 : hi] + self.rho[lo : hi - 1]) * np.diff(self.angle[lo:hi]),
            )
            for lo, hi in self.cuts()
        ]
        s = np.concatenate(steps)
        return float(np.mean(s)) if s.size else math.nan

    @property
    def aspect(self) -> float:
        return self.feed_um / self.dphi_deg

    @property
    def max_points_per_rev(self) -> int:
        return int(math.ceil(360.0 / self.dphi_deg)) if self.dphi_deg > 0 else 0


def crossings(
    path: CommandedPath, z_um: np.ndarray, theta: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every pass of every cut over the rays at the part's angles ``theta`` [rad] (model §5):
    radius [µm] and Z [µm] of each, sorted by radius along each ray (NaN padding last), and the
    number of passes per ray. A cut crosses a ray once per revolution (linear segments as
    :func:`ftsweep.stages.interpolation.rays.crossings`, cubic ones as
    :func:`ftsweep.stages.interpolation.timed_path.crossings`); a radius below zero (the tool
    past the centre) is not a pass over the ray."""
    q = path.sense * np.asarray(theta, dtype=np.float64)
    pos_parts, w_parts = [], []
    for lo, hi in path.cuts():
        if hi - lo < 2:
            continue
        a = path.angle[lo:hi]
        if path.tangents is None:
            pos, w, _ = rays.crossings(a, path.rho[lo:hi], z_um[lo:hi], q)
        else:
            chan = np.column_stack([a, path.rho[lo:hi], z_um[lo:hi]])
            pos, w, _ = timed_path.crossings(a, chan, path.tangents[lo : hi - 1], q)
        pos_parts.append(pos)
        w_parts.append(w)
    pos = np.concatenate(pos_parts, axis=1)
    w = np.concatenate(w_parts, axis=1)
    pos[~(pos >= 0.0)] = np.nan
    order = np.argsort(np.where(np.isnan(pos), np.inf, pos), axis=1)
    pos = np.take_along_axis(pos, order, axis=1)
    w = np.take_along_axis(w, order, axis=1)
    return pos, w, np.isfinite(pos).sum(axis=1).astype(np.int64)
