"""One query core over result cubes: which cases may be chosen, where a case sits, and the
best case under a condition. ``select``/``export``, the sweep summary, ``report`` and the
``ds.ftsweep`` accessor all ask it, so they never disagree on what "best" means: a case that
``export`` would refuse (failed, pending, infeasible, over the controller's capacity, or
without a finite P-V) is never anyone's best.
"""

from __future__ import annotations

import json
import math
from typing import Any, Optional

import numpy as np
import xarray as xr

from ftsweep import registry
from ftsweep.store import cube


def capacity_of(ds: xr.Dataset) -> int:
    """The controller capacity [points] of the machine the cube's sweep used."""
    machines = json.loads(ds.attrs["catalog_entries"])["machine"]
    return int(next(iter(machines.values()))["capacity_points"])


def eligible(ds: xr.Dataset) -> xr.DataArray:
    """Cases that may be chosen: done, with a finite P-V, feasible for the machine's
    dynamics, and within the controller's capacity."""
    ok = (ds["status"] == cube.DONE) & (ds["n_points"] <= capacity_of(ds)) & np.isfinite(ds["pv_nm"])
    if "feasible" in ds:
        ok = ok & (ds["feasible"] == 1)
    return ok


def eligible_pv(ds: xr.Dataset) -> xr.DataArray:
    """P-V [nm] of the eligible cases, NaN elsewhere."""
    return ds["pv_nm"].where(eligible(ds))


def position(ds: xr.Dataset, flat: int) -> dict[str, int]:
    """Index along each dimension of the case at C-order flat index ``flat``."""
    shape = ds["status"].shape
    return {str(d): int(i) for d, i in zip(ds["status"].dims, np.unravel_index(flat, shape), strict=True)}


def best_flat(ds: xr.Dataset, where: Optional[xr.DataArray] = None) -> Optional[int]:
    """Flat index of the eligible case with the lowest P-V (within ``where`` if given; the
    first in C order on ties), or None if there is none."""
    pv = eligible_pv(ds)
    if where is not None:
        pv = pv.where(where)
    values = pv.values.ravel()
    if not np.any(np.isfinite(values)):
        return None
    return int(np.nanargmin(values))


def best_per_points(ds: xr.Dataset) -> list[tuple[float, Optional[int]]]:
    """For each target point count: (target, flat index of its best eligible case or None);
    for a spiral cube, for each value of its rule axis (its first dimension)."""
    axis = "points" if "points" in ds.dims else str(ds["status"].dims[0])
    index = xr.DataArray(np.arange(ds.sizes[axis]), dims=axis)
    return [(float(p), best_flat(ds, index == i)) for i, p in enumerate(ds[axis].values)]


def best_pv_over_aspect(ds: xr.Dataset) -> xr.DataArray:
    """Lowest eligible P-V [nm] over (points, aspect), every other sweep axis reduced by its
    minimum: the surface the optimum per point count is read from."""
    pv = eligible_pv(ds)
    if "aspect" not in pv.dims:
        return pv  # a spiral cube: every axis is kept
    other = [d for d in pv.dims if d not in ("points", "aspect")]
    return pv.min(other) if other else pv


def _plain(value: Any) -> Any:
    """A coordinate value as a Python float, or as str for a name."""
    return str(value) if isinstance(value, str) else float(value)


def describe(ds: xr.Dataset, flat: int) -> dict[str, Any]:
    """The coordinates (``<axis>_target``) and key results of the case at flat index ``flat``."""
    pos = position(ds, flat)
    point = ds.isel(pos)
    out: dict[str, Any] = {"index": int(flat)}
    # a named axis (the compensation) keeps its names
    out.update({f"{d}_target": _plain(ds[d].values[i]) for d, i in pos.items()})
    layout = ds.attrs.get("layout_method", "")
    names = registry.kind(layout).pitches
    out["layout"] = layout
    out["n_points"] = int(point["n_points"])
    out[names[0]] = float(point[names[0]])
    out[names[1]] = float(point[names[1]])
    # a D path has no pitch aspect
    out["aspect_actual"] = float(point["aspect_actual"]) if "aspect_actual" in point else math.nan
    for var in ("pv_nm", "rms_nm", "pv_interp_nm", "pv_inner_nm", "pv_outer_nm"):
        out[var] = float(point[var])
    out["status"] = cube.STATUS_MEANINGS.split()[int(point["status"])]
    if "feasible" in ds:
        out["feasible"] = bool(int(point["feasible"]) == 1)
    return out
