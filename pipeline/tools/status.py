"""``ftsweep status``: how a cube stands, read without writing anything: its spec, its cases
done / pending / failed / refused / pruned (the workers' logs not yet merged counted in, the
reasons of failed and refused cases grouped), who holds its lock or lease and until when,
how it grew, and its last run."""

from __future__ import annotations

import json
import re
import socket
import time
from collections.abc import Iterable
from typing import Any, Optional

import numpy as np

from ftsweep.store import caselog, cube
from ftsweep.store.lock import holder_alive, lock_path, read_holder
from ftsweep.store.storage import PathLike, Place, place
from ftsweep.sweeps.spec import SweepSpec, n_cases

STATUS_NAMES = {
    cube.PENDING: "pending",
    cube.DONE: "done",
    cube.FAILED: "failed",
    cube.REFUSED: "refused",
    cube.PRUNED: "pruned",
}


def cube_status(where: PathLike) -> dict[str, Any]:
    """The status of the cube at ``where`` (a path or URL) as one JSON-ready mapping."""
    at = place(where)
    if not at.exists():
        raise cube.CubeError(f"no cube at {at}")
    attrs = cube.read_attrs(at)
    status = caselog.current_status(at).ravel()
    counts = {name: int(np.sum(status == value)) for value, name in STATUS_NAMES.items()}
    ds = cube.open_dataset(at)
    messages = np.asarray(ds["message"].values).ravel()
    runs = np.asarray(ds["run_id"].values).ravel()
    spec = SweepSpec.model_validate_json(attrs["sweep_spec"])
    return {
        "cube": str(at),
        "sweep": attrs.get("sweep_name"),
        "surface": spec.surface,
        "layout": spec.layout,
        "machine": spec.machine,
        "axes": {name: list(map(_plain, values)) for name, values in _axes(ds).items()},
        "cases": n_cases(spec),
        "counts": counts,
        "complete": not any(counts[name] for name in cube.UNSETTLED),
        "reasons": {
            name: grouped_reasons(messages[status == value])
            for value, name in STATUS_NAMES.items()
            if value in (cube.FAILED, cube.REFUSED, cube.PRUNED) and np.any(status == value)
        },
        "writer": writer_of(at),
        # blocks that cannot be read count their cases pending: name them (the next run rewrites them)
        "unreadable": cube.unreadable_chunks(at)[:5],
        "grown": json.loads(attrs.get("growth_history", "[]")),
        "last_run": _last_run(runs, status),
        "created": attrs.get("created"),
        "ftsweep_version": attrs.get("ftsweep_version"),
    }


def _axes(ds: Any) -> dict[str, np.ndarray]:
    return {str(d): np.asarray(ds[d].values) for d in ds["status"].dims}


def _plain(value: Any) -> Any:
    return value.item() if hasattr(value, "item") else value


def grouped_reasons(messages: Iterable[Any], most: int = 5) -> list[dict[str, Any]]:
    """Reasons of cases, grouped with the numbers in them set aside, the ``most`` frequent
    first: how many, and one in full (at most 300 characters)."""
    groups: dict[str, list[str]] = {}
    for text in (str(m) for m in messages):
        groups.setdefault(re.sub(r"[\d.,]+", "#", text), []).append(text)
    ranked = sorted(groups.values(), key=len, reverse=True)[:most]
    return [{"count": len(same), "example": same[0][:300]} for same in ranked]


def _last_run(runs: np.ndarray, status: np.ndarray) -> Optional[dict[str, Any]]:
    """The newest run that recorded cases (its ID starts with its start time) and what it left."""
    ids = [str(r) for r in runs if str(r)]
    if not ids:
        return None
    newest = max(ids)
    mine = np.array([str(r) == newest for r in runs])
    return {
        "run_id": newest,
        "started": time.strftime("%Y-%m-%dT%H:%M:%S", time.strptime(newest.split("-")[0], "%Y%m%dT%H%M%S")),
        "cases": {
            STATUS_NAMES[v]: int(np.sum(mine & (status == v))) for v in STATUS_NAMES if v != cube.PENDING
        },
    }


def writer_of(at: Place) -> Optional[dict[str, Any]]:
    """Who holds the cube's lock or lease, and whether it still holds: a local lock's pid
    checked on this host, a lease by its expiry; None when nobody writes it."""
    if at.local:
        holder = read_holder(lock_path(at))
        if holder is None:
            return None
        here = holder.get("host") == socket.gethostname()
        return {**holder, "kind": "lock file", "alive": holder_alive(holder) if here else None}
    lock = at.sibling(".lock")
    if not lock.exists():
        return None
    try:
        holder = json.loads(lock.read())
    except (ValueError, OSError):
        return {"kind": "lease", "unreadable": True}
    until = float(holder.get("lease_until", 0))
    return {
        **{k: v for k, v in holder.items() if k != "owner"},
        "kind": "lease",
        "lease_until": time.strftime("%Y-%m-%dT%H:%M:%S%z", time.localtime(until)),
        "expired": until < time.time(),
    }
