"""``ftsweep estimate``: the first-order P-V of every layout of a sweep plane in milliseconds
(model §3, §5; :mod:`ftsweep.stages.layouts.estimate`), and its measured agreement with a simulated
cube. The estimate never replaces the simulation: it seeds and prunes it."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ftsweep.engine.case import program_request
from ftsweep.inputs import catalogs
from ftsweep.kinds.table.layout import build_layout
from ftsweep.stages.layouts import estimate as est


def second_derivatives(
    surface_spec: Any, kind: str, folder: Path | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Sampled second derivatives of the surface along the table coordinates of ``kind``."""
    surface = catalogs.surface_callable(surface_spec, folder)
    aperture = catalogs.aperture_of(surface_spec)
    if kind == "ring":
        return est.ring_second_derivatives(surface, aperture)
    return est.mesh_second_derivatives(surface, aperture)


def pitches(surface_spec: Any, kind: str, points: float, aspect: float) -> tuple[float, float, int]:
    """(pitch 1, pitch 2, realised N) of the layout for target (N, α), in the estimate's
    coordinates: (Δρ µm, Δθ rad) for rings, (Δx, Δy) µm for meshes; NaN if it cannot be built."""
    try:
        layout = build_layout(surface_spec, program_request(kind=kind, points=points, aspect=aspect))
    except ValueError:
        return math.nan, math.nan, 0
    second = math.radians(layout.pitch[1]) if layout.periodic else layout.pitch[1]
    return layout.pitch[0], second, layout.n_points


def interp_plane(
    surface_spec: Any, kind: str, points: np.ndarray, aspects: np.ndarray, folder: Path | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(first-order interpolation span [nm], realised N) of every (N, α) of the plane
    ``points`` × ``aspects``; NaN and 0 where the layout cannot be built."""
    d11, d22 = second_derivatives(surface_spec, kind, folder)
    p1 = np.empty((points.size, aspects.size))
    p2 = np.empty_like(p1)
    n_points = np.zeros(p1.shape, dtype=np.int64)
    for i, n in enumerate(points):
        for j, a in enumerate(aspects):
            p1[i, j], p2[i, j], n_points[i, j] = pitches(surface_spec, kind, float(n), float(a))
    span = est.interp_span_nm(d11, d22, np.nan_to_num(p1), np.nan_to_num(p2))
    span[~np.isfinite(p1)] = np.nan
    return span, n_points


def seed_layout(
    surface_spec: Any,
    kind: str,
    tolerance_nm: float,
    capacity: int,
    cusp_nm: float,
    aspect_range: tuple[float, float],
    folder: Path | None = None,
) -> tuple[float, float, float]:
    """Where a tolerance search should start: (target N, α, estimated P-V [nm]) of the fewest
    points whose estimated P-V meets ``tolerance_nm``, at the estimated best aspect ratio of
    that count (or the best layout at the capacity when none does)."""
    points = np.geomspace(1e3, float(capacity), 80)
    aspects = np.geomspace(aspect_range[0], aspect_range[1], 161)
    span, n_points = interp_plane(surface_spec, kind, points, aspects, folder)
    pv = np.where(n_points <= capacity, span + cusp_nm, np.nan)
    best = np.nanmin(np.where(np.isfinite(pv), pv, np.inf), axis=1)
    meets = np.flatnonzero(best <= tolerance_nm)
    i = int(meets[0]) if meets.size else int(np.argmin(best))
    j = int(np.argmin(np.where(np.isfinite(pv[i]), pv[i], np.inf)))
    return float(points[i]), float(aspects[j]), float(pv[i, j])


def estimate_sweep(spec: Any, coords: Mapping[str, np.ndarray], folder: Path | None = None) -> xr.Dataset:
    """The estimated P-V [nm] over the sweep's (points, aspect[, feed_um, nose_radius_um]) axes:
    a sweep spec (:class:`ftsweep.sweeps.spec.SweepSpec`) and its cube's coordinates."""
    assert spec.layout is not None
    surface_spec = catalogs.entry("surfaces", spec.surface, folder)
    cutting = catalogs.entry("cutting", spec.cutting, folder)
    pts, asp = coords["points"], coords["aspect"]
    interp, n_points = interp_plane(surface_spec, spec.layout, pts, asp, folder)
    feeds = coords.get("feed_um", np.array([cutting.feed_um]))
    radii = coords.get("nose_radius_um", np.array([cutting.nose_radius_um]))
    cusp = np.array([[est.cusp_nm(f, r) for r in radii] for f in feeds])
    pv = interp[:, :, None, None] + cusp[None, None, :, :]
    dims = ["points", "aspect", "feed_um", "nose_radius_um"]
    ds = xr.Dataset(
        {
            "pv_estimate_nm": (dims, pv, {"units": "nm", "long_name": "first-order estimate of P-V"}),
            "interp_estimate_nm": (
                dims[:2],
                interp,
                {"units": "nm", "long_name": "first-order span of the bilinear interpolation error"},
            ),
            "n_points": (
                dims[:2],
                n_points,
                {"units": "1", "long_name": "realised number of control points"},
            ),
        },
        coords={"points": pts, "aspect": asp, "feed_um": feeds, "nose_radius_um": radii},
        attrs={"surface": spec.surface, "layout": spec.layout},
    )
    drop = [d for d in ("feed_um", "nose_radius_um") if d not in coords]
    return ds.isel({d: 0 for d in drop}, drop=True)
