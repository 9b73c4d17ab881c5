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
from ftsweep.store.cube import CASE_NUMBER, DONE
from ftsweep.store.storage import PathLike
from ftsweep.store.values import case_name, value_text


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


def case_numbers(ds: xr.Dataset) -> np.ndarray:
    """The case number of every case, in flat (C) order: the cube's ``case_number`` variable
    (:data:`CASE_NUMBER`), or the flat index in a cube made before cubes carried one (never
    grown since: growth writes the variable)."""
    if CASE_NUMBER in ds:
        return np.asarray(ds[CASE_NUMBER].values).ravel().astype(np.int64)
    return np.arange(int(ds["status"].size), dtype=np.int64)


def flat_of(ds: xr.Dataset, number: int) -> int:
    """The flat (C-order) index in this cube of case number ``number``."""
    hits = np.flatnonzero(case_numbers(ds) == int(number))
    if hits.size != 1:
        raise ValueError(f"the cube has no case number {number}")
    return int(hits[0])


def coordinates_of(ds: xr.Dataset, flat: int) -> dict[str, Any]:
    """The coordinates of the case at flat index ``flat``: ``{axis: value}`` in the cube's
    axis order, numbers as Python numbers, names as text."""
    return {d: _plain(ds[d].values[i]) for d, i in position(ds, flat).items()}


def find_case(ds: xr.Dataset, text: str) -> int:
    """The flat index of the case ``text`` names: its coordinates (``points=950000
    aspect=16``, separated by spaces or commas; every axis of the cube, values as the cube
    holds them) or its case number (``66``). A ValueError names what does not match."""
    text = text.strip()
    if text.lstrip("-").isdigit():
        try:
            return flat_of(ds, int(text))
        except ValueError:
            numbers = case_numbers(ds)
            raise ValueError(
                f"the cube has no case number {text} (its numbers run {numbers.min()}..{numbers.max()}; "
                "or name the case by its coordinates, e.g. " + case_name(coordinates_of(ds, 0)) + ")"
            ) from None
    axes = [str(d) for d in ds["status"].dims]
    given: dict[str, str] = {}
    for part in text.replace(",", " ").split():
        axis, sep, value = part.partition("=")
        if not sep or axis not in axes:
            raise ValueError(
                f"--case {text!r}: {part!r} is not AXIS=VALUE of this cube's axes ({', '.join(axes)})"
            )
        given[axis] = value
    missing = [a for a in axes if a not in given]
    if missing:
        raise ValueError(
            f"--case {text!r} names no value of {', '.join(missing)} (every axis: {', '.join(axes)})"
        )
    at = {axis: _axis_position(ds, axis, value) for axis, value in given.items()}
    return int(np.ravel_multi_index(tuple(at[a] for a in axes), ds["status"].shape))


def _axis_position(ds: xr.Dataset, axis: str, value: str) -> int:
    """Where ``value`` (text) lies on the cube's ``axis``, or a ValueError listing its values."""
    values = ds[axis].values
    if values.dtype.kind in "OUS":
        hits = np.flatnonzero(values.astype(str) == value)
    else:
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        hits = np.flatnonzero(np.isclose(values.astype(float), number, rtol=1e-9, atol=0.0))
    if hits.size != 1:
        shown = ", ".join(value_text(_plain(v)) for v in values[:12]) + (" ..." if values.size > 12 else "")
        raise ValueError(f"the cube's axis {axis} has no value {value} (its values: {shown})")
    return int(hits[0])


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


def rows_axis(ds: xr.Dataset) -> str:
    """The axis a cube's best cases are listed over: its point counts, or a spiral cube's rule
    axis (its first dimension)."""
    return "points" if "points" in ds.dims else str(ds["status"].dims[0])


def best_per_points(ds: xr.Dataset) -> list[tuple[float, Optional[int]]]:
    """For each target point count: (target, flat index of its best eligible case or None);
    for a spiral cube, for each value of its rule axis (its first dimension)."""
    axis = rows_axis(ds)
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
    """The case at flat index ``flat``: its name (``name``, :func:`case_name`), its case number
    (``index``: the same case however the cube grows, :data:`CASE_NUMBER`), its coordinates
    (``<axis>_target``) and key results."""
    pos = position(ds, flat)
    point = ds.isel(pos)
    out: dict[str, Any] = {"name": case_name(coordinates_of(ds, flat)), "index": int(case_numbers(ds)[flat])}
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
    whether the cube has an aspect axis (a table sweep) to name the best α by; ``axis`` names
    the axis the rows run over (``points``, or a spiral cube's rule axis, e.g. ``chord_um``)."""
    ds = cube.open_dataset(path).load()
    axis = rows_axis(ds)
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
                    "name": None,
                    "axis": axis,
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
                "index": case["index"],
                "name": case["name"],
                "axis": axis,
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
