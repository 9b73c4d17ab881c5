"""Sweeps on Dask into Zarr cubes: specs, schedulers, crash safety."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from support import hold
from support.clusters import external_cluster

from ftsweep.inputs.catalogs import CatalogError
from ftsweep.store import caselog, cube
from ftsweep.store.cube import CubeError
from ftsweep.sweeps.run import run_sweep
from ftsweep.sweeps.spec import case_at, load_sweep, n_cases
from ftsweep.tools.query import best_per_point_count

SMALL = """
description: a small sweep for tests
surface: small_sine
layout: ring
axes:
  points: [8000, 20000]
  aspect: {start: 1.0, stop: 16.0, num: 3}
"""

BIN = Path(sys.executable).parent


def write_spec(folder: Path, text: str = SMALL, name: str = "small.yaml") -> Path:
    path = folder / name
    path.write_text(text)
    return path


def data_of(path: Path) -> xr.Dataset:
    """The cube's values without the wall-time variables (which differ run to run)."""
    return xr.open_zarr(path).drop_vars(list(cube.TIMING_VARS)).load()


# ----------------------------------------------------------------------------- specs
def test_reference_sweeps_validate_and_cover_the_ranges():
    for name, lo, hi, alo, ahi in (
        ("sinewave-ring", 9e4, 1e6, 0.3, 400),
        ("lens-array-mesh", 4e4, 1e6, 0.08, 16),
    ):
        _, spec = load_sweep(name)
        from ftsweep.sweeps.spec import coordinates

        c = coordinates(spec)
        assert c["points"].size >= 6 and c["aspect"].size >= 12
        assert c["points"].min() == pytest.approx(lo, rel=0.15) and c["points"].max() == pytest.approx(
            hi, rel=0.02
        )
        assert c["aspect"].min() == pytest.approx(alo) and c["aspect"].max() == pytest.approx(ahi)


@pytest.mark.parametrize(
    "text, message",
    [
        (SMALL.replace("layout: ring", "layout: ring\ncolour: red"), "colour: unknown key"),
        (SMALL.replace("points: [8000, 20000]", "points: []"), "axes.points: the axis is empty"),
        (SMALL.replace("points: [8000, 20000]", "points: [8000, -5]"), "axes.points"),
        (SMALL.replace("start: 1.0", "start: 0"), "axes.aspect"),
        (SMALL.replace("surface: small_sine", "surface: teapot"), "key 'surface': unknown surface 'teapot'"),
        (SMALL + "machine: fts-9\n", "key 'machine': unknown machine 'fts-9'"),
        (
            SMALL.replace("  aspect: {start: 1.0, stop: 16.0, num: 3}\n", ""),
            "axes.aspect: required key is missing",
        ),
        (SMALL.replace("num: 3", "num: 3, spacing: 2"), "spacing: unknown key"),
        # every rule is the model's, checked when the file is loaded
        (SMALL.replace("surface: small_sine", "surface: [a, b]"), "surface"),
        (SMALL + "  feed_um: [1.0, 170.0]\n", "axes.feed_um: feed 170 µm/rev is not below twice the nose"),
        (
            SMALL + "  nose_radius_um: [0.4, 50.0]\n",
            "axes.nose_radius_um: feed 1 µm/rev is not below twice the nose radius (0.8 µm)",
        ),
        (SMALL.replace("points: [8000, 20000]", "points: [8000, .inf]"), "axes.points"),
    ],
)
def test_spec_errors_name_the_file_and_key(tmp_path, catalog_dir, text, message):
    path = write_spec(tmp_path, text)
    with pytest.raises(CatalogError) as err:
        load_sweep(str(path), catalog_dir)
    assert str(path) in str(err.value)
    assert message in str(err.value)


def test_unknown_sweep_name_lists_the_known_ones():
    with pytest.raises(CatalogError, match="sinewave-ring"):
        load_sweep("no-such-sweep")


def test_expansion_order_and_cases(tmp_path, catalog_dir):
    _, spec = load_sweep(str(write_spec(tmp_path)), catalog_dir)
    assert n_cases(spec) == 6
    case = case_at(spec, 4)  # C order: points index 1, aspect index 1
    assert case.layout.points == 20000 and case.layout.aspect == pytest.approx(4.0)


# ----------------------------------------------------------------------------- schedulers
@pytest.fixture()
def reference_cube(tmp_path, catalog_dir):
    """The small sweep computed with dask's synchronous scheduler."""
    out = tmp_path / "sync.zarr"
    report = run_sweep(str(write_spec(tmp_path)), out, scheduler="synchronous", catalog_folder=catalog_dir)
    assert report.done == 6 and report.failed == 0
    return out


@pytest.mark.slow  # 5-7 s on 2 cores: the full command runs it, the quick one leaves it out
def test_local_cluster_equals_synchronous_value_for_value(tmp_path, catalog_dir, reference_cube):
    out = tmp_path / "cluster.zarr"
    report = run_sweep(str(write_spec(tmp_path)), out, workers=2, catalog_folder=catalog_dir)
    assert report.done == 6
    xr.testing.assert_equal(data_of(out), data_of(reference_cube))


@pytest.mark.integration  # an external scheduler and workers
def test_external_dask_scheduler_and_workers_give_the_same_cube(tmp_path, catalog_dir, reference_cube):
    """The README's --scheduler example with a relative --out: the workers run in another
    folder than the client, so the cube path must reach them absolute."""
    env = dict(os.environ, FTSWEEP_CATALOGS=str(catalog_dir))
    worker_dir, client_dir = tmp_path / "workers", tmp_path / "client"
    worker_dir.mkdir()
    client_dir.mkdir()
    with external_cluster(tmp_path, env) as cluster:
        assert cluster.address.startswith("tcp://127.0.0.1:")
        for _ in range(2):
            cluster.add_worker(cwd=worker_dir)
        cluster.wait_for_workers(2)
        result = subprocess.run(
            [
                str(BIN / "ftsweep"),
                "sweep",
                str(write_spec(tmp_path)),
                "--out",
                "outputs/remote.zarr",
                "--scheduler",
                cluster.address,
            ],
            capture_output=True,
            text=True,
            env=env,
            cwd=client_dir,
            timeout=300,
        )
    assert result.returncode == 0, result.stderr
    assert not (worker_dir / "outputs").exists()
    xr.testing.assert_equal(data_of(client_dir / "outputs" / "remote.zarr"), data_of(reference_cube))
    # the summary counts the cluster's workers, not this machine's cores
    assert "2 worker(s), 2 thread(s)" in result.stderr and "on 2 worker(s), 2 thread(s)" in result.stdout


# ----------------------------------------------------------------------------- crash safety
KILL_SPEC = """
surface: small_sine
layout: ring
axes:
  points: [6000, 9000, 12000, 16000, 20000, 25000]
  aspect: [2.0, 8.0]
cases_per_task: 1
"""


@pytest.mark.integration  # a sweep process killed midway
@pytest.mark.serial
def test_killed_sweep_loses_nothing_and_resumes(tmp_path, catalog_dir):
    """kill -9 of a sweep (its driver and its worker) once three cases are logged, its worker
    held there (tests/support/hold.py): the re-run keeps those three and computes the rest."""
    spec = write_spec(tmp_path, KILL_SPEC, "kill.yaml")
    env = dict(os.environ, FTSWEEP_CATALOGS=str(catalog_dir))
    out = tmp_path / "killed.zarr"
    cmd = [str(BIN / "ftsweep"), "sweep", str(spec), "--out", str(out), "--workers", "1"]
    proc = hold.sweep(cmd, env, tmp_path / "hold", after=3)
    os.killpg(proc.pid, signal.SIGKILL)  # the driver and its worker processes
    proc.wait()
    # the cases its workers logged since the driver's last merge are merged by the next writer
    # (the re-run below does that first); merge them here to see what the kill left
    caselog.merge_logs(out)
    first = xr.open_zarr(out).load()
    done_mask = first["status"].values == cube.DONE
    assert done_mask.sum() == 3
    first_ids = first["run_id"].values[done_mask]

    rerun = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert rerun.returncode == 0, rerun.stderr
    assert f"{int(done_mask.sum())} were done already" in rerun.stdout
    final = xr.open_zarr(out).load()
    assert np.all(final["status"].values == cube.DONE)
    # finished cases were not recomputed: they keep the first run's id
    np.testing.assert_array_equal(final["run_id"].values[done_mask], first_ids)
    assert len(set(final["run_id"].values[~done_mask])) == 1
    assert set(final["run_id"].values[~done_mask]).isdisjoint(first_ids)

    clean = tmp_path / "clean.zarr"
    run_sweep(str(spec), clean, scheduler="synchronous", catalog_folder=catalog_dir)
    xr.testing.assert_equal(data_of(out), data_of(clean))


def test_torn_status_chunk_reads_as_pending(reference_cube, tmp_path, catalog_dir):
    # the six cases share one block (cube.case_chunks); blocks are replaced whole (a rename,
    # a PUT), so only damage from outside can tear one: its cases are then computed again
    chunk = reference_cube / "status" / "c" / "0" / "0"
    assert chunk.exists() and not (reference_cube / "status" / "c" / "1").exists()
    chunk.write_bytes(chunk.read_bytes()[:1])
    status = cube.read_status(reference_cube)
    assert np.all(status == cube.PENDING)
    report = run_sweep(
        str(write_spec(tmp_path)), reference_cube, scheduler="synchronous", catalog_folder=catalog_dir
    )
    assert report.skipped == 0 and report.done == 6
    assert np.all(cube.read_status(reference_cube) == cube.DONE)


def test_refused_cases_are_listed_not_run_and_never_retried(tmp_path, catalog_dir):
    """Cases over the controller's capacity are refused before any is sent (their reason
    recorded, nothing computed); neither a re-run nor --retry-failed runs them again
    (--retry-failed reconsiders them, and the driver's own check refuses them again at once)."""
    text = SMALL.replace("points: [8000, 20000]", "points: [8000, 3000000]")  # over capacity
    out = tmp_path / "refused.zarr"
    report = run_sweep(
        str(write_spec(tmp_path, text)), out, scheduler="synchronous", catalog_folder=catalog_dir
    )
    assert report.done == 3 and report.failed == 0 and len(report.refused) == 3
    assert report.queued == 3 and len(report.rows) == 3  # the refused ones were never sent
    ds = xr.open_zarr(out)
    assert np.all(ds["status"].values[0] == cube.DONE)
    assert np.all(ds["status"].values[1] == cube.REFUSED)
    assert all("over the capacity" in m for m in ds["message"].values[1])
    assert np.all(np.isnan(ds["pv_nm"].values[1]))
    for retry in (False, True):
        again = run_sweep(
            str(write_spec(tmp_path, text)),
            out,
            scheduler="synchronous",
            catalog_folder=catalog_dir,
            retry_failed=retry,
        )
        assert again.rows == [] and len(again.refused) == (3 if retry else 0)
    assert all("over the capacity" in m for m in xr.open_zarr(out)["message"].values[1])
    best = best_per_point_count(out)
    assert best[0]["pv_nm"] is not None and best[1]["pv_nm"] is None


def test_failed_case_is_recorded_and_the_rest_run_on(tmp_path, catalog_dir, monkeypatch):
    """A case that breaks (not one its planning refuses) is recorded failed; a plain re-run
    leaves it, --retry-failed runs it again."""
    from ftsweep.sweeps import executor

    real = executor.run_case

    def flaky(case, *args, **kw):  # type: ignore[no-untyped-def]
        if case.layout.points == 20000:
            raise MemoryError("the worker ran out of memory")
        return real(case, *args, **kw)

    monkeypatch.setattr(executor, "run_case", flaky)
    out = tmp_path / "fail.zarr"
    report = run_sweep(
        str(write_spec(tmp_path, SMALL)), out, scheduler="synchronous", catalog_folder=catalog_dir
    )
    assert report.done == 3 and report.failed == 3
    ds = xr.open_zarr(out)
    assert np.all(ds["status"].values[1] == cube.FAILED)
    assert all("MemoryError" in m for m in ds["message"].values[1])
    again = run_sweep(
        str(write_spec(tmp_path, SMALL)), out, scheduler="synchronous", catalog_folder=catalog_dir
    )
    assert again.rows == []
    monkeypatch.setattr(executor, "run_case", real)
    retry = run_sweep(
        str(write_spec(tmp_path, SMALL)),
        out,
        scheduler="synchronous",
        catalog_folder=catalog_dir,
        retry_failed=True,
    )
    assert len(retry.rows) == 3 and retry.done == 3
    assert all(row["pv_nm"] is not None for row in best_per_point_count(out))


def test_existing_cube_is_never_silently_overwritten(tmp_path, catalog_dir, reference_cube):
    # aspects that move (1 and 12 against 1, 4 and 16): neither growth nor a part of the cube
    changed = SMALL.replace("num: 3", "num: 2").replace("stop: 16.0", "stop: 12.0")
    with pytest.raises(CubeError, match="different spec.*--restart"):
        run_sweep(
            str(write_spec(tmp_path, changed)),
            reference_cube,
            scheduler="synchronous",
            catalog_folder=catalog_dir,
        )
    report = run_sweep(
        str(write_spec(tmp_path, changed)),
        reference_cube,
        scheduler="synchronous",
        catalog_folder=catalog_dir,
        restart=True,
    )
    assert report.total == 4 and report.done == 4
    before = set(xr.open_zarr(reference_cube)["run_id"].values.ravel())
    again = run_sweep(
        str(write_spec(tmp_path, changed)),
        reference_cube,
        scheduler="synchronous",
        catalog_folder=catalog_dir,
        restart=True,
    )  # same spec: --restart still starts over
    assert again.skipped == 0 and again.done == 4
    assert set(xr.open_zarr(reference_cube)["run_id"].values.ravel()).isdisjoint(before)
    not_a_cube = tmp_path / "plain"
    not_a_cube.mkdir()
    (not_a_cube / "notes.txt").write_text("keep me")
    with pytest.raises(CubeError, match="not a Zarr cube|not an ftsweep cube"):
        run_sweep(str(write_spec(tmp_path)), not_a_cube, scheduler="synchronous", catalog_folder=catalog_dir)
    assert (not_a_cube / "notes.txt").read_text() == "keep me"


# ----------------------------------------------------------------------------- cube contents
def test_cube_opens_in_a_plain_python_session_with_coordinates_and_units(reference_cube):
    code = (
        "import xarray as xr, sys; ds = xr.open_zarr(sys.argv[1]); print(ds);"
        "print({v: ds[v].attrs.get('units') for v in ds.variables})"
    )
    out = subprocess.run(
        [sys.executable, "-c", code, str(reference_cube)], capture_output=True, text=True, check=True
    )
    assert "* points" in out.stdout and "* aspect" in out.stdout
    assert "'pv_nm': 'nm'" in out.stdout and "'seconds': 's'" in out.stdout
    ds = xr.open_zarr(reference_cube)
    for name, var in ds.variables.items():
        assert "long_name" in var.attrs, name
        # numbers carry units; flags (status) and text follow CF and carry none
        numeric = var.dtype.kind in "fiu" and "flag_values" not in var.attrs
        assert ("units" in var.attrs) == numeric, name
    # a ring cube names its pitches by their physics, with parseable units
    assert ds["drho_um"].attrs["units"] == "um" and ds["dtheta_deg"].attrs["units"] == "deg"
    assert ds["aspect"].attrs["units"] == "um/deg" and "pitch_0" not in ds
    for key in ("ftsweep_version", "git_revision", "sweep_spec", "catalog_entries", "created"):
        assert ds.attrs[key]
    entries = json.loads(ds.attrs["catalog_entries"])
    assert "small_sine" in entries["surface"] and "fts-1m" in entries["machine"]
    assert set(ds["status"].values.ravel()) == {cube.DONE}
    assert np.all(ds["pv_nm"].values > 0)


def test_provenance_is_ftsweeps_own_revision_not_the_callers(tmp_path):
    """A copy of ftsweep installed inside a user's git project (its virtual environment in
    the project's folder, untracked) records no revision rather than the project's."""
    import shutil
    import subprocess

    from ftsweep import version

    def git(*args):
        return subprocess.run(["git", *args], cwd=tmp_path, capture_output=True, text=True, check=True)

    git("init", "-q")
    (tmp_path / "notes.txt").write_text("a user's project\n")
    git("add", "notes.txt")
    git("-c", "user.name=u", "-c", "user.email=u@x", "commit", "-q", "-m", "user")
    installed = tmp_path / ".venv" / "lib" / "ftsweep"
    installed.mkdir(parents=True)
    copy = Path(shutil.copy(version.__file__, installed / "version.py"))
    assert version.git_revision(copy) == "unknown"
    git("add", "-f", str(copy))  # tracked by that repository: a checkout of its own
    git("-c", "user.name=u", "-c", "user.email=u@x", "commit", "-q", "-m", "vendored")
    assert version.git_revision(copy) == git("rev-parse", "HEAD").stdout.strip()


@pytest.mark.slow  # 5-7 s on 2 cores: the full command runs it, the quick one leaves it out
def test_resuming_another_revisions_cube_warns_in_one_line(tmp_path, catalog_dir):
    """The command line prints the warning as one line (pytest would capture it in process)."""
    import zarr

    spec, out = write_spec(tmp_path), tmp_path / "c.zarr"
    args = [
        sys.executable,
        "-m",
        "ftsweep.cli.main",
        "sweep",
        str(spec),
        "--out",
        str(out),
        "--scheduler",
        "synchronous",
    ]
    env = {**os.environ, "FTSWEEP_CATALOGS": str(catalog_dir)}
    assert subprocess.run(args, env=env, capture_output=True, text=True).returncode == 0
    zarr.open_group(str(out), mode="r+").attrs["git_revision"] = "0123456789abcdef"
    r = subprocess.run(args, env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if "code revision" in ln]
    assert len(lines) == 1 and lines[0].startswith("Warning: ") and "0123456789" in lines[0], r.stderr
    assert "UserWarning" not in r.stderr and "warnings.warn(" not in r.stderr


def test_the_sweep_command_reads_its_spec_once(tmp_path, monkeypatch):
    """The command checks the spec before anything runs and hands what it read to the run: the
    file is read once (refused here by --max-cases, after both had their look)."""
    from click.testing import CliRunner

    from ftsweep.cli.main import main
    from ftsweep.inputs import catalogs

    reads = []
    real = catalogs.read_yaml_file

    def counted(path, *args, **kwargs):
        reads.append(Path(path).name)
        return real(path, *args, **kwargs)

    monkeypatch.setattr(catalogs, "read_yaml_file", counted)
    out = tmp_path / "c.zarr"
    r = CliRunner().invoke(main, ["sweep", "sinewave-ring", "--out", str(out), "--max-cases", "1"])
    assert r.exit_code == 1 and "over the limit of 1 cases" in r.output, r.output
    assert reads.count("sinewave-ring.yaml") == 1, reads
    assert not out.exists()
