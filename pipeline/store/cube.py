"""Zarr result cubes: one dimension per sweep axis, cases stored in blocks.

A cube lives in a local folder or at any fsspec URL (:mod:`ftsweep.store.storage`). Its arrays are
chunked in blocks of up to :data:`BLOCK_CASES` cases (error maps: up to
:data:`BLOCK_BYTES` a chunk), so a cube holds a few objects per variable, not one per case:
the 84-case reference sweep ~100 objects instead of 3,300, a 10⁵-case sweep ~1,200.

Write protocol (crash safety):

1. The template (every variable at its fill value, status ``pending``, coordinates, units
   and provenance) is written with its consolidated metadata last: a cube without it is an
   unfinished template (its writer was killed), which the next sweep replaces and readers
   refuse.
2. A worker logs each case as soon as it finishes (:mod:`ftsweep.store.caselog`): one object per
   task, replaced whole after every case, so a kill loses at most the cases in flight.
3. The sweep's driver, the one writer (it holds the lock), merges the logs into the blocks
   (every variable, ``status`` last) every few seconds, at the end and at the start of the
   next run, and deletes a log only once merged: a kill mid-merge merges it again.
   A case whose status is not ``done`` is recomputed on the next run; a block that cannot
   be read counts as pending.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Literal, Optional

import numpy as np
import zarr

from ftsweep.store.faultpoints import write_point
from ftsweep.store.fenced import fenced_store
from ftsweep.store.storage import PathLike, Place, place
from ftsweep.store.values import (
    DONE,
    FAILED,
    MAP_VARS,
    PENDING,
    PRUNED,
    REFUSED,
    SCHEMA_VERSION,
    STATUS_MEANINGS,
    TEXT,
    TIMING_VARS,  # noqa: F401 - a cube's readers find it here
    UNSETTLED,  # noqa: F401 - a cube's readers find it here
    CubeError,
    Values,
    done_values,
    ended_values,
    metric_values,  # noqa: F401 - a cube's readers find it here
    metrics_for,
)

# a sweep's workers log their cases with neither xarray nor zarr (ftsweep.store.values):
# xarray and pandas were 0.5 s of their start, zarr 0.16 s
if TYPE_CHECKING:
    import xarray as xr


# a cube's case numbers: given to each case as it enters the cube (C order when it is made,
# after every case it held when it grows, ftsweep.sweeps.grow), so a number names the same
# case however the cube grows; the variable is written with the template, never by a case
CASE_NUMBER = "case_number"


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
            "flag_values": [PENDING, DONE, FAILED, PRUNED, REFUSED],
            "flag_meanings": STATUS_MEANINGS,
        },
    )
    for var, long_name in TEXT.items():
        data[var] = (dims, np.full(shape, "", dtype=object), {"long_name": long_name})
    return data


# cases per chunk of a per-case variable, and bytes per chunk of an error map
BLOCK_CASES = 4096
BLOCK_BYTES = 4 * 2**20


def case_chunks(case_shape: tuple[int, ...], per_case_values: int = 1) -> tuple[int, ...]:
    """Chunk shape over the case dimensions: the last dimensions whole, as many as fit in
    :data:`BLOCK_CASES` cases (and :data:`BLOCK_BYTES` of 8-byte values), the next one in
    part, the rest one at a time."""
    room = max(1, min(BLOCK_CASES, BLOCK_BYTES // (8 * max(per_case_values, 1))))
    chunks = []
    for size in reversed(case_shape):
        take = max(1, min(size, room))
        chunks.append(take)
        room = room // size if take == size else 1
    return tuple(reversed(chunks))


def _encoding(ds: xr.Dataset) -> dict[str, Any]:
    case_dims = tuple(d for d in ds["status"].dims)
    shape = tuple(ds.sizes[d] for d in case_dims)
    encoding: dict[str, Any] = {}
    for v in ds.data_vars:
        extra = [d for d in ds[v].dims if d not in case_dims]
        per_case = int(np.prod([ds.sizes[d] for d in extra])) if extra else 1
        encoding[str(v)] = {"chunks": (*case_chunks(shape, per_case), *(ds.sizes[d] for d in extra))}
    return encoding


def create(where: PathLike, ds: xr.Dataset) -> None:
    """Write the template to ``where`` (a path or URL), its consolidated metadata last: until
    then it is an unfinished template (:func:`unfinished`), never a cube."""
    at = place(where)
    if at.exists():
        raise CubeError(f"{at} exists already; refusing to overwrite it")
    with warnings.catch_warnings():
        # consolidated metadata is a zarr-python extension in format 3; readers here use it
        warnings.filterwarnings("ignore", message="Consolidated metadata", category=UserWarning)
        ds.to_zarr(at.zarr_store(), zarr_format=3, encoding=_encoding(ds), consolidated=True, mode="w-")


def open_group(where: PathLike, mode: Literal["r", "r+"] = "r") -> zarr.Group:
    """The cube's zarr group (its consolidated metadata when only reading)."""
    at = place(where)
    reading = mode == "r"
    return zarr.open_group(at.zarr_store(read_only=reading), mode=mode, use_consolidated=reading or None)


def open_dataset(where: PathLike) -> xr.Dataset:
    """The cube as a lazy :class:`xarray.Dataset` (a path or URL, with its storage options)."""
    import xarray as xr

    return xr.open_zarr(place(where).zarr_store(read_only=True), consolidated=True)


def unfinished(where: PathLike) -> bool:
    """An ftsweep template whose writer was killed before its consolidated metadata."""
    at = place(where)
    try:
        zarr.open_group(at.zarr_store(read_only=True), mode="r", use_consolidated=True)
        return False
    except ValueError:
        try:
            attrs = zarr.open_group(at.zarr_store(read_only=True), mode="r", use_consolidated=False).attrs
        except Exception:  # noqa: BLE001 - not a zarr group at all
            return False
        return "sweep_spec_hash" in attrs or "optimize_spec_hash" in attrs
    except Exception:  # noqa: BLE001 - not a zarr group at all
        return False


def read_attrs(where: PathLike, check_schema: bool = True) -> dict[str, Any]:
    """The cube's attributes, or a :class:`CubeError` if ``where`` is not a cube, or (with
    ``check_schema``) is one of an older layout that this version does not read."""
    at = place(where)
    if unfinished(at):
        raise CubeError(
            f"{at} is an unfinished cube template (its sweep was killed while creating it); run the "
            "sweep again, which replaces it"
        )
    try:
        group = open_group(at)
    except Exception as exc:  # zarr raises several types for "not a group"
        raise CubeError(
            f"{at} exists but is not a Zarr cube ({str(exc)[:200]}); choose another --out"
        ) from None
    attrs = dict(group.attrs)
    if "sweep_spec_hash" not in attrs:
        raise CubeError(f"{at} is a Zarr store but not an ftsweep cube; choose another --out")
    if check_schema and attrs.get("ftsweep_cube_schema", 1) != SCHEMA_VERSION:
        raise CubeError(
            f"{at} was written by an older ftsweep (pitch_0/pitch_1 variables, units that no units "
            f"library parses); recompute it with: ftsweep sweep {attrs.get('sweep_name', 'NAME')} "
            f"--out {at} --restart"
        )
    return attrs


def variable_shapes(where: PathLike) -> dict[str, tuple[int, ...]]:
    """Every array of the cube by name with its shape (what a case log may write into)."""
    group = open_group(where, mode="r")
    return {name: tuple(array.shape) for name, array in group.arrays()}


def integer_variables(where: PathLike) -> frozenset[str]:
    """The cube's arrays that hold integers (counts, flags): a value written there must be a
    whole, finite number."""
    group = open_group(where, mode="r")
    found = set()
    for name, array in group.arrays():
        try:
            if np.dtype(array.dtype).kind in "biu":
                found.add(name)
        except TypeError:  # zarr's variable-length strings
            continue
    return frozenset(found)


# the metrics without which no case counts as done (every kind stores them: the run's record)
REQUIRED = ("pv_nm", "rms_nm")


def read_status(where: PathLike) -> np.ndarray:
    """Status of every case; a chunk that cannot be read (damaged) counts as pending, and so
    does a case marked done whose P-V or RMS is missing or not finite (a block lost, or
    written by nobody): status and select never call such a case done, and the next run
    computes it again."""
    at = place(where)
    values, _ = _read_array(at, "status", PENDING)
    status = values.astype(np.int8)
    group = open_group(at)
    for var in REQUIRED:
        if var in group and np.any(status == DONE):
            metric, _ = _read_array(at, var, np.nan)
            status[(status == DONE) & ~np.isfinite(metric.astype(float))] = PENDING
    return status


class CubeWriter:
    """Writes cases into an existing cube's blocks: the one writer of a cube (the sweep's
    driver, which merges its workers' logs, or ``optimize``). Every variable first,
    ``status`` last, so a case counts as done only once all else is written."""

    def __init__(self, where: PathLike, fence: Optional[Callable[[], None]] = None) -> None:
        at = place(where)
        self.fence = fence
        if fence is not None and not at.local:
            # every block a writer under a lease puts is a conditional write (ftsweep.store.fenced)
            self.group = zarr.open_group(fenced_store(at, fence), mode="r+", use_consolidated=None)
        else:
            self.group = open_group(at, mode="r+")
        self.shape = self._array("status").shape

    def _array(self, name: str) -> zarr.Array:
        array = self.group[name]
        if not isinstance(array, zarr.Array):
            raise CubeError(f"{name} in the cube is not an array")
        # a block equal to the fill value (NaNs a kind legitimately leaves, e.g. a spiral's
        # chord error under the angle rule) is still written: a block holding a finished case
        # always exists, and a missing one means damage (:func:`damaged_cases`)
        return array.with_config({"write_empty_chunks": True})

    def _index(self, flat: int) -> tuple[int, ...]:
        return tuple(int(i) for i in np.unravel_index(flat, self.shape))

    def write(self, cases: list[tuple[int, Values]]) -> None:
        """Write ``(flat index, values)`` of many cases: one pass per variable, ``status``
        last. Writing the same values again changes nothing (a merge may be repeated).
        The writer's ``fence`` is called before each variable's blocks are written (it raises
        to stop a writer that lost its lease), and on object storage every block is a
        conditional write besides (:class:`ftsweep.store.fenced.FencedStore`)."""
        fence = self.fence
        columns: dict[str, tuple[list[int], list[Any]]] = {}
        for flat, values in cases:
            for var, value in values.items():
                idx, vals = columns.setdefault(var, ([], []))
                idx.append(flat)
                vals.append(value)
        for var in sorted(columns, key=lambda v: v == "status"):
            if var not in self.group:
                continue  # an error map the cube was made without
            flats, vals = columns[var]
            write_point("before-var", var)
            if fence is not None:
                fence()
            array = self._array(var)
            coords = np.unravel_index(np.asarray(flats, dtype=np.int64), self.shape)
            if array.ndim > len(self.shape):  # error maps: each case's whole map
                for flat, value in zip(flats, vals, strict=True):
                    array[(*self._index(flat), slice(None), slice(None))] = value  # type: ignore[index]
            else:
                data = np.asarray(vals, dtype=object if array.dtype.kind not in "biuf" else array.dtype)
                array.vindex[coords] = data
            write_point("after-var", var)

    def write_done(self, flat: int, record: dict[str, Any], run_id: str) -> None:
        """Write a finished case's record, then mark it done."""
        self.write([(flat, done_values(record, run_id))])

    def write_values(self, flat: int, values: dict[str, Any]) -> None:
        """Write further per-case variables (before :meth:`write_done`, which marks it done)."""
        self.write([(flat, values)])

    def write_failed(self, flat: int, message: str, run_id: str) -> None:
        """Record a case that raised, with its message."""
        self.write([(flat, ended_values(FAILED, message, run_id))])


# ----------------------------------------------------------------------------- integrity
def chunk_path(where: PathLike, var: str, idx: tuple[int, ...]) -> str:
    """Where the chunk ``idx`` of variable ``var`` is (zarr v3's default ``c/i/j`` keys)."""
    return f"{place(where)}/{var}/c/{'/'.join(str(i) for i in idx)}"


def _read_array(where: Place, var: str, fill: Any = None) -> tuple[np.ndarray, dict[tuple[int, ...], str]]:
    """The whole array of ``var`` and its unreadable chunks (chunk index → error); the
    elements of an unreadable chunk read as ``fill`` (default: the array's fill value)."""
    array = open_group(where)[var]
    assert isinstance(array, zarr.Array)
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


def _stored_chunks(where: Place, var: str) -> set[tuple[int, ...]]:
    """The chunk indices of ``var`` that exist in the store."""
    found = set()
    for key in where.listing(f"{var}/c"):
        parts = key.split("/")[2:]
        if all(p.isdigit() for p in parts):
            found.add(tuple(int(p) for p in parts))
    return found


def repair(where: PathLike, fence: Optional[Callable[[], None]] = None) -> dict[int, str]:
    """Make a damaged cube writable again and say which cases lost data: every chunk that
    cannot be read is deleted (its elements read as fill values, a status chunk as pending),
    and every done case with an unreadable block, or a metric block that is missing (the
    writer writes every block of a finished case, fill values included), is marked pending
    so the next run recomputes it. Returns flat index → reason naming the chunk. The caller
    holds the cube's lock; ``fence`` is its lease's (:class:`CubeWriter`)."""
    at = place(where)
    group = open_group(at)
    status, status_bad = _read_array(at, "status", PENDING)
    shape = status.shape
    metrics = metrics_for(str(group.attrs.get("layout_method")))
    damaged: dict[int, str] = {}
    for var in ("status", *metrics, *MAP_VARS, *TEXT):
        if var not in group:
            continue
        array = group[var]
        assert isinstance(array, zarr.Array)
        bad = status_bad if var == "status" else _read_array(at, var)[1]
        # a case's map lies in one chunk: its block is the case block followed by zeros
        found = {block[: len(shape)]: f"is unreadable ({why})" for block, why in bad.items()}
        if var in metrics:
            stored = _stored_chunks(at, var)
            grid = tuple(-(-s // c) for s, c in zip(shape, array.chunks, strict=False))
            found.update(
                {
                    b: "is missing"
                    for b in np.ndindex(grid)
                    if b + (0,) * (array.ndim - len(shape)) not in stored
                }
            )
        if not found:
            continue
        blocks = _case_block_ids(shape, array.chunks)
        grid = tuple(-(-s // c) for s, c in zip(shape, array.chunks, strict=False))
        ids = {int(np.ravel_multi_index(b, grid)): b for b in found}
        hit = np.isin(blocks, list(ids)) & ((status.ravel() == DONE) | (var == "status"))
        for flat in np.flatnonzero(hit):
            block = ids[int(blocks[flat])]
            full = block + (0,) * (array.ndim - len(shape))
            damaged.setdefault(int(flat), f"{chunk_path(at, var, full)} {found[block]}")
        for block in bad:
            if fence is not None:
                fence()
            at.remove(f"{var}/c/{'/'.join(map(str, block))}")
    if damaged:
        CubeWriter(at, fence).write([(flat, {"status": PENDING}) for flat in damaged])
    return damaged


def _case_block_ids(shape: tuple[int, ...], chunks: tuple[int, ...]) -> np.ndarray:
    """The flat chunk index, over the case dimensions, of every case (flat order)."""
    idx = np.unravel_index(np.arange(int(np.prod(shape))), shape)
    grid = tuple(-(-s // c) for s, c in zip(shape, chunks, strict=False))
    return np.ravel_multi_index(tuple(i // c for i, c in zip(idx, chunks, strict=False)), grid)


def read_status_shape(where: PathLike) -> tuple[int, ...]:
    """Shape of the cube's case grid."""
    status = open_group(where)["status"]
    assert isinstance(status, zarr.Array)
    return tuple(status.shape)


def unreadable_chunks(where: PathLike) -> list[str]:
    """Every chunk of the cube that cannot be read, with why (a damaged block, or an entry
    that is not a file ftsweep writes: a FIFO, device, socket or link, never opened)."""
    at = place(where)
    found: list[str] = []
    for name, _ in open_group(at).arrays():
        _, bad = _read_array(at, name)
        found.extend(f"{chunk_path(at, name, idx)} ({err})" for idx, err in bad.items())
    return found


def check_readable(where: PathLike) -> None:
    """Raise :class:`CubeError` naming every unreadable chunk of the cube (at most five)."""
    at = place(where)
    found = unreadable_chunks(at)
    if found:
        more = f" and {len(found) - 5} more" if len(found) > 5 else ""
        raise CubeError(
            f"{at} has unreadable chunks: {'; '.join(found[:5])}{more}. Re-run the sweep on it to "
            "recompute those cases, or delete the damaged files first"
        )
