"""Sweeps that grow: a spec whose axes gained values extends its cube, and only the new cases
are computed.

A spec grows its cube when everything but the axes is unchanged, the same axes come in the
same order, and every value the cube holds is still on its axis (new point counts, aspect
ratios, feeds ... anywhere, or a range with more values that keeps the old ones). The cube is
rebuilt for the new spec with every recorded case moved to its new place (the cube is small:
its blocks are few), written beside it as ``NAME.zarr.grow`` and then moved in; a run killed
during the move finishes it on its next start (:func:`finish_interrupted`), one killed before
leaves the old cube as it was. A spec whose every case the cube holds (values removed, or
the catalog's spec of a cube grown from a copy) resumes the cube as it records
(:func:`held_by`); any other change is still refused without ``--restart``.
"""

from __future__ import annotations

import json
import os
import time
from typing import Any, Optional

import numpy as np

from ftsweep.store import cube, ledger
from ftsweep.store.cube import CubeError
from ftsweep.store.storage import Place
from ftsweep.sweeps.spec import SweepSpec, coordinates
from ftsweep.sweeps.template import template

STAGING = ".grow"


def _positions(old: np.ndarray, new: np.ndarray) -> Optional[np.ndarray]:
    """Where each old axis value lies on the new axis, or None if one is gone."""
    found = []
    for value in old:
        if isinstance(value, str) or old.dtype.kind in "OUS":
            hits = np.flatnonzero(new == value)
        else:
            hits = np.flatnonzero(np.isclose(new.astype(float), float(value), rtol=1e-12, atol=0.0))
        if hits.size != 1:
            return None
        found.append(int(hits[0]))
    return np.asarray(found, dtype=np.int64)


def growth(old_spec_json: str, new: SweepSpec) -> Optional[dict[str, Any]]:
    """How ``new`` grows the cube of the old spec: per axis the positions of its old values
    on the new axis and how many were added; None if it does not only grow it."""
    old = SweepSpec.model_validate_json(old_spec_json)
    if old.model_dump(mode="json", exclude={"axes"}) != new.model_dump(mode="json", exclude={"axes"}):
        return None
    old_axes, new_axes = coordinates(old), coordinates(new)
    if list(old_axes) != list(new_axes):
        return None
    plan: dict[str, Any] = {"positions": {}, "added": {}}
    for axis, values in old_axes.items():
        where = _positions(np.asarray(values), np.asarray(new_axes[axis]))
        if where is None:
            return None
        plan["positions"][axis] = where
        plan["added"][axis] = int(new_axes[axis].size - values.size)
    return plan


def _numbers(old: Any, shape: tuple[int, ...], index: Any) -> np.ndarray:
    """The grown cube's case numbers: every kept case its own (a cube from before numbers:
    its flat index, which were its numbers), the new cases the next ones in C order."""
    held = old[cube.CASE_NUMBER].values if cube.CASE_NUMBER in old else np.arange(old["status"].size)
    numbers = np.full(shape, -1, dtype=np.int64)
    numbers[index] = np.asarray(held, dtype=np.int64).reshape(old["status"].shape)
    new = numbers < 0
    numbers[new] = int(numbers.max()) + 1 + np.arange(int(new.sum()))
    return numbers


def describe(plan: dict[str, Any]) -> str:
    """``points +2, aspect +0`` for a notice."""
    return ", ".join(f"{axis} +{n}" for axis, n in plan["added"].items())


def grow(out: Place, spec: SweepSpec, name: str, plan: dict[str, Any]) -> None:
    """Rebuild the cube at ``out`` for ``spec`` with its recorded cases in their new places
    (the caller holds the lock and has merged the case logs)."""
    old = cube.open_dataset(out).load()
    entries = json.loads(old.attrs["catalog_entries"])
    # the cube keeps its sweep's name whatever file the grown spec came from
    new = template(spec, str(old.attrs.get("sweep_name") or name), entries)
    index = np.ix_(*plan["positions"].values())
    for var in new.data_vars:
        if var in old.data_vars:
            values = new[var].values.copy()
            values[index] = old[var].values
            new[var].values = values
    new[cube.CASE_NUMBER].values = _numbers(old, new[cube.CASE_NUMBER].shape, index)
    new.attrs["grown_from"] = old.attrs.get("sweep_spec_hash", "")
    history = json.loads(old.attrs.get("growth_history", "[]"))
    history.append(
        {"at": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "added": describe(plan), "from": new.attrs["grown_from"]}
    )
    new.attrs["growth_history"] = json.dumps(history)
    new.attrs["created"] = old.attrs.get("created", new.attrs["created"])
    staging = out.sibling(STAGING)
    staging.remove_all()
    cube.create(staging, new)
    _move_in(staging, out)


def _move_in(staging: Place, out: Place) -> None:
    """Replace ``out`` by the complete cube at ``staging``: a rename on a local disk; on object
    storage a copy of every object, the root metadata last, then the staging deleted. The
    cube's export ledger is carried over first (:func:`ftsweep.store.ledger.carry`), so a
    growth, or its finish after a kill, never forgets an export."""
    ledger.carry(out, staging)
    out.remove_all()
    if out.local:
        os.replace(staging.path, out.path)
        return
    fs, _ = out.fs()
    keys = [k for k in staging.listing("") if k != "zarr.json"] + ["zarr.json"]
    for key in keys:
        fs.copy(staging.key(key), out.key(key))
    staging.remove_all()


def finish_interrupted(out: Place) -> None:
    """A growth killed midway: a complete staging cube is moved in (the old cube may be half
    deleted already), an unfinished one deleted (the old cube is intact)."""
    staging = out.sibling(STAGING)
    if not staging.exists():
        return
    if cube.unfinished(staging) or not staging.exists("zarr.json"):
        staging.remove_all()
        return
    _move_in(staging, out)


def held_by(out: Place, spec: SweepSpec, name: str) -> tuple[SweepSpec, str, str]:
    """A spec all of whose cases an existing cube holds (a catalog's sweep whose cube was grown
    from another file) resumes that cube as it was recorded, under its own sweep name: returns
    the spec and name to run and a note saying so; else ``spec`` and ``name`` as given."""
    try:
        attrs = cube.read_attrs(out) if out.exists() and not cube.unfinished(out) else None
    except CubeError:
        attrs = None  # not a cube this run can resume: prepare_cube says why
    if attrs is None or attrs.get("sweep_spec_hash") == spec.spec_hash():
        return spec, name, ""
    try:
        recorded = SweepSpec.model_validate_json(attrs["sweep_spec"])
    except (KeyError, ValueError):
        return spec, name, ""
    plan = growth(spec.model_dump_json(), recorded)
    if plan is None:
        return spec, name, ""
    kept = str(attrs.get("sweep_name") or name)
    return (
        recorded,
        kept,
        (
            f"the cube holds every case of this spec and more ({describe(plan)} values, grown since); "
            f"resuming sweep '{kept}' as the cube records it"
        ),
    )
