"""Clusters as they are: tasks planned for the cluster's threads and the
summary counting its workers; a run whose workers all left ends with a message; a worker
without ftsweep is named; SIGTERM releases the cube's lock; the local dashboard's address."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import pytest
from support import hold
from support.clusters import BIN, done_count, external_cluster, kill_group

from ftsweep.store import cube
from ftsweep.store.lock import lock_path
from ftsweep.sweeps.run import run_sweep
from ftsweep.sweeps.spec import load_sweep, n_cases, plan_tasks

# external Dask schedulers and workers, killed and terminated
pytestmark = [pytest.mark.integration, pytest.mark.serial]

# 18 cases: 8 tasks on one thread, 9 on two (this machine's cores)
SPEC = """
surface: small_sine
layout: ring
axes:
  points: [6000, 8000, 10000, 12000, 16000, 20000]
  aspect: [1.5, 3.0, 6.0]
"""
# one case a task, so a killed worker leaves most of them pending
SLOW = """
surface: small_sine
layout: ring
axes:
  points: [6000, 9000, 12000, 16000, 20000, 25000, 30000, 36000]
  aspect: [2.0, 8.0]
cases_per_task: 1
"""


def _spec(folder: Path, text: str) -> Path:
    path = folder / "c.yaml"
    path.write_text(text)
    return path


def _env(catalog_dir: Path) -> dict[str, str]:
    return dict(os.environ, FTSWEEP_CATALOGS=str(catalog_dir))


def test_tasks_are_planned_for_the_clusters_threads(tmp_path, catalog_dir):
    spec_path = _spec(tmp_path, SPEC)
    _, spec = load_sweep(str(spec_path), catalog_dir)
    everything = list(range(n_cases(spec)))
    one, two = (len(plan_tasks(spec, everything, w, catalog_dir)) for w in (1, 2))
    assert one != two  # otherwise this test could not tell them apart
    with external_cluster(tmp_path, _env(catalog_dir)) as cluster:
        cluster.add_worker(cwd=tmp_path)
        cluster.wait_for_workers(1)
        seen = []
        report = run_sweep(
            str(spec_path),
            tmp_path / "one.zarr",
            scheduler=cluster.address,
            workers=2,  # what this machine would ask for: the cluster's count wins
            catalog_folder=catalog_dir,
            announce=lambda r: seen.append((r.workers, r.threads, r.tasks)),
        )
    assert report.done == len(everything)
    assert (report.workers, report.threads, report.tasks) == (1, 1, one)
    assert seen == [(1, 1, one)]  # announced before the cases ran


def test_a_run_whose_workers_all_left_ends_with_a_message(tmp_path, catalog_dir):
    gate = tmp_path / "hold"
    env = {**_env(catalog_dir), **hold.environment(gate, after=2)}
    out = tmp_path / "lost.zarr"
    with external_cluster(tmp_path, env) as cluster:
        cluster.add_worker(cwd=tmp_path)
        cluster.wait_for_workers(1)
        cmd = [str(BIN / "ftsweep"), "sweep", str(_spec(tmp_path, SLOW)), "--out", str(out)]
        cmd += ["--scheduler", cluster.address, "--worker-wait", "3"]
        run = hold.sweep(cmd, env, gate, after=2, output=True, session=False)
        cluster.kill_workers()
        killed = time.monotonic()
        _, stderr = run.communicate(timeout=120)
        took = time.monotonic() - killed
    assert run.returncode == 1
    assert "every worker of the cluster left and none came back within 3 s" in stderr
    assert "run the same command again" in stderr
    assert took < 60, took  # 3 s of waiting, the rest closing the client
    assert not lock_path(out).exists()
    kept = done_count(out)
    assert kept == 2  # the worker was held after its second case
    # the finished cases are kept and a run on a local cluster completes the rest
    report = run_sweep(str(tmp_path / "c.yaml"), out, scheduler="synchronous", catalog_folder=catalog_dir)
    assert report.skipped == kept and report.done == 16 - kept


BLOCK_FTSWEEP = '''
"""A worker's environment without ftsweep (a preload run before the worker takes tasks)."""
import sys


class NoFtsweep:
    def find_spec(self, name, path=None, target=None):
        if name == "ftsweep" or name.startswith("ftsweep."):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None


sys.meta_path.insert(0, NoFtsweep())
'''


def test_a_worker_without_ftsweep_is_named(tmp_path, catalog_dir):
    env = _env(catalog_dir)
    preload = tmp_path / "no_ftsweep.py"
    preload.write_text(BLOCK_FTSWEEP)
    out = tmp_path / "bare.zarr"
    with external_cluster(tmp_path, env) as cluster:
        cluster.add_worker(cwd=tmp_path, preload=preload)
        cluster.wait_for_workers(1)
        r = subprocess.run(
            [str(BIN / "ftsweep"), "sweep", str(_spec(tmp_path, SPEC)), "--out", str(out)]
            + ["--scheduler", cluster.address],
            capture_output=True,
            text=True,
            env=env,
            timeout=120,
        )
    assert r.returncode == 1
    assert "1 worker(s) of tcp://127.0.0.1:" in r.stderr and "cannot import ftsweep" in r.stderr
    assert "tcp://127.0.0.1:" in r.stderr.split("cannot import ftsweep (")[1]  # the worker's address
    assert "No module named 'ftsweep'" in r.stderr and "install ftsweep" in r.stderr
    assert len(r.stderr.strip().splitlines()) <= 3  # a message, not a traceback
    assert done_count(out) == 0 and not lock_path(out).exists()


def test_no_worker_joining_is_reported_after_the_wait(tmp_path, catalog_dir):
    env = _env(catalog_dir)
    with external_cluster(tmp_path, env) as cluster:
        start = time.monotonic()
        r = subprocess.run(
            [str(BIN / "ftsweep"), "sweep", str(_spec(tmp_path, SPEC)), "--out", str(tmp_path / "w.zarr")]
            + ["--scheduler", cluster.address, "--worker-wait", "2"],
            capture_output=True,
            text=True,
            env=env,
            timeout=120,
        )
        took = time.monotonic() - start
    assert r.returncode == 1 and "no worker joined the scheduler" in r.stderr and "within 2 s" in r.stderr
    assert took < 30


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_a_terminated_sweep_releases_its_lock_and_resumes(tmp_path, catalog_dir, sig):
    env = _env(catalog_dir)
    out = tmp_path / "term.zarr"
    cmd = [str(BIN / "ftsweep"), "sweep", str(_spec(tmp_path, SLOW)), "--out", str(out), "--workers", "1"]
    gate = tmp_path / "hold"
    run = hold.sweep(cmd, env, gate, after=2, output=True)  # two cases logged, its worker held there
    try:
        assert lock_path(out).exists()
        run.send_signal(sig)  # the driver only, as a batch system's job stop does
        hold.let_go(gate)
        _, stderr = run.communicate(timeout=120)
    finally:
        if run.poll() is None:
            os.killpg(run.pid, signal.SIGKILL)
    assert run.returncode == 128 + sig, stderr
    assert "terminated by a signal" in stderr
    assert "dashboard http://127.0.0.1:" in stderr  # the local cluster's, on loopback
    assert not lock_path(out).exists()
    kept = done_count(out)
    rerun = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert rerun.returncode == 0, rerun.stderr
    assert f"{kept} were done already" in rerun.stdout


def test_a_sweep_survives_losing_one_of_two_external_workers(tmp_path, catalog_dir):
    """Kill one worker of an external 2-worker cluster mid-sweep; the other
    finishes (Dask reruns the lost worker's task there) and the cube equals a local run."""
    gate = tmp_path / "hold"
    env = {**_env(catalog_dir), **hold.environment(gate, after=1)}
    out = tmp_path / "survive.zarr"
    spec = _spec(tmp_path, SLOW)
    with external_cluster(tmp_path, env) as cluster:
        for _ in range(2):
            cluster.add_worker(cwd=tmp_path)
        cluster.wait_for_workers(2)
        cmd = [str(BIN / "ftsweep"), "sweep", str(spec), "--out", str(out), "--scheduler", cluster.address]
        run = hold.sweep(cmd, env, gate, after=1, output=True, session=False, workers=2)  # one case each
        kill_group(cluster.workers[0], signal.SIGKILL)
        hold.let_go(gate)
        stdout, stderr = run.communicate(timeout=300)
    assert run.returncode == 0, stderr
    assert "16 done" in stdout
    local = tmp_path / "local.zarr"
    run_sweep(str(spec), local, scheduler="synchronous", catalog_folder=catalog_dir)
    import xarray as xr

    def data(path: Path) -> xr.Dataset:
        return xr.open_zarr(path).drop_vars(list(cube.TIMING_VARS)).load()

    xr.testing.assert_equal(data(out), data(local))
