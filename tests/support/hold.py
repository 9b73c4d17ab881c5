"""A sweep held where a test needs it, by a fault point rather than a workload's length: each
worker (a dask preload, so those of a local cluster and of an external one alike) stops once
its ``after``-th case is logged (``ftsweep.store.faultpoints``, event "logged"), leaves a file
``held-<pid>`` in the hold folder, and goes on once the test writes ``go`` there. The state a
test then sees is the same on a fast machine and a slow one.

Imported by a worker as its preload, this module installs the hook when the environment names
a hold folder (:func:`environment`)."""

from __future__ import annotations

import os
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

FOLDER = "FTSWEEP_TEST_HOLD"
AFTER = "FTSWEEP_TEST_HOLD_AFTER"
WAIT_S = 240.0


def environment(folder: Path, after: int) -> dict[str, str]:
    """What a sweep's environment adds for its workers to hold after ``after`` logged cases each."""
    folder.mkdir(parents=True, exist_ok=True)
    return {
        FOLDER: str(folder),
        AFTER: str(after),
        "DASK_DISTRIBUTED__WORKER__PRELOAD": repr([str(Path(__file__).resolve())]),
    }


def without(env: dict[str, str]) -> dict[str, str]:
    """``env`` with no hold: another run's, beside a held one."""
    return {k: v for k, v in env.items() if k not in (FOLDER, AFTER, "DASK_DISTRIBUTED__WORKER__PRELOAD")}


def _hook(folder: Path, after: int) -> Callable[[str, str], None]:
    logged: list[str] = []

    def hold(event: str, key: str) -> None:
        if event != "logged":
            return
        logged.append(key)
        if len(logged) != after:
            return
        (folder / f"held-{os.getpid()}").write_text(f"{key}\n")
        while not (folder / "go").exists():
            time.sleep(0.02)  # until the test's word, not a workload's length

    return hold


def held(folder: Path, count: int, run: subprocess.Popen[str] | None = None) -> list[int]:
    """Wait until ``count`` workers are held; the pids of those held. Fails naming the sweep's
    end if ``run`` ended first."""
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        found = sorted(int(p.name.split("-")[1]) for p in folder.glob("held-*"))
        if len(found) >= count:
            return found
        if run is not None and run.poll() is not None:
            raise AssertionError(f"the sweep ended (exit {run.returncode}) before {count} worker(s) held")
        time.sleep(0.05)
    raise AssertionError(f"no {count} worker(s) held within {WAIT_S:.0f} s")


def sweep(
    cmd: list[str],
    env: dict[str, str],
    gate: Path,
    after: int,
    output: bool = False,
    session: bool = True,
    workers: int = 1,
) -> subprocess.Popen[str]:
    """Start ``cmd`` (an ``ftsweep sweep``) with its workers holding after ``after`` logged
    cases each, and return once ``workers`` of them are held (the workers of an external
    cluster take the hold from the cluster's environment: give them :func:`environment` too).
    ``output``: its stdout and stderr piped (text), else discarded; ``session``: in a session
    of its own, so that a test can end its group. A sweep that is not held is ended before
    the failure is raised."""
    sink = subprocess.PIPE if output else subprocess.DEVNULL
    run = subprocess.Popen(
        cmd,
        stdout=sink,
        stderr=sink,
        text=True,
        env={**env, **environment(gate, after)},
        start_new_session=session,
    )
    try:
        held(gate, workers, run)
    except BaseException:
        run.kill()
        run.wait()
        raise
    return run


def let_go(folder: Path) -> None:
    """The held workers go on."""
    (folder / "go").write_text("")


if os.environ.get(FOLDER):
    from ftsweep.store import faultpoints

    faultpoints.WRITE_POINT = _hook(Path(os.environ[FOLDER]), int(os.environ.get(AFTER, "1")))
