"""The corrective loop from the command line: a part cut by a cube's case, measured (a point
cloud made of the case's prediction and a machine's error), explained (`ftsweep measure
--cube --case`, and `--program` for the program that cut it), corrected over two gains and
two low-passes into a cube of the trade (`ftsweep correct`), the best exported and signed;
verify names the measurement, the registered measurement and figures are written."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from click.testing import CliRunner
from support import measured as ms

from ftsweep.cli.main import main
from ftsweep.stages.measurement import zernike_basis

pytestmark = pytest.mark.integration  # local Dask clusters: sweeps of the cut and of its correction

CASE = "points=2000 aspect=4"


def _cli(args, **env):
    res = CliRunner().invoke(main, [str(a) for a in args], env=env or None)
    assert res.exit_code == 0, res.output
    return res


@pytest.fixture(scope="module")
def cut(tmp_path_factory):
    """(folder, cube, measured part): a small ring sweep of the Zernike freeform and a part its
    case CASE cut on a machine with 15 nm of astigmatism and a 40 nm thermal ramp."""
    folder = tmp_path_factory.mktemp("loop")
    spec = folder / "zr.yaml"
    spec.write_text(
        "description: Two ring layouts of the Zernike freeform.\nsurface: zernike_example\nlayout: ring\n"
        "axes:\n  points: [2000, 6000]\n  aspect: [4.0]\n"
    )
    cube = folder / "zr.zarr"
    _cli(["sweep", spec, "-o", cube, "--workers", 1])
    from ftsweep.tools.measure import prediction_of

    _, record = prediction_of(cube=cube, case=CASE)
    machine = ms.summed(lambda x, y: 0.015 * zernike_basis(x, y, 1000.0, 6)[:, 5], ms.thermal(0.040, 1000.0))
    points = ms.part(
        "zernike_example", 1000.0, (0.0, 0.0, 0.2), ms.summed(ms.predicted(record), machine), n=61
    )
    return folder, cube, ms.write_cloud(folder / "part.csv", points)


def test_measure_explains_a_part_by_its_cube_case_and_writes_what_it_found(cut):
    folder, cube, part = cut
    out = folder / "registered.nc"
    res = _cli(
        [
            "measure",
            part,
            "--cube",
            cube,
            "--case",
            CASE,
            "--no-decentre",
            "-o",
            out,
            "--plots",
            folder / "p",
            "--json",
        ]
    )
    found = json.loads(res.stdout)
    assert found["surface"] == "zernike_example" and 0.0 < found["explained"]["explained_share"] < 1.0
    import ftsweep.tools.accessor  # noqa: F401  (the accessor)
    from ftsweep.tools.measureviews import open_registered

    ds = open_registered(out)
    assert ds.ftsweep.measured()["sha256"] == found["sha256"]
    assert set(ds.ftsweep.terms().columns) == {"measured_nm", "explained_nm", "unexplained_nm"}
    assert (folder / "p" / "maps.png").stat().st_size > 10_000 and (folder / "p" / "terms.png").is_file()
    text = _cli(["measure", part, "--cube", cube, "--case", CASE, "--no-decentre"]).output
    assert "explained " in text and "the machine's share" in text


def test_measure_explains_a_part_by_the_program_that_cut_it(tmp_path, cut):
    folder, _, part = cut
    spec = tmp_path / "sp.yaml"
    spec.write_text(
        "description: One spiral of the Zernike freeform.\nsurface: zernike_example\nlayout: spiral\n"
        "axes:\n  points_per_rev: [90]\n"
    )
    _cli(["sweep", spec, "-o", tmp_path / "sp.zarr", "--workers", 1])
    program = tmp_path / "cut.nc"
    _cli(["export", tmp_path / "sp.zarr", "-o", program, "--case", "0", "--dialect", "iso-sts"])
    res = _cli(
        ["measure", part, "--program", program, "--surface", "zernike_example", "--no-decentre", "--json"]
    )
    assert "explained_share" in json.loads(res.stdout)["explained"]


def test_correct_sweeps_the_trade_exports_the_best_and_verify_names_the_measurement(tmp_path, cut):
    _, cube, part = cut
    keys = tmp_path / "shop"
    _cli(["keys", "new", "-o", keys])
    fix = tmp_path / "fix"
    header = fix / "corrected.h"
    args = ["correct", part, "--cube", cube, "--case", CASE, "--no-decentre", "--folder", fix]
    args += ["--gain", 0.5, "--gain", 1, "--terms", 6, "--terms", 15, "--workers", 1]
    res = _cli([*args, "-o", header, "--sign-key", f"{keys}.key", "--json"])
    found = json.loads(res.stdout)
    assert len(found["trade"]) == 4 and found["best"]["correction_gain"] == 1.0
    assert found["best"]["residual_rms_nm"] <= 0.1 * found["uncorrected_rms_nm"]
    half = [t for t in found["trade"] if t["correction_gain"] == 0.5 and t["correction_terms"] == 15][0]
    assert 0.35 < half["residual_rms_nm"] / found["uncorrected_rms_nm"] < 0.65  # half the correction
    for name in ("trade.nc", "trade.png", "registered.nc", "maps.png", "terms.png", "corrected.yaml"):
        assert (fix / name).is_file(), name
    env = {"FTSWEEP_CATALOGS": str(fix / "catalogs")}
    out = _cli(["verify", header, "--trusted-key", f"{keys}.pub"], **env).output
    sha = json.loads(_cli(["measure", part, "--surface", "zernike_example", "--json"]).stdout)["sha256"]
    assert f"corrected    by measurement {sha[:16]}" in out and "signed by key" in out
    sidecar = json.loads(Path(f"{header}.json").read_text())
    block = sidecar["catalog_entries"]["surface"]["correction"]
    assert block["measurement_sha256"] == sha and "piston_um" in block["fit"]
    assert os.access(header, os.R_OK)


def test_correct_refuses_a_folder_that_holds_a_correction_before_any_work(tmp_path, cut):
    _, cube, part = cut
    (tmp_path / "fix" / "catalogs").mkdir(parents=True)
    res = CliRunner().invoke(
        main, ["correct", str(part), "--cube", str(cube), "--case", CASE, "--folder", str(tmp_path / "fix")]
    )
    assert res.exit_code == 1 and "already holds a correction (catalogs)" in res.output
    assert sorted(p.name for p in (tmp_path / "fix").iterdir()) == ["catalogs"]
