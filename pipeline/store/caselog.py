"""Case logs: how sweep workers hand finished cases to the cube without writing its blocks.

A cube's arrays hold many cases per chunk (:mod:`ftsweep.store.cube`), and two workers must never
rewrite the same chunk. So a worker logs: every task keeps one object
``_log/<run id>/<writer>-<version>.npz`` under the cube holding every case it finished so
far, replaced by the next version after each case (the previous one deleted after), so a
kill loses at most the case being computed. The cube's one writer — the sweep's driver,
holding the lock — merges the logs into the blocks (:func:`merge_logs`) and deletes each log
only after, so a kill mid-merge merges it again; merging is idempotent. zarr ignores the
``_log`` folder: readers see the merged cases.
"""

from __future__ import annotations

import io
import uuid
import warnings
import zipfile
from collections import defaultdict
from collections.abc import Callable
from typing import Any

import numpy as np

from ftsweep.store.faultpoints import write_point
from ftsweep.store.storage import PathLike, Place, place
from ftsweep.store.values import DONE, FAILED, REFUSED, TEXT, CubeError, Values, done_values, ended_values

LOG = "_log"
# where logs that fail their checks are kept for inspection (zarr ignores the folder too)
REJECTED = "_log_rejected"


def _encode(cases: list[tuple[int, Values]]) -> bytes:
    """The cases as an ``.npz`` of plain arrays (no pickles): per variable the flat indices
    of the cases that set it and their values."""
    columns: dict[str, tuple[list[int], list[Any]]] = defaultdict(lambda: ([], []))
    for flat, values in cases:
        for var, value in values.items():
            columns[var][0].append(flat)
            columns[var][1].append(value)
    arrays: dict[str, np.ndarray] = {}
    for var, (flats, vals) in columns.items():
        arrays[f"{var}.index"] = np.asarray(flats, dtype=np.int64)
        arrays[f"{var}.value"] = np.asarray(vals, dtype=str if isinstance(vals[0], str) else None)
    buffer = io.BytesIO()
    np.savez(buffer, allow_pickle=False, **arrays)
    return buffer.getvalue()


class BadLog(ValueError):
    """A case log that is not what a worker writes; the message says what is wrong."""


def _check_column(
    var: str,
    index: np.ndarray,
    values: np.ndarray,
    shapes: dict[str, tuple[int, ...]],
    integers: frozenset[str] = frozenset(),
) -> None:
    """One variable's columns of a log: a cube variable, int64 flat indices within the cube,
    one value per index of the cube variable's kind (maps of its shape); a variable of
    ``integers`` gets whole, finite numbers within int64 (a NaN count would stop every
    merge that converts it)."""
    if var not in shapes:
        raise BadLog(f"variable {var[:60]!r} is not one of the cube's")
    n_cases = int(np.prod(shapes["status"]))
    if index.dtype != np.int64 or index.ndim != 1 or values.shape[:1] != index.shape:
        raise BadLog(
            f"{var}: indices and values do not pair up ({index.dtype} {index.shape}, {values.shape})"
        )
    if index.size and (index.min() < 0 or index.max() >= n_cases):
        raise BadLog(f"{var}: case index {int(index.min())}..{int(index.max())} outside 0..{n_cases - 1}")
    kind = "U" if var in TEXT else "biuf"
    if values.dtype.kind not in kind:
        held = "text" if kind == "U" else "numbers"
        raise BadLog(f"{var}: values of type {values.dtype} where the cube holds {held}")
    extra = shapes[var][len(shapes["status"]) :]
    if values.shape[1:] != extra:
        raise BadLog(f"{var}: values of shape {values.shape[1:]} where the cube holds {extra}")
    if var in integers and values.size and values.dtype.kind == "f":
        whole = np.isfinite(values) & (np.abs(values) < 2.0**63)
        whole[whole] = values[whole] == np.round(values[whole])
        if not whole.all():
            bad = values[~whole].ravel()[0]
            raise BadLog(f"{var}: {bad} is not a whole number, and the cube holds counts")


# every done case has these finite (where the cube holds them): the form error's metrics the
# simulator refuses a case without (model §6; the interpolation-only P-V may be asked off)
_FINITE_WHEN_DONE = ("error_min_nm", "error_max_nm", "mean_nm", "pv_inner_nm", "pv_outer_nm")
# bytes a log's member may unpack to per case and value: numbers 8, text up to the longest
# message a case records (2,000 characters of 4 bytes in numpy's unicode arrays)
_BYTES_PER_VALUE, _BYTES_PER_TEXT, _HEADER_BYTES = 8, 4 * 2000, 4096


def unpacked_cap(shapes: dict[str, tuple[int, ...]]) -> int:
    """The most bytes a log of a cube of these variable ``shapes`` can hold unpacked: every
    case with every variable (indices and values), a header each. A log past it is refused
    before anything is unpacked, so a compressed bomb costs nothing."""
    n_cases = int(np.prod(shapes["status"]))
    total = 0
    for var, shape in shapes.items():
        per_case = int(np.prod(shape[len(shapes["status"]) :], dtype=np.int64)) if len(shape) > 1 else 1
        value = _BYTES_PER_TEXT if var in TEXT else _BYTES_PER_VALUE * per_case
        total += 2 * _HEADER_BYTES + n_cases * (8 + value)
    return total


# stored metrics that cannot be negative; P-V = max - min and RMS <= P-V hold for every case
_NON_NEGATIVE = ("pv_nm", "rms_nm", "pv_inner_nm", "pv_outer_nm", "pv_interp_nm", "cusp_nm", "n_points")


def _check_done(flat: int, values: Values) -> None:
    """A done case's values: P-V and RMS present and finite, no infinity anywhere, the
    non-negative metrics non-negative, ``feasible`` 0 or 1, and the metrics consistent
    (P-V = max − min error to 1e-6 relative, RMS ≤ P-V)."""
    pv, rms = values.get("pv_nm"), values.get("rms_nm")
    if not (isinstance(pv, (int, float)) and isinstance(rms, (int, float)) and np.isfinite([pv, rms]).all()):
        raise BadLog(f"case {flat} is done but its P-V or RMS is missing or not finite ({pv}, {rms})")
    for var, value in values.items():
        if isinstance(value, (int, float)) and np.isinf(value):
            raise BadLog(f"case {flat}: {var} is infinite")
        if var in _NON_NEGATIVE and isinstance(value, (int, float)) and value < 0:
            raise BadLog(f"case {flat}: {var} = {value} is negative")
    for var in _FINITE_WHEN_DONE:
        if var in values and not (isinstance(values[var], (int, float)) and np.isfinite(values[var])):
            raise BadLog(f"case {flat} is done but its {var} is {values[var]}, not a finite number")
    if values.get("feasible", 0) not in (0, 1):
        raise BadLog(f"case {flat}: feasible = {values['feasible']} is not 0 or 1")
    lo, hi = values.get("error_min_nm"), values.get("error_max_nm")
    if isinstance(lo, float) and isinstance(hi, float) and abs((hi - lo) - pv) > 1e-6 * max(1.0, abs(pv)):
        raise BadLog(f"case {flat}: P-V {pv} nm is not its largest minus its smallest error ({hi} - {lo})")
    if rms > pv * (1 + 1e-9) + 1e-9:
        raise BadLog(f"case {flat}: RMS {rms} nm exceeds its P-V {pv} nm")


def _check_sizes(data: bytes, cap: int) -> None:
    """The log's members as its zip directory declares them: each unpacks to at most what
    the cube can hold (:func:`unpacked_cap`), read before any member is unpacked (zipfile
    stops a member at its declared size)."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            declared = sum(info.file_size for info in archive.infolist())
    except (zipfile.BadZipFile, ValueError, OSError) as exc:
        raise BadLog(f"not a readable log ({type(exc).__name__}: {str(exc)[:120]})") from None
    if declared > cap:
        raise BadLog(
            f"it unpacks to {declared:,} bytes, more than a log of this cube can hold ({cap:,}); "
            "nothing was unpacked"
        )


def _columns(data: bytes, cap: int) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """A log's ``(index, value)`` arrays by variable, its sizes checked first (:func:`_check_sizes`)."""
    if len(data) > cap:
        raise BadLog(f"it holds {len(data):,} bytes, more than a log of this cube can hold")
    _check_sizes(data, cap)
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            columns = {}
            for name in npz.files:
                var, _, part = name.rpartition(".")
                if (
                    part not in ("index", "value")
                    or f"{var}.index" not in npz.files
                    or f"{var}.value" not in npz.files
                ):
                    raise BadLog(f"entry {name[:60]!r} is not a variable's index or value")
                columns[var] = (npz[f"{var}.index"], npz[f"{var}.value"])
    except BadLog:
        raise
    except Exception as exc:  # zipfile, numpy and zlib raise many kinds for damaged bytes
        raise BadLog(f"not a readable log ({type(exc).__name__}: {str(exc)[:120]})") from None
    return columns


def checked_cases(
    data: bytes, shapes: dict[str, tuple[int, ...]], integers: frozenset[str] = frozenset()
) -> list[tuple[int, Values]]:
    """The cases of a log's bytes, every record checked as untrusted input (``shapes``: each
    cube variable's shape): a readable ``.npz`` without pickles, columns that pair up, indices
    within the cube, values of the variables' kinds, a status a worker writes, and a done
    case's metrics finite, in range and consistent (:func:`_check_done`); :class:`BadLog`
    naming the first problem otherwise. ``integers``: the cube's integer variables
    (:func:`ftsweep.store.cube.integer_variables`)."""
    columns = _columns(data, unpacked_cap(shapes))
    by_case: dict[int, Values] = defaultdict(dict)
    for var, (index, values) in columns.items():
        _check_column(var, index, values, shapes, integers)
        for flat, value in zip(index.tolist(), values, strict=True):
            by_case[int(flat)][var] = value.item() if value.ndim == 0 else value
    for flat, case_values in by_case.items():
        status = case_values.get("status")
        if status not in (DONE, FAILED, REFUSED):
            raise BadLog(f"case {flat}: status {status!r} is not one a worker writes (done, failed, refused)")
        if status == DONE:
            _check_done(flat, case_values)
    return list(by_case.items())


class Fenced(CubeError):
    """A worker of a run whose lease was taken over: it writes no log."""


class CaseLog:
    """One task's log (worker side), with :class:`~ftsweep.store.cube.CubeWriter`'s writing methods."""

    def __init__(self, where: PathLike, run_id: str) -> None:
        self.place = place(where)
        self.fence_key = f"{LOG}/{run_id}/{FENCED}"
        self.prefix = f"{LOG}/{run_id}/{uuid.uuid4().hex[:12]}"
        self.cases: list[tuple[int, Values]] = []
        self.version = 0

    def _key(self, version: int) -> str:
        return f"{self.prefix}-{version:06d}.npz"

    def _add(self, flat: int, values: Values) -> None:
        if not self.place.exists("zarr.json"):
            # a log would recreate the cube's folder and merge into nothing
            raise CubeError(f"the cube {self.place} is gone (deleted while the sweep ran)")
        if self.place.exists(self.fence_key):
            # another run took the cube over: this run's workers write nothing more, and the
            # task stops here (its remaining cases are the taking run's)
            raise Fenced(
                f"the lease of this run on {self.place} was taken over: its workers write nothing more"
            )
        self.cases.append((flat, values))
        self.version += 1
        self.place.write(self._key(self.version), _encode(self.cases))
        if self.version > 1:
            self.place.remove(self._key(self.version - 1))
        write_point("logged", self._key(self.version))

    def write_done(self, flat: int, record: dict[str, Any], run_id: str) -> None:
        self._add(flat, done_values(record, run_id))

    def write_failed(self, flat: int, message: str, run_id: str) -> None:
        self._add(flat, ended_values(FAILED, message, run_id))

    def write_refused(self, flat: int, message: str, run_id: str) -> None:
        self._add(flat, ended_values(REFUSED, message, run_id))


# beside the logs of a run whose lease was taken over: none of its logs but those listed
# before the takeover is read again
FENCED = "FENCED"


def _run_of(key: str) -> str:
    parts = key.split("/")
    return parts[1] if len(parts) > 2 else ""


def fenced_out(keys: list[str], keep: frozenset[str] = frozenset()) -> tuple[list[str], list[str]]:
    """``keys`` split into the logs that may be read and those of fenced runs (not in ``keep``),
    which are deleted unread."""
    fenced = {_run_of(k) for k in keys if k.endswith(f"/{FENCED}")}
    usable = [k for k in keys if _run_of(k) not in fenced or k in keep]
    dropped = [k for k in keys if _run_of(k) in fenced and k not in keep and not k.endswith(FENCED)]
    return usable, dropped


def fence_run(where: PathLike, run_id: str) -> frozenset[str]:
    """Fence the logs of ``run_id`` (a run whose lease is being taken over): list them, then
    write the marker that makes every later one unread; returns the listed keys, which the
    taking writer alone still reads. A log its workers finish between the listing and the
    takeover is dropped, and its cases are computed again."""
    at = place(where)
    listed = frozenset(k for k in at.listing(f"{LOG}/{run_id}") if k.endswith(".npz"))
    at.write(f"{LOG}/{run_id}/{FENCED}", b"the lease of this run was taken over\n")
    return listed


def _latest(keys: list[str], keep: frozenset[str] = frozenset()) -> dict[str, tuple[int, list[str]]]:
    """Per writer: its newest version's key and every key of that writer up to it (the logs
    of fenced runs left out but those in ``keep``, :func:`fenced_out`)."""
    versions: dict[str, list[tuple[int, str]]] = defaultdict(list)
    for key in fenced_out(keys, keep)[0]:
        stem, _, tail = key.rpartition("-")
        if key.endswith(".npz") and tail[:-4].isdigit():
            versions[stem].append((int(tail[:-4]), key))
    return {stem: (max(v)[0], [k for _, k in sorted(v)]) for stem, v in versions.items()}


def merge_logs(
    where: PathLike, fence: Callable[[], None] | None = None, keep: frozenset[str] = frozenset()
) -> int:
    """Merge every case log under the cube into its blocks and delete the merged logs; the
    caller holds the cube's lock. Logs are applied oldest run first (a case computed again
    by a later run takes the later values). ``fence``: the writer's lease
    (:meth:`ftsweep.store.lock.Lease.fence`), which makes every block write conditional
    (:class:`ftsweep.store.cube.CubeWriter`); when it raises, nothing is deleted. Returns the
    number of cases merged. ``keep``: the logs of a fenced run that this writer may still read
    (:attr:`ftsweep.store.lock.Lease.inherited`); other logs of fenced runs are deleted unread."""
    from ftsweep.store import cube  # the driver's: workers never open the store (module doc)

    at: Place = place(where)
    keys = at.listing(LOG)
    for key in fenced_out(keys, keep)[1]:
        if fence is not None:
            fence()
        at.remove(key)
    writers = _latest(keys, keep)
    if not writers:
        return 0
    shapes, integers = cube.variable_shapes(at), cube.integer_variables(at)
    cases: list[tuple[int, Values]] = []
    merged: list[str] = []
    for stem in sorted(writers):  # the run id (a timestamp) leads the stem
        _, keys = writers[stem]
        try:
            data = at.read_capped(keys[-1], unpacked_cap(shapes))
        except FileNotFoundError:  # its writer replaced it just now: the next merge takes that
            continue
        except ValueError as exc:  # larger than any log of this cube: never downloaded
            _reject(at, keys[-1], None, str(exc))
            merged.extend(keys)
            continue
        try:
            cases.extend(checked_cases(data, shapes, integers))
        except BadLog as exc:
            _reject(at, keys[-1], data, str(exc))
        merged.extend(keys)
    if cases:
        cube.CubeWriter(at, fence).write(cases)
    write_point("commit", LOG)
    for key in merged:
        at.remove(key)
    at.remove_empty_folders(LOG)
    return len({flat for flat, _ in cases})


def _reject(at: Place, key: str, data: bytes | None, reason: str) -> None:
    """Move a bad log aside (under ``_log_rejected/``, kept for inspection) with a warning;
    its cases stay pending, so the run computes them again. ``data`` None: a log too large to
    read, deleted unread (the merge deletes it with the others)."""
    if data is None:
        where = "deleted unread"
    else:
        where = f"moved to {REJECTED + key[len(LOG) :]}"
        at.write(REJECTED + key[len(LOG) :], data)
    warnings.warn(
        f"case log {key} is not what a worker writes ({reason}); {where}, and its cases will be "
        "computed again",
        stacklevel=3,
    )


def pending_logs(where: PathLike) -> int:
    """How many case logs wait to be merged (a run was killed, or is running)."""
    return len(_latest(place(where).listing(LOG)))


def logged_cases(where: PathLike) -> list[tuple[int, Values]]:
    """The cases the logs hold, oldest run first, as the next merge would write them (read
    only: for reading a cube a run is writing, or one a killed run left, from elsewhere)."""
    from ftsweep.store import cube

    at = place(where)
    shapes, integers = cube.variable_shapes(at), cube.integer_variables(at)
    found: list[tuple[int, Values]] = []
    for _, (_, keys) in sorted(_latest(at.listing(LOG)).items()):
        try:
            found.extend(checked_cases(at.read_capped(keys[-1], unpacked_cap(shapes)), shapes, integers))
        except (FileNotFoundError, ValueError):  # replaced just now, or one the merge will reject
            continue
    return found


def current_status(where: PathLike) -> np.ndarray:
    """Every case's status as the next merge will make it: the cube's, with what the logs
    hold laid over (read only; for watching a running sweep from another process)."""
    from ftsweep.store import cube

    at = place(where)
    status = cube.read_status(at)
    flat = status.reshape(-1)
    for index, values in logged_cases(at):
        if "status" in values:
            flat[index] = int(values["status"])
    return status


def with_logged(ds: Any, where: PathLike) -> Any:
    """A loaded cube ``ds`` with the cases its logs hold laid over, in memory (nothing is
    written): what the cube will hold once they are merged."""
    shape = ds["status"].shape
    for index, values in logged_cases(where):
        pos = np.unravel_index(index, shape)
        for var, value in values.items():
            if var in ds:
                ds[var].values[pos] = value
    return ds
