"""Choosing the layout that goes to production from a result cube.

Only eligible cases are ever chosen: computed (status done), feasible for the machine's
dynamics, and within the controller's capacity.
"""

from __future__ import annotations

import json
from typing import Any, Optional

import numpy as np
import xarray as xr

from ftsweep.inputs.case_entries import Entries
from ftsweep.store import cube
from ftsweep.store.storage import PathLike, place
from ftsweep.tools.query import best_flat, capacity_of, describe, eligible, eligible_pv, find_case, position


class SelectError(ValueError):
    """Nothing can be selected as asked; the message says why."""


def completeness(status: np.ndarray) -> Optional[str]:
    """One line saying how incomplete a cube of case ``status`` is where a choice from it
    could still change (cases pending, failed or pruned, which a run computes), or None when
    none can: done, refused and infeasible cases are final."""
    status = np.asarray(status).ravel()
    open_ = {name: int(np.sum(status == value)) for name, value in cube.UNSETTLED.items()}
    if not any(open_.values()):
        return None
    done = int(np.sum(status == cube.DONE))
    rest = ", ".join(f"{n} {name}" for name, n in open_.items() if n)
    return f"the cube is incomplete: {done} of {status.size} cases done, {rest}; the choice could change"


def check_complete(status: np.ndarray, allow: bool) -> Optional[str]:
    """Refuse (:class:`SelectError`) to choose from a cube whose case ``status`` is incomplete
    unless ``allow``; returns the line that says how incomplete it is (None when complete)."""
    note = completeness(status)
    if note is not None and not allow:
        raise SelectError(f"{note}: run the sweep to finish it, or pass --allow-incomplete to choose anyway")
    return note


def current_status(path: PathLike) -> np.ndarray:
    """The case status of the cube at ``path`` (checked to be a cube), its unmerged logs
    counted as they will be: what :func:`check_complete` reads without loading the cube."""
    at = place(path)
    if not at.exists():
        raise cube.CubeError(f"no cube at {at}")
    cube.read_attrs(at)
    from ftsweep.store import caselog

    return caselog.current_status(at)


def open_cube(path: PathLike) -> xr.Dataset:
    """Open a cube (a path or URL) for reading and load it: checks it is an ftsweep cube and
    that every chunk can be read, naming the chunks that cannot (a cube is small: a few MB)."""
    at = place(path)
    if not at.exists():
        raise cube.CubeError(f"no cube at {at}")
    cube.read_attrs(at)
    try:
        ds = cube.open_dataset(at).load()
    except Exception:  # codecs raise many types for a damaged chunk: name the files instead
        cube.check_readable(at)
        raise
    from ftsweep.store import caselog

    # cases a running (or killed) run logged but has not merged yet count as they will
    return caselog.with_logged(ds, at)


def select_budget(ds: xr.Dataset, budget_points: int) -> dict[str, Any]:
    """The eligible case with the lowest P-V among layouts of at most ``budget_points``."""
    flat = best_flat(ds, ds["n_points"] <= budget_points)
    if flat is None:
        counts = ds["n_points"].where(eligible_pv(ds).notnull()).values
        smallest = (
            f"; its smallest has {int(np.nanmin(counts)):,} points (--budget-points {int(np.nanmin(counts))})"
            if np.any(np.isfinite(counts))
            else ""
        )
        raise SelectError(
            f"no computed, feasible case has at most {budget_points:,} points in this cube{smallest}"
        )
    chosen = describe(ds, flat)
    chosen["rule"] = f"lowest P-V at or under {budget_points:,} points"
    return chosen


def select_tolerance(ds: xr.Dataset, tolerance_nm: float) -> dict[str, Any]:
    """The smallest eligible layout whose P-V meets ``tolerance_nm`` (lowest P-V on ties).

    When none meets it, the result has ``met: False`` and describes the best case found.
    """
    ok = eligible(ds).values.ravel()
    pv = ds["pv_nm"].values.ravel()
    n = ds["n_points"].values.ravel().astype(float)
    meets = ok & (pv <= tolerance_nm)
    if np.any(meets):
        # smallest N first, then lowest P-V
        order = np.lexsort((np.where(meets, pv, np.inf), np.where(meets, n, np.inf)))
        chosen = describe(ds, int(order[0]))
        chosen.update(met=True, rule=f"fewest points with P-V ≤ {tolerance_nm:g} nm")
        return chosen
    flat = best_flat(ds)
    if flat is None:
        raise SelectError("no computed, feasible case within the machine's capacity in this cube")
    best = describe(ds, flat)
    best.update(met=False, rule=f"no case meets P-V ≤ {tolerance_nm:g} nm; this is the best found")
    return best


def choose(
    ds: xr.Dataset,
    budget_points: Optional[int] = None,
    tolerance_nm: Optional[float] = None,
    index: Optional[int | str] = None,
) -> dict[str, Any]:
    """One of: a budget, a tolerance, or an explicit case (``index``: its coordinates as
    ``points=950000 aspect=16`` or its case number, :func:`~ftsweep.tools.query.find_case`)."""
    given = [v is not None for v in (budget_points, tolerance_nm, index)]
    if sum(given) != 1:
        raise SelectError("give exactly one of budget_points, tolerance_nm or index")
    if budget_points is not None:
        return select_budget(ds, budget_points)
    if tolerance_nm is not None:
        return select_tolerance(ds, tolerance_nm)
    assert index is not None
    try:
        flat = find_case(ds, str(index))
    except ValueError as exc:
        raise SelectError(str(exc)) from None
    chosen = describe(ds, flat)
    chosen["rule"] = f"case {chosen['name']} as asked"
    return chosen


def recorded_case(ds: xr.Dataset, flat: int, trust_plugins: bool = False) -> tuple[Any, Entries]:
    """The case at flat index ``flat`` of a cube and the (surface, machine, cutting) entries
    the cube recorded for it. A cube is data: a plug-in surface it names must be one of the
    local catalog's unless ``trust_plugins`` (:func:`~ftsweep.inputs.trust.specs_from_entries`)."""
    from ftsweep.freetext import TextError, check_strings
    from ftsweep.inputs.catalogs import CatalogError
    from ftsweep.inputs.trust import specs_from_entries
    from ftsweep.sweeps.spec import SweepSpec, case_at

    case = case_at(SweepSpec.model_validate_json(ds.attrs["sweep_spec"]), flat)
    entries = json.loads(ds.attrs["catalog_entries"])
    try:  # a cube's recorded text is written into what export makes: held to the same rule
        check_strings({"case": case.model_dump(mode="json"), "catalog_entries": entries}, "the cube's record")
    except TextError as exc:
        raise SelectError(f"the cube's case {flat}: {exc}") from None
    try:
        return case, specs_from_entries(
            entries["surface"][case.surface],
            entries["machine"][case.machine],
            entries["cutting"][case.cutting],
            trust_plugins=trust_plugins,
        )
    except CatalogError as exc:
        raise SelectError(f"the cube's case {flat}: {exc}") from None


def check_exportable(ds: xr.Dataset, flat: int) -> None:
    """Refuse failed, pending, infeasible or over-capacity cases, saying which and why."""
    point = ds.isel(position(ds, flat))
    status = int(point["status"])
    if status == cube.FAILED:
        raise SelectError(
            f"case {flat} failed in the sweep ({point['message'].values}); it cannot be exported"
        )
    if status == cube.REFUSED:
        raise SelectError(
            f"case {flat} was refused in the sweep as specified ({point['message'].values}); it was "
            "never computed and cannot be exported"
        )
    if status == cube.PRUNED:
        raise SelectError(
            f"case {flat} was pruned by the estimate ({point['message'].values}); run the sweep "
            "without --prune to compute it"
        )
    if status != cube.DONE:
        raise SelectError(f"case {flat} has not been computed yet; run the sweep to the end first")
    cap = capacity_of(ds)
    if int(point["n_points"]) > cap:
        raise SelectError(
            f"case {flat} has {int(point['n_points']):,} points, over the controller capacity {cap:,}"
        )
    if not np.isfinite(float(point["pv_nm"])):
        raise SelectError(f"case {flat} has no finite P-V in the cube; it cannot be exported")
    if "feasible" in ds and int(point["feasible"]) != 1:
        raise SelectError(
            f"case {flat} is infeasible for the machine: {point['infeasible_reason'].values}; "
            "it cannot be exported"
        )
