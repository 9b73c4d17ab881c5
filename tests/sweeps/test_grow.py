"""Sweeps that grow: values added to a sweep axis extend the cube and only
the new cases are computed; removing values or changing anything else is still refused;
a growth killed midway finishes on the next run; exit statuses a scheduler can act on."""

from __future__ import annotations

import json
import os
import subprocess

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner
from support.clusters import BIN

from ftsweep.cli.main import main
from ftsweep.store import cube
from ftsweep.store.cube import CubeError
from ftsweep.store.storage import place
from ftsweep.sweeps import grow
from ftsweep.sweeps.run import run_sweep

BASE = """
surface: small_sine
layout: ring
axes: {{points: {points}, aspect: {aspect}}}
"""


def _spec(folder, points="[8000, 20000]", aspect="[2.0, 8.0]"):  # type: ignore[no-untyped-def]
    path = folder / "grow.yaml"
    path.write_text(BASE.format(points=points, aspect=aspect))
    return path


def _data(path):  # type: ignore[no-untyped-def]
    return xr.open_zarr(path).drop_vars(list(cube.TIMING_VARS)).load()


@pytest.mark.slow  # 5-7 s on 2 cores: the full command runs it, the quick one leaves it out
def test_added_point_counts_and_aspects_compute_only_the_new_cases(tmp_path, catalog_dir):
    out = tmp_path / "g.zarr"
    first = run_sweep(str(_spec(tmp_path)), out, scheduler="synchronous", catalog_folder=catalog_dir)
    assert first.done == 4
    before = _data(out)
    ids_before = xr.open_zarr(out)["run_id"].values
    # a point count between the old ones, one beyond, and an aspect ratio in front
    spec = _spec(tmp_path, "[8000, 12000, 20000, 30000]", "[1.0, 2.0, 8.0]")
    grown = run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    assert grown.skipped == 4 and grown.queued == 8 and grown.done == 8
    assert "points +2, aspect +1" in grown.note and "8 new case(s), 4 kept" in grown.note
    after = _data(out)
    # the old cases kept their values and run ids, at their new places
    xr.testing.assert_equal(after.sel(points=before["points"], aspect=before["aspect"]), before)
    ids = xr.open_zarr(out)["run_id"].sel(points=before["points"], aspect=before["aspect"]).values
    assert (ids == ids_before).all() and len(set(xr.open_zarr(out)["run_id"].values.ravel())) == 2
    # and the whole equals a sweep of the grown spec from scratch, but for the case numbers:
    # there C order over the grown axes, here the old cases' own and the new ones after them
    clean = tmp_path / "clean.zarr"
    run_sweep(str(spec), clean, scheduler="synchronous", catalog_folder=catalog_dir)
    numbered = cube.CASE_NUMBER
    xr.testing.assert_equal(_data(out).drop_vars(numbered), _data(clean).drop_vars(numbered))
    assert sorted(_data(out)[numbered].values.ravel().tolist()) == list(range(12))
    assert xr.open_zarr(out).attrs["sweep_spec_hash"] == xr.open_zarr(clean).attrs["sweep_spec_hash"]
    again = run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    assert again.queued == 0 and again.note == ""


def test_a_value_moved_is_refused(tmp_path, catalog_dir):
    out = tmp_path / "r.zarr"
    run_sweep(str(_spec(tmp_path)), out, scheduler="synchronous", catalog_folder=catalog_dir)
    with pytest.raises(CubeError, match="may only add values"):
        run_sweep(
            str(_spec(tmp_path, "[8000, 20001]")), out, scheduler="synchronous", catalog_folder=catalog_dir
        )


def test_a_spec_whose_cases_the_cube_holds_resumes_the_cube_as_recorded(tmp_path, catalog_dir):
    """A spec with fewer values (the catalog's sweep, once its cube was grown from a copy of
    it) changes nothing: the cube, larger, is resumed as it records, under its own name."""
    out = tmp_path / "r.zarr"
    run_sweep(str(_spec(tmp_path)), out, scheduler="synchronous", catalog_folder=catalog_dir)
    before = _data(out)
    fewer = _spec(tmp_path, "[8000]")
    again = run_sweep(str(fewer), out, scheduler="synchronous", catalog_folder=catalog_dir)
    assert again.queued == 0 and again.total == 4
    assert "holds every case of this spec and more (points +1, aspect +0" in again.note
    xr.testing.assert_equal(_data(out), before)


def test_a_grown_cube_keeps_its_name_and_case_numbers_and_its_catalog_command(tmp_path, catalog_dir):
    """Grown from a copy of its spec under another file name: the sweep keeps its name, every
    case its number (new cases numbered after), select names cases by coordinates, the original
    spec still runs on the cube, and a header exported before the growth verifies as the
    cube's case of its coordinates."""
    out = tmp_path / "g.zarr"
    first = tmp_path / "nightly.yaml"
    first.write_text(BASE.format(points="[8000, 20000]", aspect="[2.0, 8.0]"))
    run_sweep(str(first), out, scheduler="synchronous", catalog_folder=catalog_dir)
    env = {"FTSWEEP_CATALOGS": str(catalog_dir)}
    header = tmp_path / "before.h"
    r = CliRunner().invoke(
        main, ["export", str(out), "--case", "points=20000,aspect=8", "-o", str(header)], env=env
    )
    assert r.exit_code == 0, r.output
    assert "case         points=20000 aspect=8 (case number 3)" in r.output
    numbers = xr.open_zarr(out)["case_number"].load()
    copy = tmp_path / "copy.yaml"
    copy.write_text(BASE.format(points="[8000, 12000, 20000]", aspect="[2.0, 8.0]"))
    grown = run_sweep(str(copy), out, scheduler="synchronous", catalog_folder=catalog_dir)
    assert grown.done == 2
    ds = xr.open_zarr(out).load()
    assert ds.attrs["sweep_name"] == "nightly"  # not the copy's file name
    # every old case keeps its number; the two new ones come after
    xr.testing.assert_equal(ds["case_number"].sel(points=[8000, 20000]), numbers)
    assert sorted(ds["case_number"].sel(points=12000).values.tolist()) == [4, 5]
    # number 3 is still points=20000 aspect=8, whose flat index is now 5
    for how in ("3", "points=20000 aspect=8.0"):
        r = CliRunner().invoke(
            main, ["export", str(out), "--case", how, "-o", str(tmp_path / "n.h"), "--force"], env=env
        )
        assert r.exit_code == 0 and "case         points=20000 aspect=8 (case number 3)" in r.output, r.output
    # the cube's first spec still runs on it: nothing to compute
    again = run_sweep(str(first), out, scheduler="synchronous", catalog_folder=catalog_dir)
    assert again.queued == 0 and "resuming sweep 'nightly'" in again.note
    # the header exported before the growth is still the cube's case of its coordinates
    v = CliRunner().invoke(main, ["verify", str(header), "--expect-case", "points=20000,aspect=8"], env=env)
    assert v.exit_code == 0, v.output
    assert "for          case points=20000 aspect=8 of" in v.output
    assert "in cube      the cube's case points=20000 aspect=8 (number 3) is the file's case" in v.output
    # the growth rebuilt the cube, its export ledger with it: the rollback check still holds
    assert "latest       the latest export of before.h in the cube's ledger (sequence 1)" in v.output
    wrong = CliRunner().invoke(
        main, ["verify", str(header), "--expect-case", "points=8000,aspect=8"], env=env
    )
    assert wrong.exit_code != 0 and "not the expected points=8000 aspect=8" in wrong.output
    # a case the cube does not hold is refused naming the axis' values
    r = CliRunner().invoke(
        main, ["export", str(out), "--case", "points=9000,aspect=8", "-o", str(tmp_path / "x.h")], env=env
    )
    assert r.exit_code != 0 and "axis points has no value 9000 (its values: 8000, 12000, 20000)" in r.output


def test_verify_says_when_the_cube_no_longer_holds_the_files_case(tmp_path, catalog_dir):
    out = tmp_path / "s.zarr"
    run_sweep(str(_spec(tmp_path)), out, scheduler="synchronous", catalog_folder=catalog_dir)
    env = {"FTSWEEP_CATALOGS": str(catalog_dir)}
    header = tmp_path / "h.h"
    r = CliRunner().invoke(
        main, ["export", str(out), "--case", "points=8000,aspect=2", "-o", str(header)], env=env
    )
    assert r.exit_code == 0, r.output
    # started over with another aspect axis: the file's coordinates are gone
    run_sweep(
        str(_spec(tmp_path, aspect="[3.0]")),
        out,
        scheduler="synchronous",
        catalog_folder=catalog_dir,
        restart=True,
    )
    v = CliRunner().invoke(main, ["verify", str(header), "--json"], env=env)
    assert "no longer holds the file's case points=8000 aspect=2" in v.output, v.output


def test_another_change_with_added_values_is_refused(tmp_path, catalog_dir):
    out = tmp_path / "m.zarr"
    run_sweep(str(_spec(tmp_path)), out, scheduler="synchronous", catalog_folder=catalog_dir)
    spec = _spec(tmp_path, "[8000, 12000, 20000]")
    spec.write_text(spec.read_text() + "machine: sluggish-fts\n")
    with pytest.raises(CubeError, match="changed: .*machine"):
        run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)


def test_a_growth_killed_midway_is_finished_by_the_next_run(tmp_path, catalog_dir, monkeypatch):
    out = tmp_path / "k.zarr"
    run_sweep(str(_spec(tmp_path)), out, scheduler="synchronous", catalog_folder=catalog_dir)
    before = _data(out)

    def killed(staging, target):  # type: ignore[no-untyped-def]
        target.remove_all()  # the old cube deleted, the new one not yet moved in
        raise KeyboardInterrupt

    monkeypatch.setattr(grow, "_move_in", killed)
    spec = _spec(tmp_path, "[8000, 12000, 20000]")
    with pytest.raises(KeyboardInterrupt):
        run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    assert not out.exists() and place(str(out) + grow.STAGING).exists()
    monkeypatch.undo()
    report = run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    assert report.skipped == 4 and report.done == 2
    xr.testing.assert_equal(_data(out).sel(points=before["points"]), before)
    assert not place(str(out) + grow.STAGING).exists()


@pytest.mark.integration  # runs ftsweep in subprocesses
def test_a_scheduled_run_whose_spec_grows_and_its_exit_statuses(tmp_path, catalog_dir):
    """The README's cron example: the same command every night; the spec gains a point count."""
    env = dict(os.environ, FTSWEEP_CATALOGS=str(catalog_dir))
    out = tmp_path / "nightly.zarr"
    spec = _spec(tmp_path)
    cmd = [str(BIN / "ftsweep"), "sweep", str(spec), "--out", str(out), "--scheduler", "synchronous"]
    night1 = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert night1.returncode == 0, night1.stderr
    _spec(tmp_path, "[8000, 20000, 40000]")
    night2 = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert night2.returncode == 0, night2.stderr
    assert "grown: points +1, aspect +0 values; 2 new case(s), 4 kept" in night2.stdout
    assert "(4 were done already, 2 run now)" in night2.stdout
    status = subprocess.run(
        [str(BIN / "ftsweep"), "status", str(out), "--json"],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    found = json.loads(status.stdout)
    assert status.returncode == 0 and found["complete"] and found["counts"]["done"] == 6
    assert [g["added"] for g in found["grown"]] == ["points +1, aspect +0"]
    assert found["last_run"]["cases"] == {"done": 2, "failed": 0, "refused": 0, "pruned": 0}
    # another run holds the lock: 75, try later
    from ftsweep.store.lock import cube_lock

    with cube_lock(out, "a long run"):
        locked = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert locked.returncode == 75 and "is being written by" in locked.stderr
    # cases that cannot run: 1 (a point count over the machine's capacity is refused, not run)
    _spec(tmp_path, "[8000, 20000, 40000, 3000000]")
    failing = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert failing.returncode == 1 and "0 failed, 2 refused" in failing.stdout
    assert "refused      2 case(s), e.g." in failing.stdout and "capacity" in failing.stdout
    r = CliRunner().invoke(main, ["sweep", str(spec), "--out", str(out), "--workers", "0"], env=env)
    assert r.exit_code == 2  # a usage error
    assert np.sum(cube.read_status(out) == cube.DONE) == 6


@pytest.mark.parametrize("grows", [False, True], ids=["resume", "growth"])
def test_a_cube_never_mixes_catalogs(tmp_path, catalog_dir, grows):
    # the catalog's surface edited after the cube was computed: neither a plain resume nor a
    # growth may compute new cases with the edited entry under the old record
    out = tmp_path / "g.zarr"
    run_sweep(str(_spec(tmp_path)), out, scheduler="synchronous", catalog_folder=catalog_dir)
    surfaces = catalog_dir / "surfaces.yaml"
    surfaces.write_text(surfaces.read_text().replace("amplitude_x_um: 0.5,", "amplitude_x_um: 0.25,", 1))
    spec = _spec(tmp_path, "[8000, 12000, 20000]") if grows else _spec(tmp_path)
    with pytest.raises(
        CubeError, match=r"surface 'small_sine'.params.amplitude_x_um: recorded 0.5, .* has 0.25"
    ):
        run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    assert xr.open_zarr(out).sizes["points"] == 2  # untouched
    again = run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir, restart=True)
    assert again.done == (6 if grows else 4)
