"""`ftsweep status` on a cube, and what select, export, report and compare do with an
incomplete one: say how incomplete in one line, and refuse unless --allow-incomplete."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from ftsweep.cli.main import main
from ftsweep.store import cube
from ftsweep.sweeps.run import run_sweep

SPEC = "surface: small_sine\nlayout: ring\naxes: {points: [8000, 16000, 3000000], aspect: [1.0, 4.0]}\n"


@pytest.fixture(scope="module")
def finished(tmp_path_factory, module_catalog_dir):
    folder = tmp_path_factory.mktemp("status")
    spec = folder / "s.yaml"
    spec.write_text(SPEC)
    out = folder / "s.zarr"
    run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=module_catalog_dir)
    return out, module_catalog_dir


def _cli(args, folder):  # type: ignore[no-untyped-def]
    return CliRunner().invoke(main, args, env={"FTSWEEP_CATALOGS": str(folder)})


def test_status_of_a_finished_cube(finished):
    out, folder = finished
    res = _cli(["status", str(out), "--json"], folder)
    found = json.loads(res.stdout)
    assert res.exit_code == 0 and found["complete"]
    assert found["counts"] == {"pending": 0, "done": 4, "failed": 0, "refused": 2, "pruned": 0}
    assert (
        found["reasons"]["refused"][0]["count"] == 2
        and "capacity" in found["reasons"]["refused"][0]["example"]
    )
    assert found["axes"] == {"points": [8000, 16000, 3000000], "aspect": [1.0, 4.0]}
    assert found["writer"] is None and found["last_run"]["cases"]["done"] == 4
    text = _cli(["status", str(out)], folder)
    assert "4 done, 0 pending, 0 failed, 2 refused" in text.output and "writer       none" in text.output


def test_an_incomplete_cube_is_said_and_refused_unless_allowed(finished, tmp_path):
    import shutil

    out, folder = finished
    half = tmp_path / "half.zarr"
    shutil.copytree(out, half)
    cube.CubeWriter(half).write([(i, {"status": cube.PENDING}) for i in (2, 3)])  # as a killed run leaves it
    res = _cli(["status", str(half)], folder)
    assert res.exit_code == 1 and "2 done, 2 pending" in res.output and "incomplete" in res.output
    for args in (
        ["select", str(half), "--budget-points", "20000"],
        ["export", str(half), "--budget-points", "20000", "-o", str(tmp_path / "a.h")],
        ["report", str(half), "-o", str(tmp_path / "r")],
        ["compare", str(half)],
    ):
        refused = _cli(args, folder)
        assert refused.exit_code == 1, refused.output
        assert (
            "incomplete: 2 of 6 cases done, 2 pending" in refused.output
            and "--allow-incomplete" in refused.output
        )
    allowed = _cli(["select", str(half), "--budget-points", "20000", "--allow-incomplete"], folder)
    assert allowed.exit_code == 0 and "note: the cube is incomplete" in allowed.output
    # a case named by its index is the same case whatever else is computed
    named = _cli(["export", str(half), "--case", "0", "-o", str(tmp_path / "b.h")], folder)
    assert named.exit_code == 0, named.output
