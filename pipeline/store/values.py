"""A case's values as a cube stores them (:mod:`ftsweep.store.cube`): the statuses, the
per-case variables of a layout kind, and the values of a finished, failed or left-out case.

Nothing here imports zarr: a sweep's workers build their cases' values for their logs
(:mod:`ftsweep.store.caselog`) with this module alone; only the driver, the cube's one
writer, opens the store.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ftsweep.engine import plugins as registry
from ftsweep.engine import result

# refused: planning refuses the case as specified (over the machine's capacity, a layout the
# aperture rules out, ...): known before it is sent, or raised by its planning; never retried
PENDING, DONE, FAILED, PRUNED, REFUSED = 0, 1, 2, 3, 4
STATUS_MEANINGS = "pending done failed pruned refused"
# the statuses a later run may still change (a choice from a cube holding them could change)
UNSETTLED = {"pending": PENDING, "failed": FAILED, "pruned": PRUNED}

# cubes written before the variables were named per layout kind and carried parseable units
SCHEMA_VERSION = 2


def metrics_for(kind: str) -> dict[str, tuple[str, Any, str, Any]]:
    """The per-case numeric variables of a cube of layout ``kind``: name → (dtype, units,
    long_name, fill), as :mod:`ftsweep.engine.result` declares them."""
    return result.stored(registry.kind(kind))


MAP_VARS = {
    "error_map_mean_nm": "mean form error in each bin of the coarse error map",
    "error_map_peak_nm": "form error of largest magnitude in each bin of the coarse error map",
}
TEXT = {
    "message": "failure message of the case (empty when done)",
    "infeasible_reason": "machine limits the W motion exceeds (empty when feasible)",
    "run_id": "identifier of the run that computed the case",
}
# variables that differ between otherwise identical runs: every wall time (units "s") and the
# run id; derived from the declared result so a new timer cannot be forgotten
# wall times (which differ run to run), not the predicted machining times
TIMING_VARS = (*result.TIMING, "run_id")


class CubeError(ValueError):
    """A cube cannot be used as asked; the message says what to do."""


def metric_values(record: dict[str, Any]) -> dict[str, Any]:
    """The stored variables (:func:`metrics_for` the record's layout kind) of a finished case's
    record (``run_case`` output): the same names, ``feasible`` as a 0/1 flag."""
    values = {var: record[var] for var in metrics_for(record["layout"])}
    values["feasible"] = int(bool(record["feasible"]))
    return values


# a case's values as the store protocol writes them: variable -> value (a map: its array)
Values = dict[str, Any]


def done_values(record: dict[str, Any], run_id: str) -> Values:
    """Every stored variable of a finished case's record, ``status`` done (written last)."""
    values: Values = dict(metric_values(record))
    values["infeasible_reason"] = record["infeasible_reason"]
    for var in MAP_VARS:
        if var in record:
            values[var] = np.asarray(record[var])
    values.update(message="", run_id=run_id, status=DONE)
    return values


def ended_values(status: int, message: str, run_id: str) -> Values:
    """A case that failed, or that ``--prune`` left out, with its message."""
    return {"message": message[:2000], "run_id": run_id, "status": status}


def value_text(value: Any) -> str:
    """A coordinate value as a case's name writes it: names as they are, whole numbers
    without a decimal point (``950000``), others to 12 significant digits."""
    if isinstance(value, str):
        return value
    return str(int(value)) if float(value).is_integer() and abs(value) < 1e15 else f"{value:.12g}"


def case_name(coordinates: dict[str, Any]) -> str:
    """A case named by what it is: ``points=950000 aspect=16``, every axis of its cube."""
    return " ".join(f"{axis}={value_text(value)}" for axis, value in coordinates.items())


def case_name_at(axes: dict[str, Any], index: int) -> str:
    """The name (:func:`case_name`) of the case at flat C-order ``index`` of a cube whose axes
    hold ``axes`` (``{axis: values}``)."""
    at = np.unravel_index(index, tuple(len(values) for values in axes.values()))
    plain = {
        a: v[i].item() if hasattr(v[i], "item") else v[i] for (a, v), i in zip(axes.items(), at, strict=True)
    }
    return case_name(plain)
