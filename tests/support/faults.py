"""Fault injection at a cube writer's write points (``ftsweep.store.faultpoints.WRITE_POINT``):
the writer paused there while another run takes the cube over, or killed there. No sleeps:
a pause is another run executed at that very point, and a lease's expiry is written into its
lock record, so the outcome does not depend on the machine's load."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import xarray as xr

from ftsweep.store import caselog, cube, faultpoints, fenced
from ftsweep.store.lock import LeaseLost, LockError
from ftsweep.store.storage import place
from ftsweep.sweeps import cases, run
from ftsweep.sweeps.run import run_sweep

# two cases, merged one at a time (no pacing: MERGE_EVERY_S = MERGE_MAX_S = 0): the second
# merge lands on blocks that already hold the first case
SPEC = """
surface: small_sine
layout: ring
axes: {points: [8000], aspect: [1.0, 4.0]}
"""


class Killed(BaseException):
    """The writer died at a write point: nothing it would do later happens (every later write
    point raises it again, so no ``finally`` writes either)."""


def data(where: Any) -> xr.Dataset:
    """A cube's data variables, without those that differ between identical runs."""
    return cube.open_dataset(where).drop_vars(list(cube.TIMING_VARS)).load()


def block_tags(url: str) -> dict[str, str]:
    """Every object of a cube on object storage but its case logs, with its tag."""
    return {k: v for k, v in fenced.object_tags(place(url)).items() if not k.startswith(caselog.LOG)}


def expire_lease(url: str) -> None:
    """Write the lease of the cube at ``url`` as expired, as a paused holder's lease is once its
    term has passed (its owner, pid and run are kept)."""
    lock = place(url).sibling(".lock")
    record = json.loads(lock.read(""))
    record["lease_until"] = 0.0
    lock.write("", json.dumps(record).encode())


def writers(event: str) -> bool:
    """Whether ``event`` is a point of the cube's writer (a worker's logged case is not: the
    held sweeps of tests/support/hold.py stop there)."""
    return event != "logged"


def writers_only(hook: Callable[[str, str], None]) -> Callable[[str, str], None]:
    """``hook`` called at the writer's points only (:func:`writers`)."""

    def at_writers(event: str, key: str) -> None:
        if writers(event):
            hook(event, key)

    return at_writers


def points(spec: Path, url: str, catalog: Path, monkeypatch: Any) -> list[tuple[str, str]]:
    """The write points of a clean run of ``spec`` into ``url``, in order."""
    seen: list[tuple[str, str]] = []
    monkeypatch.setattr(run, "MERGE_EVERY_S", 0.0)
    monkeypatch.setattr(run, "MERGE_MAX_S", 0.0)
    monkeypatch.setattr(
        faultpoints, "WRITE_POINT", writers_only(lambda event, key: seen.append((event, key)))
    )
    run_sweep(str(spec), url, scheduler="synchronous", catalog_folder=catalog)
    monkeypatch.setattr(faultpoints, "WRITE_POINT", None)
    return seen


def faulted_run(spec: Path, url: str, catalog: Path, at: int, fault: str, monkeypatch: Any) -> dict[str, Any]:
    """Run ``spec`` into ``url`` with the ``fault`` ("pause" or "kill") at write point ``at``
    (1-based). A pause runs a second writer right there: on object storage after the first
    one's lease expired (it takes the cube over and finishes it), on a local folder while the
    first one's process lives (it is refused). Returns what happened: ``outcome`` of the
    first writer ("finished", "lease lost", "killed"), ``second`` ("finished", "refused"),
    and on object storage the block tags right after the second writer finished."""
    seen = {"count": 0, "dead": False}
    found: dict[str, Any] = {"second": None}
    local = place(url).local

    def pause() -> None:
        if local:
            try:
                run_sweep(str(spec), url, scheduler="synchronous", catalog_folder=catalog)
            except LockError:
                found["second"] = "refused"
            return
        expire_lease(url)
        run_sweep(str(spec), url, scheduler="synchronous", catalog_folder=catalog)
        found["second"] = "finished"
        found["tags"] = block_tags(url)

    def hook(event: str, key: str) -> None:
        if seen["dead"]:
            raise Killed
        seen["count"] += 1
        if seen["count"] != at:
            return
        if fault == "kill":
            seen["dead"] = True
            raise Killed
        held_hook, faultpoints.WRITE_POINT = faultpoints.WRITE_POINT, None  # the second writer runs clean
        try:
            pause()
        finally:
            faultpoints.WRITE_POINT = held_hook

    monkeypatch.setattr(run, "MERGE_EVERY_S", 0.0)
    monkeypatch.setattr(run, "MERGE_MAX_S", 0.0)
    monkeypatch.setattr(faultpoints, "WRITE_POINT", writers_only(hook))
    try:
        run_sweep(str(spec), url, scheduler="synchronous", catalog_folder=catalog)
        found["outcome"] = "finished"
    except LeaseLost as exc:
        found["outcome"] = "lease lost"
        found["message"] = str(exc)
    except Killed:
        found["outcome"] = "killed"
    finally:
        monkeypatch.setattr(faultpoints, "WRITE_POINT", None)
    return found


# the variables at whose write points a fault is injected: the first block a merge writes, a
# metric, the last before the status, and the status (what makes a case done)
KEY_VARS = ("n_points", "pv_nm", "run_id", "status")


def key_points(every: list[tuple[str, str]]) -> list[int]:
    """The 1-based indices of the write points of ``every`` that stand for all of them: before
    and after each block of :data:`KEY_VARS` (and each of its puts on object storage) in every
    merge, and every merge's commit. The points between are of the same kinds (another
    variable's block); ``check_every_point(..., every_point=True)`` goes through them all."""
    return [
        i + 1
        for i, (event, key) in enumerate(every)
        if event == "commit" or key in KEY_VARS or key.split("/")[0] in KEY_VARS
    ]


def check_every_point(
    spec_text: str,
    make_url: Callable[[int], str],
    tmp_path: Path,
    catalog: Path,
    monkeypatch: Any,
    fault: str,
    every_point: bool = False,
    puts_of: tuple[str, ...] = (),
) -> int:
    """For each write point of a clean run in turn (:func:`key_points`, or every one): the
    ``fault`` there, then a plain run of the same sweep; the cube must then equal a clean
    run's, bit for bit. ``puts_of``: only the points right before the puts of these variables' blocks,
    between the block's read and its write, where a check-then-write fence fails (a slow store).
    Returns the number of points checked."""
    spec = tmp_path / "fault.yaml"
    spec.write_text(spec_text)
    clean = make_url(0)  # the same kind of store: its write points are the ones faulted
    every = points(spec, clean, catalog, monkeypatch)
    expected = data(clean)
    chosen = list(range(1, len(every) + 1)) if every_point else key_points(every)
    if puts_of:
        chosen = [
            i for i in chosen if every[i - 1][0] == "before-put" and every[i - 1][1].split("/")[0] in puts_of
        ]
    for at in chosen:
        check_point(spec, make_url(at), catalog, (at, fault), monkeypatch, (expected, every))
    return len(chosen)


def check_point(
    spec: Path,
    url: str,
    catalog: Path,
    fault_at: tuple[int, str],
    monkeypatch: Any,
    clean: tuple[xr.Dataset, list[tuple[str, str]]],
) -> None:
    """The fault ``fault_at`` = (point, "pause" or "kill") in a run of ``spec`` into ``url``,
    then a plain run; the cube must equal the clean run's data (``clean``: its data and its
    write points), and on object storage the paused writer must have lost its lease without
    changing an object after the takeover."""
    at, fault = fault_at
    expected, every = clean
    found = faulted_run(spec, url, catalog, at, fault, monkeypatch)
    where = f"{fault} at point {at} {every[at - 1]}"
    if fault == "kill":
        assert found["outcome"] == "killed", where
    elif place(url).local:
        # a live process's lock is never taken over: the second writer waits (exit 75)
        assert found["second"] == "refused" and found["outcome"] == "finished", (where, found)
    else:
        assert found["second"] == "finished", (where, found)
        assert found["outcome"] == "lease lost", (where, found)
        # not one object changed after the takeover finished (a stale write landed nowhere)
        assert block_tags(url) == found["tags"], where
    run_sweep(str(spec), url, scheduler="synchronous", catalog_folder=catalog)
    xr.testing.assert_equal(data(url), expected)
    counts = cases.cube_counts(url)
    assert counts["done"] == expected["status"].size and counts["pending"] == 0, where
    assert not caselog.pending_logs(url), where
    if not place(url).local:
        place(url).remove_all()  # memory:// lists every object of the process
