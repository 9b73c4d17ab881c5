"""An external Dask cluster for tests: a ``dask scheduler`` and ``dask worker`` processes on
127.0.0.1, each in its own session so a test can kill one worker, or all, as a batch system
or a crash would."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Optional

BIN = Path(sys.executable).parent


class ExternalCluster:
    """A running scheduler (``address``) and its worker processes (``workers``)."""

    def __init__(self, folder: Path, env: dict[str, str]) -> None:
        self.folder = folder
        self.env = env
        self.address = ""
        self.scheduler: Optional[subprocess.Popen] = None
        self.workers: list[subprocess.Popen] = []

    def start_scheduler(self) -> str:
        sched_file = self.folder / "scheduler.json"
        self.scheduler = subprocess.Popen(
            [
                str(BIN / "dask"),
                "scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                "0",
                "--no-dashboard",
                "--scheduler-file",
                str(sched_file),
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=self.env,
            start_new_session=True,
        )
        deadline = time.time() + 60
        while time.time() < deadline:
            try:  # absent, or not yet written whole
                self.address = json.loads(sched_file.read_text())["address"]
                return self.address
            except (OSError, ValueError, KeyError):
                time.sleep(0.2)
        raise AssertionError(f"the scheduler wrote no address to {sched_file} within 60 s")

    def add_worker(self, cwd: Path, preload: Optional[Path] = None) -> subprocess.Popen:
        cmd = [
            str(BIN / "dask"),
            "worker",
            self.address,
            "--nthreads",
            "1",
            "--no-dashboard",
            "--host",
            "127.0.0.1",
        ]
        if preload is not None:
            cmd += ["--preload", str(preload)]
        proc = subprocess.Popen(
            cmd,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=self.env,
            cwd=cwd,
            start_new_session=True,
        )
        self.workers.append(proc)
        return proc

    def wait_for_workers(self, n: int) -> None:
        from distributed import Client

        with Client(self.address, timeout="30s") as client:
            client.wait_for_workers(n, timeout=60)

    def kill_workers(self) -> None:
        for p in self.workers:
            kill_group(p, signal.SIGKILL)

    def stop(self) -> None:
        procs = [*self.workers, *([self.scheduler] if self.scheduler else [])]
        for p in procs:
            kill_group(p, signal.SIGTERM)
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                kill_group(p, signal.SIGKILL)
                p.wait()


def kill_group(proc: subprocess.Popen, sig: int) -> None:
    try:
        os.killpg(proc.pid, sig)
    except ProcessLookupError:
        pass


def group_gone(group: int, within_s: float) -> bool:
    """Whether every process of session ``group`` has ended within ``within_s`` seconds."""
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        try:
            os.killpg(group, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.1)
    return False


@contextmanager
def external_cluster(folder: Path, env: dict[str, str]) -> Iterator[ExternalCluster]:
    """A scheduler on 127.0.0.1 (add workers with :meth:`ExternalCluster.add_worker`)."""
    cluster = ExternalCluster(folder, env)
    try:
        cluster.start_scheduler()
        yield cluster
    finally:
        cluster.stop()


def done_count(where: object) -> int:
    """Cases done in a cube so far, the ones its workers logged included (0 before it exists)."""
    import numpy as np

    from ftsweep.store import caselog, cube

    try:
        return int(np.sum(caselog.current_status(where) == cube.DONE))  # type: ignore[arg-type]
    except Exception:  # noqa: BLE001 - the template is not in place yet
        return 0
