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
from ftsweep.store.cube import DONE
from ftsweep.store.storage import PathLike


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


def best_per_point_count(path: PathLike) -> list[dict[str, Any]]:
    """For each target point count: its best eligible case, the one ``select`` and
    ``ds.ftsweep.optimum()`` name too (None where no case is eligible); ``swept_aspect`` says
    whether the cube has an aspect axis (a table sweep) to name the best α by."""
    ds = cube.open_dataset(path).load()
    rows = []
    for target, flat in best_per_points(ds):
        if flat is None:
            rows.append(
                {
                    "points": target,
                    "aspect": None,
                    "pv_nm": None,
                    "n_points": None,
                    "index": None,
                    "swept_aspect": "aspect" in ds.dims,
                }
            )
            continue
        case = describe(ds, flat)
        rows.append(
            {
                "points": target,
                # a table sweep's aspect axis; path programs have none worth naming
                "aspect": case.get("aspect_target"),
                "swept_aspect": "aspect" in ds.dims,
                "pv_nm": case["pv_nm"],
                "n_points": case["n_points"],
                "index": flat,
            }
        )
    return rows


def best_aspect(pv: xr.DataArray) -> xr.DataArray:
    """The aspect ratio of the lowest P-V at each point count (NaN where none is finite)."""
    filled = pv.fillna(np.inf)
    index = filled.argmin("aspect")
    best = pv["aspect"].isel(aspect=index).where(np.isfinite(filled.min("aspect")))
    return best.drop_vars("aspect", errors="ignore")


def agreement(estimate: xr.Dataset, cube: xr.Dataset) -> dict[str, Any]:
    """How the estimate compares with a simulated cube of the same axes: the ratio
    estimate/simulated P-V over every computed case, and the aspect optimum per point count."""
    sim = cube["pv_nm"].where(cube["status"] == DONE)
    pv_est = estimate["pv_estimate_nm"].reindex_like(sim)  # the same sweep: the same coordinates
    ratio = (pv_est / sim).values.ravel()
    ratio = ratio[np.isfinite(ratio)]
    a_est = best_aspect(pv_est)
    a_sim = best_aspect(sim)
    quotient = a_est / a_sim
    factor = xr.where(quotient >= 1.0, quotient, 1.0 / quotient).values.ravel()
    factor = factor[np.isfinite(factor)]
    return {
        "cases": int(ratio.size),
        "pv_ratio_min": float(ratio.min()) if ratio.size else math.nan,
        "pv_ratio_median": float(np.median(ratio)) if ratio.size else math.nan,
        "pv_ratio_max": float(ratio.max()) if ratio.size else math.nan,
        "within_factor_2": float(np.mean((ratio >= 0.5) & (ratio <= 2.0))) if ratio.size else math.nan,
        "optimum_aspect_factor_max": float(factor.max()) if factor.size else math.nan,
        "optimum_aspect_estimated": a_est.values.tolist(),
        "optimum_aspect_simulated": a_sim.values.tolist(),
    }
