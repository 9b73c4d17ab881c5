"""Fit the ecosystem: one installed package ``ftsweep``, cubes with physics names
and parseable units, realisable pitches by rounding, catalogs printed whole."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import sysconfig
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import zarr
from click.testing import CliRunner
from support.places import REPO

from ftsweep.cli.main import main
from ftsweep.inputs import catalogs
from ftsweep.store import cube
from ftsweep.store.cube import CubeError
from ftsweep.sweeps.run import run_sweep
from ftsweep.tools.select import open_cube

SPEC = """
surface: {surface}
axes: {{points: [8000, 15000], aspect: [{aspects}]}}
"""


@pytest.fixture(scope="module")
def cubes(tmp_path_factory, module_catalog_dir):
    """A small ring cube and a small mesh cube."""
    folder = tmp_path_factory.mktemp("cubes")
    out = {}
    for kind, surface, aspects in (("ring", "small_sine", "2.0, 8.0"), ("mesh", "small_lens", "0.5, 1.0")):
        spec = folder / f"{kind}.yaml"
        spec.write_text(SPEC.format(surface=surface, aspects=aspects))
        out[kind] = folder / f"{kind}.zarr"
        run_sweep(str(spec), out[kind], scheduler="synchronous", catalog_folder=module_catalog_dir)
    return out


# ----------------------------------------------------------------------------- units
@pytest.mark.parametrize("kind", ["ring", "mesh"])
def test_cube_quantifies_with_pint_and_converts(cubes, kind):
    pint_xarray = pytest.importorskip("pint_xarray")
    assert pint_xarray
    ds = xr.open_zarr(cubes[kind])
    q = ds.pint.quantify()
    pv_um = q["pv_nm"].pint.to("um")
    np.testing.assert_allclose(pv_um.pint.magnitude, ds["pv_nm"].values / 1000.0)
    assert str(q["w_accel_peak_m_s2"].pint.units) == "meter / second ** 2"
    assert str(q["w_freq_max_hz"].pint.units) == "hertz"
    names = ("drho_um", "dtheta_deg") if kind == "ring" else ("dx_um", "dy_um")
    for name in names:
        assert name in ds and np.all(np.isfinite(ds[name].values))
    assert "pitch_0" not in ds and "pitch_1" not in ds
    assert str(q["aspect"].pint.units) == ("micrometer / degree" if kind == "ring" else "dimensionless")
    assert str(q[names[1]].pint.units) == ("degree" if kind == "ring" else "micrometer")
    # the realised aspect ratio is the ratio of the realised pitches
    np.testing.assert_allclose(ds["aspect_actual"], ds[names[0]] / ds[names[1]], rtol=1e-12)


@pytest.mark.parametrize("kind", ["ring", "mesh"])
def test_every_accessor_result_carries_units_pint_reads(cubes, kind):
    """What ``ds.ftsweep`` returns quantifies with the units of what it is."""
    pytest.importorskip("pint_xarray")
    import pint

    ds = xr.open_zarr(cubes[kind])
    done = ds.ftsweep.done()
    quantified = done.pint.quantify()
    for name in done.data_vars:
        # masking keeps every variable's units (a flag keeps none)
        assert done[name].attrs.get("units") == ds[name].attrs.get("units"), name
        if "units" in ds[name].attrs:
            assert quantified[name].pint.units == pint.Unit(ds[name].attrs["units"]), name
    assert done.pint.quantify()["pv_nm"].pint.units == pint.Unit("nm")
    assert ds.ftsweep.pv().pint.quantify().pint.units == pint.Unit("nm")
    optimum = ds.ftsweep.optimum().pint.quantify()
    assert optimum.pint.units == pint.Unit(ds["aspect"].attrs["units"])
    assert optimum.pint.units == pint.Unit("um/deg" if kind == "ring" else "1")
    # best() is a selection of the cube: its dimensions kept (length 1), coordinates and units
    # intact, so units libraries read it as they read the cube; a variable's unit suffix is
    # its unit
    best = ds.ftsweep.best(budget_points=20000)
    assert dict(best.sizes) == dict.fromkeys(ds["status"].dims, 1)
    assert best["points"].attrs == ds["points"].attrs and best.pint.quantify()[
        "pv_nm"
    ].pint.units == pint.Unit("nm")
    suffixes = {"nm": "nm", "um": "um", "deg": "deg"}
    checked = 0
    for key in best.data_vars:
        suffix = str(key).rsplit("_", 1)[-1]
        if suffix in suffixes and "units" in best[key].attrs:
            assert pint.Unit(best[key].attrs["units"]) == pint.Unit(suffixes[suffix]), key
            checked += 1
    assert checked >= 6


def test_import_ftsweep_registers_the_accessor(cubes):
    code = (
        "import sys, xarray as xr, ftsweep; ds = xr.open_zarr(sys.argv[1]); "
        "print(ds.ftsweep.best(budget_points=20000)['dtheta_deg'].item())"
    )
    out = subprocess.run([sys.executable, "-c", code, str(cubes["ring"])], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert float(out.stdout) > 0


def test_cube_of_the_old_layout_is_refused_with_how_to_recompute(tmp_path, module_catalog_dir):
    spec = tmp_path / "old.yaml"
    spec.write_text(SPEC.format(surface="small_sine", aspects="2.0"))
    out = tmp_path / "old.zarr"
    run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=module_catalog_dir)
    group = zarr.open_group(str(out), mode="r+")
    group.attrs["ftsweep_cube_schema"] = 1  # as written before the variables were renamed
    zarr.consolidate_metadata(str(out))
    with pytest.raises(CubeError, match="older ftsweep.*--restart"):
        open_cube(out)
    with pytest.raises(CubeError, match="older ftsweep"):
        run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=module_catalog_dir)
    report = run_sweep(
        str(spec), out, scheduler="synchronous", catalog_folder=module_catalog_dir, restart=True
    )
    assert report.done == 2 and open_cube(out).attrs["ftsweep_cube_schema"] == cube.SCHEMA_VERSION


# ----------------------------------------------------------------------------- pitches
def test_unrealisable_dtheta_is_rounded_with_a_notice(catalog_dir):
    env = {"FTSWEEP_CATALOGS": str(catalog_dir)}
    args = ["predict", "--surface", "small_sine", "--drho-um", "10", "--dtheta-deg", "0.7", "--json"]
    r = CliRunner().invoke(main, args, env=env)
    assert r.exit_code == 0, r.output
    record = json.loads(r.stdout)
    assert record["dtheta_deg"] == pytest.approx(360.0 / 514) and record["table_cols"] == 514
    notice = r.stderr.strip().splitlines()
    assert len(notice) == 1 and "0.7" in notice[0] and "0.7003891" in notice[0] and "514" in notice[0]
    strict = CliRunner().invoke(main, [*args, "--strict"], env=env)
    assert strict.exit_code != 0 and "does not divide 360" in strict.output
    # the value the refusal suggests is accepted as it is printed
    suggested = strict.output.split("e.g. ")[1].split(" ")[0]
    again = CliRunner().invoke(main, [*args[:-2], suggested, "--strict", "--json"], env=env)
    assert again.exit_code == 0, again.output
    assert json.loads(again.stdout)["n_points"] == record["n_points"]
    exact = CliRunner().invoke(main, [*args[:-2], "0.5", "--json"], env=env)
    assert exact.exit_code == 0 and "notice" not in exact.stderr  # 0.5 divides 360: no notice


# ----------------------------------------------------------------------------- catalogs
def test_catalogs_prints_whole_descriptions_and_json():
    r = CliRunner().invoke(main, ["catalogs"])
    assert r.exit_code == 0, r.output
    flat = " ".join(r.output.split())
    for kind in ("surfaces", "machines", "cutting"):
        for name, spec in catalogs.entries(kind).items():
            assert f"{name}" in flat
            assert " ".join(spec.description.split()) in flat, name
    assert max(len(line) for line in r.output.splitlines()) <= 120
    data = json.loads(CliRunner().invoke(main, ["catalogs", "--json"]).stdout)
    assert set(data["surfaces"]) == set(catalogs.entries("surfaces"))
    assert data["machines"]["fts-1m"]["capacity_points"] > 0
    assert "sinewave-ring" in data["sweeps"]


# ----------------------------------------------------------------------------- packaging
def _borrowing_venv(venv: Path) -> tuple[Path, str]:
    """A fresh virtual environment at ``venv`` that borrows this one's dependencies through a
    .pth line (whose own .pth files, the editable install among them, are not processed):
    its python and its site-packages folder."""
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=300)
    py = venv / "bin" / "python"
    site = subprocess.run(
        [str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    (Path(site) / "borrowed_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    return py, site


@pytest.mark.integration  # builds a wheel into a fresh virtual environment
def test_wheel_installs_one_package_named_ftsweep(tmp_path):
    """A regular (non-editable) install: build the wheel, install it without dependencies into
    a fresh virtual environment that borrows this environment's dependencies through a .pth
    line (whose own .pth files, the editable install among them, are not processed), and use
    it from a folder outside the repository."""
    dist = tmp_path / "dist"
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist), str(REPO)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert build.returncode == 0, build.stderr
    wheel = next(dist.glob("ftsweep-*.whl"))
    import zipfile

    tops = {name.split("/")[0] for name in zipfile.ZipFile(wheel).namelist()}
    assert {t for t in tops if not t.endswith(".dist-info")} == {"ftsweep"}
    # the license as a PEP 639 expression (a TOML table stops building in 2027)
    with zipfile.ZipFile(wheel) as zf:
        meta = zf.read(next(n for n in zf.namelist() if n.endswith(".dist-info/METADATA"))).decode()
    assert "License-Expression: BSD-3-Clause" in meta.splitlines()
    assert "License-File: LICENSE" in meta.splitlines()
    assert "project.license` as a TOML table is deprecated" not in build.stderr
    venv = tmp_path / "fresh"
    py, site = _borrowing_venv(venv)
    subprocess.run(
        [str(py), "-m", "pip", "install", "-q", "--no-deps", "--no-index", str(wheel)],
        check=True,
        capture_output=True,
        timeout=300,
    )
    env = {k: v for k, v in os.environ.items() if k not in ("FTSWEEP_CATALOGS", "PYTHONPATH")}
    work = tmp_path / "elsewhere"
    work.mkdir()

    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(list(args), capture_output=True, text=True, env=env, cwd=work, timeout=600)

    ok = run(str(py), "-c", "import ftsweep, ftsweep.stages, xarray; print(ftsweep.__file__)")
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout.strip().startswith(site)  # the wheel's copy, not the repository's
    # from the folder holding a clone named like the package (what `git clone …/ftsweep` makes):
    # the clone has no __init__.py, so Python would take it for a namespace package were the
    # installed package not a regular one on sys.path (the README's user install)
    clone = work / "ftsweep"
    for part in ("pipeline", "stages", "catalogs"):
        (clone / part).mkdir(parents=True)
    (clone / "pyproject.toml").write_text("[project]\nname = 'ftsweep'\n")
    here = run(
        str(py),
        "-c",
        # the wheel's xarray.backends entry point: xarray's engine list loads it, and with it the accessor
        "import ftsweep, xarray as xr; print(ftsweep.__file__);"
        " assert 'ftsweep' in xr.backends.list_engines(); print(type(xr.Dataset().ftsweep).__name__)",
    )
    assert here.returncode == 0, here.stderr
    found, accessor = here.stdout.split()
    assert found.startswith(site) and accessor != "", here.stdout
    for generic in ("pipeline", "stages"):
        refused = run(str(py), "-c", f"import {generic}")
        assert refused.returncode != 0 and "ModuleNotFoundError" in refused.stderr
    args = ["predict", "--surface", "sinewave2d", "--drho-um", "50", "--dtheta-deg", "10", "--json"]
    pred = run(str(venv / "bin" / "ftsweep"), *args)
    assert pred.returncode == 0, pred.stderr
    assert json.loads(pred.stdout)["n_points"] == 21 * 36  # catalogs shipped in the wheel


@pytest.mark.integration  # three installs into one fresh virtual environment
def test_installs_in_any_order_leave_every_command_working_and_nothing_in_the_package(tmp_path):
    """The README's sequence in one environment: the set-up's regular install and a first run
    (numba compiles), then the test block's editable install over it, then a regular install
    with an extra over that; every command works after each, and no run writes inside the
    installed package (numba's cache is the user cache directory, ftsweep.caches). The
    environment borrows this one's dependencies through a .pth line, so pip installs only
    ftsweep (--no-deps) and the test needs no index but for the build backend."""
    venv = tmp_path / "venv"
    py, site = _borrowing_venv(venv)
    cache = tmp_path / "user-cache"
    drop = ("FTSWEEP_CATALOGS", "PYTHONPATH", "NUMBA_CACHE_DIR")
    env = {**{k: v for k, v in os.environ.items() if k not in drop}, "XDG_CACHE_HOME": str(cache)}
    work = tmp_path / "elsewhere"
    work.mkdir()

    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(list(args), capture_output=True, text=True, env=env, cwd=work, timeout=600)

    def install(*args: str) -> None:
        done = run(str(py), "-m", "pip", "install", "-q", "--no-deps", *args)
        assert done.returncode == 0, done.stderr

    predict = [str(venv / "bin" / "ftsweep"), "predict", "--surface", "sinewave2d", "--drho-um", "50"]
    predict += ["--dtheta-deg", "10", "--json"]
    where = [str(py), "-c", "import ftsweep, ftsweep.stages.envelope.arcs as a; print(a.__file__)"]

    install(str(REPO))  # the set-up: a regular install, then its first run
    first = run(*predict)
    assert first.returncode == 0, first.stderr
    assert "compiling    numba's kernels" in first.stderr
    assert not list((Path(site) / "ftsweep").rglob("*.nb[ic]"))  # nothing inside the package
    assert list((cache / "ftsweep" / "numba").rglob("arcs.*.nbi"))  # ... but in the user's cache
    # bench --documented's figures come with any install: the README in the package metadata
    readme = "from ftsweep.tools.documented import documented_times as d, readme_text as r; t, w = r(); "
    readme += "print(w); print(sum(x.seconds is not None for x in d(t)))"
    shipped = run(str(py), "-c", readme)
    assert shipped.returncode == 0, shipped.stderr
    assert shipped.stdout.split("\n")[0] == "the installed package's metadata"
    assert int(shipped.stdout.split("\n")[1]) >= 6  # the quickstart's four and the compile pair
    # the revision a regular install records is its checkout's, its files being the checkout's
    revision = run(str(py), "-c", "from ftsweep.version import git_revision as g; print(g())")
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True).stdout
    assert revision.stdout.strip().split("+")[0] == head.strip(), revision.stderr

    install("-e", str(REPO))  # the test block's install, over it
    for command in (where, predict, [str(venv / "bin" / "ftsweep"), "--help"]):
        ok = run(*command)
        assert ok.returncode == 0, (command, ok.stderr)
        assert "Traceback" not in ok.stderr
    assert run(*where).stdout.strip().startswith(str(REPO / "stages"))  # the checkout's own
    assert json.loads(run(*predict).stdout)["n_points"] == json.loads(first.stdout)["n_points"]

    install(f"{REPO}[s3]")  # an extra the guide names, as a regular install over the editable one
    again = run(*predict)
    assert again.returncode == 0 and "Traceback" not in again.stderr, again.stderr
    assert run(*where).stdout.strip().startswith(site)
    assert not list((Path(site) / "ftsweep").rglob("*.nb[ic]"))
