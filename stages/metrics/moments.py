"""Error and metrics (model §6).

The form error e = z − f is reduced batch by batch into a small vector of running
statistics (:data:`STAT_NAMES`), so a case never holds the whole evaluation grid; batches
combine with :func:`merge_stats` in any order and :func:`finalize` turns the result into
the reported metrics in nm.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

STAT_NAMES = (
    "count",
    "sum",
    "sum_sq",
    "min",
    "max",
    "inner_min",
    "inner_max",
    "outer_min",
    "outer_max",
    "interp_min",
    "interp_max",
    "inner_count",
    "outer_count",
)
# named slots of the statistics vector (module constants, which numba compiles in)
(
    COUNT,
    SUM,
    SUM_SQ,
    MIN,
    MAX,
    INNER_MIN,
    INNER_MAX,
    OUTER_MIN,
    OUTER_MAX,
    INTERP_MIN,
    INTERP_MAX,
    INNER_COUNT,
    OUTER_COUNT,
) = range(len(STAT_NAMES))
_N = len(STAT_NAMES)
# the extremes of the interpolation-only error, [min, max]: a view the envelope's
# :func:`ftsweep.stages.envelope.arcs.interp_extrema_lines` updates in place
INTERP = slice(INTERP_MIN, INTERP_MAX + 1)
assert INTERP_MAX == INTERP_MIN + 1
_MIN_SLOTS = np.array([MIN, INNER_MIN, OUTER_MIN, INTERP_MIN])
_MAX_SLOTS = np.array([MAX, INNER_MAX, OUTER_MAX, INTERP_MAX])
_SUM_SLOTS = np.array([COUNT, SUM, SUM_SQ, INNER_COUNT, OUTER_COUNT])


def empty_stats() -> np.ndarray:
    """Statistics of an empty set (neutral element of :func:`merge_stats`)."""
    s = np.zeros(_N)
    s[_MIN_SLOTS] = np.inf
    s[_MAX_SLOTS] = -np.inf
    return s


def merge_stats(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Combine two statistics vectors (associative and commutative)."""
    out = a.copy()
    out[_SUM_SLOTS] += b[_SUM_SLOTS]
    out[_MIN_SLOTS] = np.minimum(a[_MIN_SLOTS], b[_MIN_SLOTS])
    out[_MAX_SLOTS] = np.maximum(a[_MAX_SLOTS], b[_MAX_SLOTS])
    return out


@njit(nogil=True, cache=True)
def accumulate(
    z: np.ndarray,
    g: np.ndarray,
    inside: np.ndarray,
    node_r: np.ndarray,
    zone_split_um: float,
    stats: np.ndarray,
) -> None:  # pragma: no cover - jit
    """Add the form errors of one batch of node grids to ``stats`` in place (model §6); the
    interpolation-only error's extremes come from the envelope
    (:func:`ftsweep.stages.envelope.arcs.interp_extrema_lines`).

    z : (R, G) machined height [µm], NaN off the evaluation nodes.
    g : (R, G) design height f at the nodes [µm].
    inside : (R, G) bool, node inside the aperture.
    node_r : (R, G) node radius [µm] (its sign ignored); nodes with |r| ≤ ``zone_split_um``
        form the inner zone.
    stats : float64 vector laid out as :data:`STAT_NAMES`; errors are accumulated in µm.
    """
    # running values live in locals, not in ``stats``: the compiler cannot keep array slots
    # in registers across iterations, and the sums are added in the same order as before,
    # so the result is the same to the last bit
    count, total, total_sq = stats[COUNT], stats[SUM], stats[SUM_SQ]
    lo, hi = stats[MIN], stats[MAX]
    in_lo, in_hi, in_n = stats[INNER_MIN], stats[INNER_MAX], stats[INNER_COUNT]
    out_lo, out_hi, out_n = stats[OUTER_MIN], stats[OUTER_MAX], stats[OUTER_COUNT]
    n_rays, n_nodes = z.shape
    for a in range(n_rays):
        for j in range(n_nodes):
            zz = z[a, j]
            if not inside[a, j] or math.isnan(zz):
                continue
            e = zz - g[a, j]
            count += 1.0
            total += e
            total_sq += e * e
            lo = min(lo, e)
            hi = max(hi, e)
            if abs(node_r[a, j]) <= zone_split_um:
                in_lo = min(in_lo, e)
                in_hi = max(in_hi, e)
                in_n += 1.0
            else:
                out_lo = min(out_lo, e)
                out_hi = max(out_hi, e)
                out_n += 1.0
    stats[COUNT], stats[SUM], stats[SUM_SQ] = count, total, total_sq
    stats[MIN], stats[MAX] = lo, hi
    stats[INNER_MIN], stats[INNER_MAX], stats[INNER_COUNT] = in_lo, in_hi, in_n
    stats[OUTER_MIN], stats[OUTER_MAX], stats[OUTER_COUNT] = out_lo, out_hi, out_n


@njit(nogil=True, cache=True)
def accumulate_extrema(
    z: np.ndarray, f: np.ndarray, inside: np.ndarray, r: np.ndarray, zone_split_um: float, stats: np.ndarray
) -> None:  # pragma: no cover - jit
    """Add points that bound the error but are not area samples (the cusp peaks) to the
    extrema of ``stats`` only: min/max and zone min/max, not count, mean or RMS.

    z, f : machined and design heights [µm] (NaN entries are skipped); inside : bool;
    r : radius [µm]; all 2-D of one shape.
    """
    # running extremes in locals, as in :func:`accumulate` (min and max do not depend on order)
    lo, hi = stats[MIN], stats[MAX]
    in_lo, in_hi = stats[INNER_MIN], stats[INNER_MAX]
    out_lo, out_hi = stats[OUTER_MIN], stats[OUTER_MAX]
    for a in range(z.shape[0]):
        for c in range(z.shape[1]):
            if not inside[a, c] or math.isnan(z[a, c]) or math.isnan(f[a, c]):
                continue
            e = z[a, c] - f[a, c]
            lo = min(lo, e)
            hi = max(hi, e)
            if r[a, c] <= zone_split_um:
                in_lo = min(in_lo, e)
                in_hi = max(in_hi, e)
            else:
                out_lo = min(out_lo, e)
                out_hi = max(out_hi, e)
    stats[MIN], stats[MAX] = lo, hi
    stats[INNER_MIN], stats[INNER_MAX] = in_lo, in_hi
    stats[OUTER_MIN], stats[OUTER_MAX] = out_lo, out_hi


@njit(nogil=True, cache=True)
def accumulate_map_xy(
    z: np.ndarray,
    g: np.ndarray,
    inside: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    x0: float,
    y0: float,
    bin_um: float,
    total: np.ndarray,
    count: np.ndarray,
    peak: np.ndarray,
) -> None:  # pragma: no cover - jit
    """Bin the form error e = z − g [µm] at points x, y [µm] of the part's frame (a batch of
    rays' nodes) into a coarse (y, x) map.

    Bin (iy, ix) covers x0 + ix·bin_um ≤ x < x0 + (ix+1)·bin_um (likewise y). ``total`` and
    ``count`` accumulate the sum and number of errors per bin (their ratio is the mean map);
    ``peak`` keeps the error of largest magnitude (signed), which shows where the P-V sits.
    """
    ny, nx = count.shape
    for a in range(z.shape[0]):
        for j in range(z.shape[1]):
            zz = z[a, j]
            if not inside[a, j] or math.isnan(zz):
                continue
            e = zz - g[a, j]
            ix = int(math.floor((x[a, j] - x0) / bin_um))
            iy = int(math.floor((y[a, j] - y0) / bin_um))
            if 0 <= ix < nx and 0 <= iy < ny:
                total[iy, ix] += e
                count[iy, ix] += 1.0
                if abs(e) > abs(peak[iy, ix]) or count[iy, ix] == 1.0:
                    peak[iy, ix] = e


def cusp_height_um(feed_um: float, nose_radius_um: float) -> float:
    """Feed cusp height of a flat surface, F²/(8·Rc) [µm] (model §6)."""
    return feed_um**2 / (8.0 * nose_radius_um)


def finalize(stats: np.ndarray) -> dict[str, float]:
    """Reported metrics from accumulated statistics; errors in nm (model §6).

    pv_nm = max e − min e; rms_nm is the RMS of e about its mean (piston is not a form
    error); pv_interp_nm is the P-V of z(interpolated commands) − z(exact commands); zone
    P-Vs use the inner (r ≤ split) and outer nodes. An empty set gives NaN.
    """
    s = dict(zip(STAT_NAMES, stats.tolist(), strict=True))
    n = s["count"]
    nan = float("nan")

    def pv(lo: float, hi: float) -> float:
        return (hi - lo) * 1e3 if hi >= lo else nan

    mean = s["sum"] / n if n else nan
    var = max(s["sum_sq"] / n - mean * mean, 0.0) if n else nan
    return {
        "pv_nm": pv(s["min"], s["max"]),
        "rms_nm": math.sqrt(var) * 1e3 if n else nan,
        "mean_nm": mean * 1e3,
        "error_min_nm": s["min"] * 1e3 if n else nan,
        "error_max_nm": s["max"] * 1e3 if n else nan,
        "pv_inner_nm": pv(s["inner_min"], s["inner_max"]),
        "pv_outer_nm": pv(s["outer_min"], s["outer_max"]),
        "pv_interp_nm": pv(s["interp_min"], s["interp_max"]),
        "n_eval": int(n),
    }
