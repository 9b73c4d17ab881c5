"""Which cases a sweep run sends, and what a cube holds: the cases refused before dispatch
(their planning would refuse them) and those pruned by the estimate, each written into the
cube with its reason; the cube's counts by status; a spec's axes in one line.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Optional

import numpy as np

from ftsweep import registry
from ftsweep.store import cube
from ftsweep.store.cube import CubeError
from ftsweep.store.storage import PathLike, Place
from ftsweep.sweeps.spec import NAMED_AXES, Costs, SweepSpec, case_costs, coordinates


def refuse_cases(
    spec: SweepSpec,
    out: Place,
    pending: list[int],
    run_id: str,
    catalog_folder: Optional[Path],
    fence: Optional[Callable[[], None]] = None,
) -> tuple[dict[int, str], Costs]:
    """Mark ``refused`` the pending cases whose planning would refuse them, known before any
    is sent (:func:`ftsweep.sweeps.spec.case_costs`: over the controller's capacity, a layout
    the aperture rules out, ...), with the reason; returns them by index, and the costs of the
    others, which plan the tasks."""
    costs, refused = case_costs(spec, pending, catalog_folder)
    if refused:  # a writer on object storage lists the cube first: only when there is something to write
        cube.CubeWriter(out, fence).write(
            [(index, cube.ended_values(cube.REFUSED, reason, run_id)) for index, reason in refused.items()]
        )
    return refused, costs


def prune_cases(
    spec: SweepSpec,
    out: Place,
    status: np.ndarray,
    factor: float,
    run_id: str,
    catalog_folder: Optional[Path],
    fence: Optional[Callable[[], None]] = None,
) -> int:
    """Mark pending cases hopeless by the estimate as pruned (see :func:`run_sweep`); returns
    how many this call pruned."""
    if not factor > 1.0:
        raise CubeError(f"the prune factor must be above 1, got {factor:g}")
    own = registry.kind(spec.layout)  # a kind with estimates: sweep --prune checks it
    est = own.estimate(spec, coordinates(spec), catalog_folder)["pv_estimate_nm"]
    values = est.transpose(*coordinates(spec)).values
    finite = np.where(np.isfinite(values), values, np.inf)
    best = finite.min(axis=1, keepdims=True)  # over the aspect ratios of each row
    hopeless = (np.isfinite(values) & (values > factor * best)).ravel()
    targets = np.flatnonzero(hopeless & (status == cube.PENDING))
    best_flat = np.broadcast_to(best, values.shape).ravel()
    message = "pruned: estimated P-V {:.4g} nm > {:g} × {:.4g} nm, the best estimate of its point count"
    cases = [
        (
            int(flat),
            cube.ended_values(
                cube.PRUNED, message.format(values.ravel()[flat], factor, best_flat[flat]), run_id
            ),
        )
        for flat in targets
    ]
    if cases:
        cube.CubeWriter(out, fence).write(cases)
    return int(targets.size)


def cube_counts(path: PathLike) -> dict[str, int]:
    """Cases pending, done, failed, pruned and refused in a cube."""
    status = cube.read_status(path)
    return {
        "pending": int(np.sum(status == cube.PENDING)),
        "done": int(np.sum(status == cube.DONE)),
        "failed": int(np.sum(status == cube.FAILED)),
        "pruned": int(np.sum(status == cube.PRUNED)),
        "refused": int(np.sum(status == cube.REFUSED)),
    }


def axis_summary(spec: SweepSpec) -> str:
    """One line per axis: its length and range, for the start of a run."""
    parts = []
    for axis, values in coordinates(spec).items():
        if axis in NAMED_AXES:
            parts.append(f"{axis} ×{values.size} [{', '.join(map(str, values))}]")
        else:
            low, high = (_number(v) for v in (values.min(), values.max()))
            parts.append(f"{axis} ×{values.size} [{low} … {high}]")
    return ", ".join(parts)


def _number(value: float) -> str:
    """A whole number with thousands separators (counts: 950,000), else 4 significant digits."""
    return f"{value:,.0f}" if float(value).is_integer() and abs(value) < 1e15 else f"{value:.4g}"
