"""Cubes on object storage, against a real S3-compatible server:
moto's standalone server on 127.0.0.1, as zarr's and s3fs's own test suites run it. A sweep
into ``s3://``: done, a re-run computes nothing, select/export/report/compare read it,
``xr.open_zarr`` + the accessor open it; a killed sweep resumes once its lease expired; a
second writer is refused while the first runs; the cube equals a local run's."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest
import xarray as xr
from click.testing import CliRunner
from support import hold
from support.clusters import BIN, done_count, group_gone
from support.places import REPO

from ftsweep.cli.main import main
from ftsweep.store import cube
from ftsweep.store.storage import place
from ftsweep.sweeps.run import run_sweep

# a moto S3 server, sweeps in subprocesses; the tests that race a running sweep (killed or
# paused mid-run) are marked serial and run alone after the parallel run, the others with it
pytestmark = [pytest.mark.integration]

pytest.importorskip("s3fs")
pytest.importorskip("moto")

SPEC = """
surface: small_sine
layout: ring
axes: {points: [8000, 16000], aspect: [1.0, 4.0, 16.0]}
"""
# 48 cases, 6-8 s on one worker: a run to kill, and to contend with
SLOW = """
surface: small_sine
layout: ring
axes:
  points: [40000, 60000, 80000, 100000, 120000, 140000, 160000, 180000]
  aspect: [1.0, 2.0, 4.0, 8.0, 16.0, 32.0]
cases_per_task: 1
"""


def _spec(folder: Path, text: str = SPEC) -> Path:
    path = folder / "s3.yaml"
    path.write_text(text)
    return path


def _data(where) -> xr.Dataset:  # type: ignore[no-untyped-def]
    return cube.open_dataset(where).drop_vars(list(cube.TIMING_VARS)).load()


def _cli(args: list[str], catalog_dir: Path):  # type: ignore[no-untyped-def]
    return CliRunner().invoke(main, args, env={"FTSWEEP_CATALOGS": str(catalog_dir)})


def test_a_sweep_into_s3_reads_back_like_a_local_one(s3, tmp_path, catalog_dir):
    spec = _spec(tmp_path)
    url = f"{s3}/c.zarr"
    r = _cli(["sweep", str(spec), "--out", url, "--scheduler", "synchronous"], catalog_dir)
    assert r.exit_code == 0, r.output
    assert "6 done" in r.output
    again = _cli(["sweep", str(spec), "--out", url, "--scheduler", "synchronous"], catalog_dir)
    assert again.exit_code == 0 and "6 were done already, 0 run now" in again.output
    local = tmp_path / "local.zarr"
    run_sweep(str(spec), local, scheduler="synchronous", catalog_folder=catalog_dir)
    xr.testing.assert_equal(_data(url), _data(local))
    # few objects: a block per variable, no case log left, the lock released
    import s3fs

    fs = s3fs.S3FileSystem()
    objects = fs.find(url)
    assert not [o for o in objects if "/_log/" in o]
    assert len(objects) < 120, len(objects)
    assert not fs.exists(f"{url}.lock")
    # readers: select, export (to a local file), report, compare, and xarray with the accessor
    sel = _cli(["select", url, "--budget-points", "16000", "--json"], catalog_dir)
    assert sel.exit_code == 0, sel.output
    header = tmp_path / "best.h"
    exp = _cli(["export", url, "--budget-points", "16000", "-o", str(header)], catalog_dir)
    assert exp.exit_code == 0 and header.exists(), exp.output
    rep = _cli(["report", url, "--out", str(tmp_path / "rep"), "--map-bins", "16"], catalog_dir)
    assert rep.exit_code == 0 and (tmp_path / "rep" / "index.html").exists(), rep.output
    cmp = _cli(["compare", url, str(local), "--as-recorded", "--json"], catalog_dir)
    assert cmp.exit_code == 0, cmp.output
    ds = xr.open_zarr(url)  # what a notebook does: storage options from fsspec's configuration
    import ftsweep  # noqa: F401  (the accessor)

    assert ds.ftsweep.best(budget_points=16000).attrs["index"] == int(
        __import__("json").loads(sel.stdout)["index"]
    )
    # a program goes to a local file: a URL is refused, saying so
    refused = _cli(["export", url, "--budget-points", "16000", "-o", f"{s3}/best.h"], catalog_dir)
    assert refused.exit_code == 2 and "written to a local path" in refused.output


def test_storage_options_on_the_command_line(s3, s3_env, tmp_path, catalog_dir, monkeypatch):
    import fsspec
    import s3fs

    monkeypatch.setitem(fsspec.config.conf, "s3", {})  # no configured endpoint: the option gives it
    monkeypatch.delenv("FSSPEC_S3_ENDPOINT_URL")
    s3fs.S3FileSystem.clear_instance_cache()
    url = f"{s3}/opt.zarr"
    option = ["--storage-option", f"endpoint_url={s3_env['FSSPEC_S3_ENDPOINT_URL']}"]
    r = _cli(
        ["sweep", str(_spec(tmp_path)), "--out", url, "--scheduler", "synchronous", *option], catalog_dir
    )
    assert r.exit_code == 0, r.output
    sel = _cli(["select", url, "--budget-points", "16000", *option], catalog_dir)
    assert sel.exit_code == 0, sel.output
    bad = _cli(["select", url, "--budget-points", "16000", "--storage-option", "endpoint_url"], catalog_dir)
    assert bad.exit_code == 2 and "KEY=VALUE" in bad.output


def _wait_gone(group: int) -> None:
    if not group_gone(group, 60.0):
        raise AssertionError(f"processes of group {group} outlived SIGKILL")


# Long enough that the killed run's lease still holds after the kill, the wait for its processes
# and a refused run's start on a loaded CI machine (4 s was not: the lease ran out first).
LEASE_S = 20


def _wait_lease_out(lock_url: str) -> None:
    """Sleep until the lease the lock object records has expired (its own ``lease_until``)."""
    until = json.loads(place(lock_url).read())["lease_until"]
    time.sleep(max(0.0, until - time.time()) + 0.5)


@pytest.mark.serial
def test_a_killed_s3_sweep_resumes_after_its_lease_and_a_second_writer_is_refused(
    s3, s3_env, tmp_path, catalog_dir
):
    spec = _spec(tmp_path, SLOW)
    url = f"{s3}/kill.zarr"
    env = dict(os.environ, FTSWEEP_CATALOGS=str(catalog_dir), FTSWEEP_LOCK_LEASE_S=str(LEASE_S), **s3_env)
    cmd = [str(BIN / "ftsweep"), "sweep", str(spec), "--out", url, "--workers", "1"]
    first = hold.sweep(cmd, env, tmp_path / "hold", after=2)  # its worker held after two cases
    try:
        second = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=120)
        assert second.returncode == 75, second.stderr
        assert "is being written by pid" in second.stderr and "lease until" in second.stderr
    finally:
        os.killpg(first.pid, signal.SIGKILL)  # the driver and its worker: no lock released
        first.wait()
    _wait_gone(first.pid)
    logged = done_count(url)
    assert logged == 2
    refused = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=120)
    assert refused.returncode == 75 and "lease" in refused.stderr  # the killed run's lease still runs
    # status of the killed cube: its logged cases counted, incomplete, the dead run's lease held
    status = subprocess.run(
        [str(BIN / "ftsweep"), "status", url, "--json"], capture_output=True, text=True, env=env, timeout=120
    )
    found = json.loads(status.stdout)
    assert status.returncode == 1 and not found["complete"], status.stderr
    assert found["counts"]["done"] == logged and found["counts"]["pending"] == 48 - logged
    assert found["writer"]["kind"] == "lease" and found["writer"]["expired"] is False
    select = subprocess.run(
        [str(BIN / "ftsweep"), "select", url, "--budget-points", "200000"],
        capture_output=True,
        text=True,
        env=env,
    )
    assert select.returncode == 1 and "incomplete" in select.stderr and "--allow-incomplete" in select.stderr
    select = subprocess.run(
        [str(BIN / "ftsweep"), "select", url, "--budget-points", "200000", "--allow-incomplete"],
        capture_output=True,
        text=True,
        env=env,
    )
    assert select.returncode == 0 and "note: the cube is incomplete" in select.stderr, select.stderr
    _wait_lease_out(f"{url}.lock")
    resumed = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    # every case the killed run logged was kept (merged first), none computed twice
    counts = next(line for line in resumed.stdout.splitlines() if line.startswith("cases"))
    assert f"({logged} were done already" in counts, counts
    clean = tmp_path / "clean.zarr"
    run_sweep(str(spec), clean, scheduler="synchronous", catalog_folder=catalog_dir)
    xr.testing.assert_equal(_data(url), _data(clean))
    assert place(f"{url}.lock").exists() is False
    done = subprocess.run([str(BIN / "ftsweep"), "status", url], capture_output=True, text=True, env=env)
    assert done.returncode == 0 and "48 done, 0 pending" in done.stdout and "writer       none" in done.stdout


def _block_tags(url: str) -> dict[str, str]:
    """ETag of every object of a cube but its case logs (the blocks and metadata)."""
    import s3fs

    fs = s3fs.S3FileSystem()
    fs.invalidate_cache()
    return {p: fs.info(p)["ETag"] for p in fs.find(url) if "/_log" not in p}


@pytest.mark.serial
def test_a_writer_paused_past_its_lease_writes_no_block_after_the_takeover(s3, s3_env, tmp_path, catalog_dir):
    # the writer is stopped (SIGSTOP) until its lease expired and another writer took the cube
    # over and finished it; resumed (SIGCONT), it must not write a block: its lease is fenced
    spec = _spec(tmp_path, SLOW)
    url = f"{s3}/fence.zarr"
    env = dict(os.environ, FTSWEEP_CATALOGS=str(catalog_dir), FTSWEEP_LOCK_LEASE_S="6", **s3_env)
    cmd = [str(BIN / "ftsweep"), "sweep", str(spec), "--out", url, "--workers", "1"]
    gate = tmp_path / "hold"
    paused = hold.sweep(cmd, env, gate, after=2, output=True, session=False)  # two cases logged
    try:
        os.kill(paused.pid, signal.SIGSTOP)
        _wait_lease_out(f"{url}.lock")
        taker = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
        assert taker.returncode == 0, taker.stderr
        before = _block_tags(url)
        os.kill(paused.pid, signal.SIGCONT)
        hold.let_go(gate)
        _, err = paused.communicate(timeout=180)
    finally:
        if paused.poll() is None:
            os.kill(paused.pid, signal.SIGCONT)
            paused.kill()
            paused.wait()
    assert paused.returncode == 75, err
    last = err.strip().splitlines()[-1]
    assert "lease" in last and ("taken over" in last or "last confirmed" in last), err
    assert _block_tags(url) == before  # not one block (nor the metadata) written after the takeover
    clean = tmp_path / "clean.zarr"
    run_sweep(str(spec), clean, scheduler="synchronous", catalog_folder=catalog_dir)
    xr.testing.assert_equal(_data(url), _data(clean))


def test_the_readme_cluster_example_runs_with_workers_that_lack_the_endpoint(
    s3, s3_env, tmp_path, catalog_dir
):
    """FSSPEC_S3_ENDPOINT_URL set where `ftsweep sweep` runs, an external scheduler and two
    workers started without it (their own credentials only): the endpoint travels with the
    tasks and every case is done. Workers without credentials are refused before any task
    runs, in one line that says what is missing."""
    from support.clusters import external_cluster

    spec = _spec(tmp_path)
    base = {k: v for k, v in os.environ.items() if not k.startswith(("FSSPEC_", "AWS_"))}
    base["FTSWEEP_CATALOGS"] = str(catalog_dir)
    creds = {k: s3_env[k] for k in ("AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY", "AWS_DEFAULT_REGION")}
    driver = {**base, **s3_env}
    for n, worker_env in ((0, {**base, **creds}), (1, base)):
        with external_cluster(tmp_path, worker_env) as cluster:
            for _ in range(2):
                cluster.add_worker(cwd=tmp_path)
            cluster.wait_for_workers(2)
            url = f"{s3}/readme{n}.zarr"
            cmd = [str(BIN / "ftsweep"), "sweep", str(spec), "--out", url, "--scheduler", cluster.address]
            run = subprocess.run(cmd, env=driver, capture_output=True, text=True, timeout=600)
        if n == 0:
            assert run.returncode == 0, run.stderr[-2000:]
            assert done_count(place(url)) == 6
        else:
            assert run.returncode == 1, run.stderr[-2000:]
            assert "cannot reach the cube" in run.stderr and "NoCredentialsError" in run.stderr
            assert run.stderr.strip().splitlines()[-1].startswith("Error: ")


def test_what_the_driver_resolves_travels_and_credentials_stay(s3, s3_env, monkeypatch):
    import fsspec

    from ftsweep.store.storage import with_configured

    monkeypatch.setitem(
        fsspec.config.conf, "s3", {"endpoint_url": "http://here:1", "secret": "s", "key": "k"}
    )
    monkeypatch.setenv("AWS_REGION", "eu-west-3")
    given = place("s3://b/c.zarr", {"endpoint_url": "http://given:2", "token": "t"})
    assert with_configured(given).options == {
        "endpoint_url": "http://given:2",  # explicit options win
        "token": "t",  # and explicit credentials travel
        "client_kwargs": {"region_name": "eu-west-3"},
    }
    assert with_configured(place("s3://b/c.zarr")).options["endpoint_url"] == "http://here:1"
    assert with_configured(place("/tmp/c.zarr")).options == {}


def test_the_notebook_tour_runs_on_a_local_cube_and_its_copy_on_s3(
    s3, s3_env, tmp_path, catalog_dir, monkeypatch
):
    """docs/tour.ipynb in a real kernel: every cell runs, and its answers are the cube's."""
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    spec = _spec(tmp_path)
    local = tmp_path / "tour.zarr"
    run_sweep(str(spec), local, scheduler="synchronous", catalog_folder=catalog_dir)
    run_sweep(str(spec), f"{s3}/tour.zarr", scheduler="synchronous", catalog_folder=catalog_dir)
    for key, value in {
        "FTSWEEP_TOUR_CUBE": str(local),
        "FTSWEEP_TOUR_S3": f"{s3}/tour.zarr",
        "FTSWEEP_CATALOGS": str(catalog_dir),
    }.items():
        monkeypatch.setenv(key, value)
    monkeypatch.delenv("MPLBACKEND", raising=False)  # the kernel draws inline, as a user's does
    notebook = nbformat.read(REPO / "docs" / "tour.ipynb", as_version=4)
    nbclient.NotebookClient(notebook, timeout=600, kernel_name="python3").execute()
    code = [c for c in notebook.cells if c.cell_type == "code"]

    def text(cell) -> str:  # type: ignore[no-untyped-def]
        return "".join(o.get("text", "") + o.get("data", {}).get("text/plain", "") for o in cell.outputs)

    assert "({'pending': 0, 'done': 6, 'failed': 0, 'refused': 0, 'pruned': 0}, True)" in text(code[1])
    chosen = cube.open_dataset(local).load()
    from ftsweep.tools.select import choose

    best = choose(chosen, budget_points=16000)
    assert f"{best['index']})" in text(code[2]) and "um/deg" in text(code[2])
    images = [c for c in code if any("image/png" in o.get("data", {}) for o in c.outputs)]
    assert len(images) == 3  # the three plots shown inline
    assert text(code[-2]).strip() == "(True, True)"  # verified, and the same bytes twice
    assert text(code[-1]).strip() == "s3 True True"


def test_status_of_a_grown_cube_on_s3(s3, tmp_path, catalog_dir):
    """A cube on S3 whose spec gained a point count: status names the growth and the run."""
    spec = _spec(tmp_path)
    url = f"{s3}/grown.zarr"
    run_sweep(str(spec), url, scheduler="synchronous", catalog_folder=catalog_dir)
    spec.write_text(SPEC.replace("[8000, 16000]", "[8000, 16000, 24000]"))
    run_sweep(str(spec), url, scheduler="synchronous", catalog_folder=catalog_dir)
    res = _cli(["status", url, "--json"], catalog_dir)
    found = json.loads(res.stdout)
    assert res.exit_code == 0 and found["complete"] and found["counts"]["done"] == 9
    assert [g["added"] for g in found["grown"]] == ["points +1, aspect +0"]
    assert found["last_run"]["cases"]["done"] == 3 and found["writer"] is None
