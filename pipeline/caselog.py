"""Case logs: how sweep workers hand finished cases to the cube without writing its blocks.

A cube's arrays hold many cases per chunk (:mod:`ftsweep.cube`), and two workers must never
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
from collections import defaultdict
from typing import Any

import numpy as np

from ftsweep import cube
from ftsweep.storage import PathLike, Place, place

LOG = "_log"


def _encode(cases: list[tuple[int, cube.Values]]) -> bytes:
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


def _decode(data: bytes) -> list[tuple[int, cube.Values]]:
    by_case: dict[int, cube.Values] = defaultdict(dict)
    with np.load(io.BytesIO(data), allow_pickle=False) as npz:
        names = {n.rsplit(".", 1)[0] for n in npz.files}
        for var in names:
            values = npz[f"{var}.value"]
            for flat, value in zip(npz[f"{var}.index"].tolist(), values, strict=True):
                by_case[int(flat)][var] = value.item() if value.ndim == 0 else value
    return list(by_case.items())


class CaseLog:
    """One task's log (worker side), with :class:`~ftsweep.cube.CubeWriter`'s writing methods."""

    def __init__(self, where: PathLike, run_id: str) -> None:
        self.place = place(where)
        self.prefix = f"{LOG}/{run_id}/{uuid.uuid4().hex[:12]}"
        self.cases: list[tuple[int, cube.Values]] = []
        self.version = 0

    def _key(self, version: int) -> str:
        return f"{self.prefix}-{version:06d}.npz"

    def _add(self, flat: int, values: cube.Values) -> None:
        if not self.place.exists("zarr.json"):
            # a log would recreate the cube's folder and merge into nothing
            raise cube.CubeError(f"the cube {self.place} is gone (deleted while the sweep ran)")
        self.cases.append((flat, values))
        self.version += 1
        self.place.write(self._key(self.version), _encode(self.cases))
        if self.version > 1:
            self.place.remove(self._key(self.version - 1))

    def write_done(self, flat: int, record: dict[str, Any], run_id: str) -> None:
        self._add(flat, cube.done_values(record, run_id))

    def write_failed(self, flat: int, message: str, run_id: str) -> None:
        self._add(flat, cube.ended_values(cube.FAILED, message, run_id))


def _latest(keys: list[str]) -> dict[str, tuple[int, list[str]]]:
    """Per writer: its newest version's key and every key of that writer up to it."""
    versions: dict[str, list[tuple[int, str]]] = defaultdict(list)
    for key in keys:
        stem, _, tail = key.rpartition("-")
        if key.endswith(".npz") and tail[:-4].isdigit():
            versions[stem].append((int(tail[:-4]), key))
    return {stem: (max(v)[0], [k for _, k in sorted(v)]) for stem, v in versions.items()}


def merge_logs(where: PathLike) -> int:
    """Merge every case log under the cube into its blocks and delete the merged logs; the
    caller holds the cube's lock. Logs are applied oldest run first (a case computed again
    by a later run takes the later values). Returns the number of cases merged."""
    at: Place = place(where)
    writers = _latest(at.listing(LOG))
    if not writers:
        return 0
    cases: list[tuple[int, cube.Values]] = []
    merged: list[str] = []
    for stem in sorted(writers):  # the run id (a timestamp) leads the stem
        _, keys = writers[stem]
        try:
            data = at.read(keys[-1])
        except FileNotFoundError:  # its writer replaced it just now: the next merge takes that
            continue
        cases.extend(_decode(data))
        merged.extend(keys)
    if cases:
        cube.CubeWriter(at).write(cases)
    for key in merged:
        at.remove(key)
    at.remove_empty_folders(LOG)
    return len({flat for flat, _ in cases})


def pending_logs(where: PathLike) -> int:
    """How many case logs wait to be merged (a run was killed, or is running)."""
    return len(_latest(place(where).listing(LOG)))


def current_status(where: PathLike) -> np.ndarray:
    """Every case's status as the next merge will make it: the cube's, with what the logs
    hold laid over (read only; for watching a running sweep from another process)."""
    at = place(where)
    status = cube.read_status(at)
    flat = status.reshape(-1)
    for _, (_, keys) in sorted(_latest(at.listing(LOG)).items()):
        try:
            cases = _decode(at.read(keys[-1]))
        except FileNotFoundError:  # replaced just now by its next version
            continue
        for index, values in cases:
            if "status" in values:
                flat[index] = int(values["status"])
    return status
