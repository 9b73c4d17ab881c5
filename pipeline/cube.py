"""Zarr result cubes: one dimension per sweep axis, one chunk per case.

Write protocol (crash safety):

1. The template (every variable at its fill value, status ``pending``, coordinates, units
   and provenance) is written to a hidden temporary folder beside the target and renamed
   into place, so a cube either exists with a complete template or not at all.
2. Each case is written by the task that computed it, right after it finishes, into its
   own chunk of every variable; ``status`` is written last. A case whose status is not
   ``done`` is recomputed on the next run, so a kill mid-write loses at most the cases in
   flight, and an unreadable (torn) status chunk reads as ``pending``.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import time
import warnings
from pathlib import Path
from typing import Any, Optional

import numpy as np
import xarray as xr
import zarr

from ftsweep import __version__, result
from ftsweep.sweep import SweepSpec, axis_attrs, coordinates

PENDING, DONE, FAILED, PRUNED = 0, 1, 2, 3
STATUS_MEANINGS = "pending done failed pruned"

# cubes written before the variables were named per layout kind and carried parseable units
SCHEMA_VERSION = 2


def metrics_for(kind: str) -> dict[str, tuple[str, Any, str, Any]]:
    """The per-case numeric variables of a cube of layout ``kind``: name → (dtype, units,
    long_name, fill), as :mod:`ftsweep.result` declares them."""
    return result.stored(kind)


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
TIMING_VARS = (*(q.name for q in result.RESULT if q.dtype and q.name.startswith("seconds")), "run_id")


class CubeError(ValueError):
    """A cube cannot be used as asked; the message says what to do."""


def git_revision(source: Optional[Path] = None) -> str:
    """The git revision of ftsweep's own source checkout, or ``unknown``: only when this very
    file (or ``source``) is tracked by the repository around it (an editable install of
    ftsweep). An installed copy inside a user's project (a virtual environment in its
    folder) would otherwise record the user's revision as ftsweep's."""
    here = Path(source or __file__).resolve()
    try:
        for args in (["ls-files", "--error-unmatch", here.name], ["rev-parse", "HEAD"]):
            out = subprocess.run(
                ["git", *args], cwd=here.parent, capture_output=True, text=True, timeout=5, check=True
            )
        return out.stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def case_variables(dims: tuple[str, ...], shape: tuple[int, ...], kind: str) -> dict[str, Any]:
    """Every per-case variable of a cube over ``dims`` at its fill value: the metrics of layout
    ``kind``, ``status`` pending, and the text variables (the store protocol sweeps and
    ``optimize`` share)."""
    data: dict[str, Any] = {}
    for var, (dtype, units, long_name, fill) in metrics_for(kind).items():
        data[var] = (dims, np.full(shape, fill, dtype=dtype), {"units": units, "long_name": long_name})
    # flags and text carry no units (CF), so unit-aware readers leave them alone
    data["status"] = (
        dims,
        np.zeros(shape, dtype="int8"),
        {
            "long_name": "case status",
            "flag_values": [PENDING, DONE, FAILED, PRUNED],
            "flag_meanings": STATUS_MEANINGS,
        },
    )
    for var, long_name in TEXT.items():
        data[var] = (dims, np.full(shape, "", dtype=object), {"long_name": long_name})
    return data


def template(spec: SweepSpec, name: str, catalog_entries: dict[str, Any]) -> xr.Dataset:
    """The empty cube of a sweep: variables at fill values, status pending, provenance attrs."""
    coords = coordinates(spec)
    dims = tuple(coords)
    shape = tuple(v.size for v in coords.values())
    assert spec.layout is not None
    data = case_variables(dims, shape, spec.layout)
    coord_vars = {k: (k, v, axis_attrs(k, spec.layout)) for k, v in coords.items()}
    bins = spec.resolution.error_map_bins
    if bins:
        from pydantic import TypeAdapter

        from ftsweep.catalogs import aperture_of, surface_spec
        from ftsweep.record import ErrorMap

        surface = TypeAdapter(surface_spec()).validate_python(catalog_entries["surface"][spec.surface])
        centres = ErrorMap.over(aperture_of(surface), bins).centres_um()
        for axis in ("map_x", "map_y"):
            coord_vars[axis] = (
                axis,
                centres,
                {"units": "um", "long_name": f"{axis[-1]} of the error-map bin centre"},
            )
        for var, what in MAP_VARS.items():
            data[var] = (
                (*dims, "map_y", "map_x"),
                np.full((*shape, bins, bins), np.nan),
                {"units": "nm", "long_name": what},
            )
    ds = xr.Dataset(data, coords=coord_vars)
    ds.attrs.update(
        ftsweep_version=__version__,
        git_revision=git_revision(),
        sweep_name=name,
        sweep_spec=json.dumps(spec.model_dump(mode="json"), sort_keys=True),
        sweep_spec_hash=spec.spec_hash(),
        catalog_entries=json.dumps(catalog_entries, sort_keys=True),
        layout_method=str(spec.layout),
        ftsweep_cube_schema=SCHEMA_VERSION,
        surface=spec.surface,
        created=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        status_meanings=STATUS_MEANINGS,
    )
    return ds


def create(path: Path, ds: xr.Dataset) -> None:
    """Write the template to ``path`` atomically (temporary folder + rename)."""
    path = Path(path)
    if path.exists():
        raise CubeError(f"{path} exists already; refusing to overwrite it")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    # one chunk per case; map variables keep each case's whole map in its chunk
    encoding = {
        v: {"chunks": tuple(1 if d not in ("map_x", "map_y") else ds.sizes[d] for d in ds[v].dims)}
        for v in ds.data_vars
    }
    with warnings.catch_warnings():
        # consolidated metadata is a zarr-python extension in format 3; readers here use it
        warnings.filterwarnings("ignore", message="Consolidated metadata", category=UserWarning)
        ds.to_zarr(tmp, zarr_format=3, encoding=encoding, consolidated=True, mode="w-")
    os.replace(tmp, path)


def read_attrs(path: Path, check_schema: bool = True) -> dict[str, Any]:
    """The cube's attributes, or a :class:`CubeError` if ``path`` is not a cube, or (with
    ``check_schema``) is one of an older layout that this version does not read."""
    try:
        group = zarr.open_group(str(path), mode="r")
    except Exception as exc:  # zarr raises several types for "not a group"
        raise CubeError(
            f"{path} exists but is not a Zarr cube ({str(exc)[:200]}); choose another --out"
        ) from None
    attrs = dict(group.attrs)
    if "sweep_spec_hash" not in attrs:
        raise CubeError(f"{path} is a Zarr store but not an ftsweep cube; choose another --out")
    if check_schema and attrs.get("ftsweep_cube_schema", 1) != SCHEMA_VERSION:
        raise CubeError(
            f"{path} was written by an older ftsweep (pitch_0/pitch_1 variables, units that no units "
            f"library parses); recompute it with: ftsweep sweep {attrs.get('sweep_name', 'NAME')} "
            f"--out {path} --restart"
        )
    return attrs


def read_status(path: Path) -> np.ndarray:
    """Status of every case; a chunk that cannot be read (torn by a kill) counts as pending."""
    values, _ = _read_array(Path(path), "status", PENDING)
    return values.astype(np.int8)


def metric_values(record: dict[str, Any]) -> dict[str, Any]:
    """The stored variables (:func:`metrics_for` the record's layout kind) of a finished case's
    record (``run_case`` output): the same names, ``feasible`` as a 0/1 flag."""
    values = {var: record[var] for var in metrics_for(record["layout"])}
    values["feasible"] = int(bool(record["feasible"]))
    return values


class CubeWriter:
    """Writes finished cases into their own chunks of an existing cube (worker side)."""

    def __init__(self, path: Path) -> None:
        self.group = zarr.open_group(str(path), mode="r+")
        self.shape = self._array("status").shape

    def _array(self, name: str) -> zarr.Array:
        array = self.group[name]
        if not isinstance(array, zarr.Array):
            raise CubeError(f"{name} in the cube is not an array")
        # a chunk equal to the fill value (a NaN a kind legitimately leaves, e.g. a spiral's
        # chord error under the angle rule) is still written: a finished case's chunk then
        # always exists, and a missing one means damage (:func:`damaged_cases`)
        return array.with_config({"write_empty_chunks": True})

    def _set(self, name: str, idx: tuple[Any, ...], value: Any) -> None:
        self._array(name)[idx] = value

    def _index(self, flat: int) -> tuple[int, ...]:
        return tuple(int(i) for i in np.unravel_index(flat, self.shape))

    def write_done(self, flat: int, record: dict[str, Any], run_id: str) -> None:
        """Write a finished case's record, then mark it done."""
        idx = self._index(flat)
        for var, value in metric_values(record).items():
            self._set(var, idx, value)
        self._set("infeasible_reason", idx, record["infeasible_reason"])
        for var in MAP_VARS:
            if var in record and var in self.group:
                self._set(var, (*idx, slice(None), slice(None)), record[var])
        self._set("message", idx, "")
        self._set("run_id", idx, run_id)
        self._set("status", idx, DONE)  # last: the case counts only once all else is written

    def write_values(self, flat: int, values: dict[str, Any]) -> None:
        """Write further per-case variables (before :meth:`write_done`, which marks it done)."""
        idx = self._index(flat)
        for var, value in values.items():
            self._set(var, idx, value)

    def write_pruned(self, flat: int, message: str, run_id: str) -> None:
        """Record a case left out by ``--prune`` (not computed), saying why."""
        idx = self._index(flat)
        self._set("message", idx, message[:2000])
        self._set("run_id", idx, run_id)
        self._set("status", idx, PRUNED)

    def write_failed(self, flat: int, message: str, run_id: str) -> None:
        """Record a case that raised, with its message."""
        idx = self._index(flat)
        self._set("message", idx, message[:2000])
        self._set("run_id", idx, run_id)
        self._set("status", idx, FAILED)


# ----------------------------------------------------------------------------- integrity
def chunk_path(path: Path, var: str, idx: tuple[int, ...]) -> Path:
    """File of the chunk ``idx`` of variable ``var`` (zarr v3's default ``c/i/j`` keys)."""
    return Path(path) / var / "c" / Path(*(str(i) for i in idx))


def _read_array(path: Path, var: str, fill: Any = None) -> tuple[np.ndarray, dict[tuple[int, ...], str]]:
    """The whole array of ``var`` and its unreadable chunks (chunk index → error); the
    elements of an unreadable chunk read as ``fill`` (default: the array's fill value)."""
    array = zarr.open_array(str(path), path=var, mode="r")
    try:
        return np.asarray(array[...]), {}
    except Exception:  # a torn or corrupt chunk; codecs raise many types
        pass
    try:
        numeric = np.dtype(array.dtype).kind in "biuf"
    except TypeError:  # zarr's variable-length strings
        numeric = False
    values = np.full(
        array.shape, array.fill_value if fill is None else fill, dtype=array.dtype if numeric else object
    )
    bad: dict[tuple[int, ...], str] = {}
    grid = tuple(-(-s // c) for s, c in zip(array.shape, array.chunks, strict=True))
    for cidx in np.ndindex(grid):
        sel = tuple(slice(i * c, (i + 1) * c) for i, c in zip(cidx, array.chunks, strict=True))
        try:
            values[sel] = array[sel]
        except Exception as exc:
            bad[cidx] = f"{type(exc).__name__}: {str(exc)[:200]}"
    return values, bad


def damaged_cases(path: Path, status: np.ndarray) -> dict[int, str]:
    """Done cases whose data cannot be trusted: a metric chunk that is missing (the writer
    writes every chunk of a finished case, fill values included) or any chunk that is
    unreadable. Returns flat index → reason naming the variable's chunk file."""
    path = Path(path)
    group = zarr.open_group(str(path), mode="r")
    shape = read_status_shape(path)
    done = [int(f) for f in np.flatnonzero(np.asarray(status).ravel() == DONE)]
    damaged: dict[int, str] = {}
    metrics = metrics_for(str(group.attrs.get("layout_method")))
    for var in (*metrics, *MAP_VARS, *TEXT):
        if var not in group or not done:
            continue
        values, bad = _read_array(path, var)
        fill = metrics[var][3] if var in metrics else None
        for flat in done:
            if flat in damaged:
                continue
            idx = tuple(int(i) for i in np.unravel_index(flat, shape))
            chunk = idx + (0,) * (values.ndim - len(idx))  # a case's map is one chunk (case, 0, 0)
            if chunk in bad:
                damaged[flat] = f"{chunk_path(path, var, chunk)} is unreadable ({bad[chunk]})"
            elif fill is not None and not chunk_path(path, var, idx).exists():
                damaged[flat] = f"{chunk_path(path, var, idx)} is missing"
    return damaged


def read_status_shape(path: Path) -> tuple[int, ...]:
    """Shape of the cube's case grid."""
    return tuple(zarr.open_array(str(path), path="status", mode="r").shape)


def reset_cases(path: Path, flats: list[int]) -> None:
    """Mark cases pending again so the next run recomputes them."""
    array = zarr.open_array(str(path), path="status", mode="r+")
    for flat in flats:
        array[tuple(int(i) for i in np.unravel_index(flat, array.shape))] = PENDING


def check_readable(path: Path) -> None:
    """Raise :class:`CubeError` naming every unreadable chunk file of the cube (at most five)."""
    group = zarr.open_group(str(path), mode="r")
    found: list[str] = []
    for name, _ in group.arrays():
        _, bad = _read_array(Path(path), name)
        found.extend(f"{chunk_path(path, name, idx)} ({err})" for idx, err in bad.items())
    if found:
        more = f" and {len(found) - 5} more" if len(found) > 5 else ""
        raise CubeError(
            f"{path} has unreadable chunks: {'; '.join(found[:5])}{more}. Re-run the sweep on it to "
            "recompute those cases, or delete the damaged files first"
        )


def remove_stale_temporaries(path: Path) -> None:
    """Delete template folders (``.NAME.zarr.tmp-PID``) left by writers that were killed
    mid-create; call only while holding the cube's lock."""
    path = Path(path)
    for tmp in path.parent.glob(f".{path.name}.tmp-*"):
        shutil.rmtree(tmp, ignore_errors=True)
