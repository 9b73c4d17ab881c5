"""End-to-end behaviour of the case runner and the ``ftsweep predict`` command."""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner
from pydantic import ValidationError

from ftsweep.cli.main import main
from ftsweep.engine.case import Case, CaseError, Resolution, program_request
from ftsweep.inputs.catalogs import CatalogError
from ftsweep.simulate import run_case
from ftsweep.sweeps.spec import load_sweep

REQUIRED = {"surface", "layout", "n_points", "pv_nm", "rms_nm", "pv_interp_nm", "seconds"}


def test_flat_surface_machines_to_feed_cusps(catalog_dir):
    for feed, rc in ((1.0, 83.0), (2.0, 50.0)):
        case = Case(
            surface="flat",
            layout=program_request(kind="ring", pitch=(5.0, 2.0)),
            feed_um=feed,
            nose_radius_um=rc,
        )
        r = run_case(case, catalog_dir)
        cusp = feed**2 / (8 * rc) * 1e3
        assert r["cusp_nm"] == pytest.approx(cusp)
        # away from the axis every cusp is F²/8Rc (the error ranges from 0 to the cusp)
        assert r["pv_outer_nm"] == pytest.approx(cusp, rel=0.02)
        # across the axis the last passes of the two sides are F/2..3F/2 apart (§5)
        assert r["pv_nm"] <= (1.5 * feed) ** 2 / (8 * rc) * 1e3 * 1.02
        assert r["pv_interp_nm"] == pytest.approx(0.0, abs=1e-6)


def test_ring_and_mesh_on_small_parts(catalog_dir):
    ring = run_case(
        Case(surface="small_sine", layout=program_request(kind="ring", points=20000, aspect=4.0)), catalog_dir
    )
    assert ring["n_points"] == pytest.approx(20000, abs=ring["table_cols"])
    assert ring["aspect_actual"] == pytest.approx(4.0, rel=0.1)
    mesh = run_case(
        Case(surface="small_lens", layout=program_request(kind="mesh", pitch=(5.0, 5.0))), catalog_dir
    )
    assert [mesh["table_rows"], mesh["table_cols"]] == [91, 91]
    for r in (ring, mesh):
        assert math.isfinite(r["pv_nm"]) and r["pv_nm"] > r["cusp_nm"]
        assert r["pv_inner_nm"] <= r["pv_nm"] + 1e-9 and r["pv_outer_nm"] <= r["pv_nm"] + 1e-9
        assert r["rms_nm"] < r["pv_nm"]


def test_finer_layouts_are_more_accurate(catalog_dir):
    pvs = [
        run_case(
            Case(surface="small_sine", layout=program_request(kind="ring", pitch=(2.0, dth))), catalog_dir
        )["pv_nm"]
        for dth in (2.0, 1.0, 0.5)
    ]
    assert pvs[0] > pvs[1] > pvs[2]
    # bilinear error is quadratic in the pitch: halving Δθ cuts the angular error ~4×
    assert 2.5 < pvs[0] / pvs[1] < 5.0


def test_capacity_is_enforced(catalog_dir):
    case = Case(surface="sinewave2d", layout=program_request(kind="ring", pitch=(0.5, 0.1)))
    with pytest.raises(CaseError, match="over the capacity"):
        run_case(case, catalog_dir)


def test_odd_points_per_feed_is_refused(tmp_path, catalog_dir):
    with pytest.raises(ValidationError, match="even"):
        Resolution(points_per_feed=3)
    # a sweep spec with it is refused when it is loaded, naming the file and the key
    spec = tmp_path / "odd.yaml"
    spec.write_text(
        "surface: flat\naxes: {points: [8000], aspect: [1.0]}\nresolution: {points_per_feed: 3}\n"
    )
    with pytest.raises(CatalogError, match=r"(?s)odd\.yaml.*resolution\.points_per_feed.*even"):
        load_sweep(str(spec), catalog_dir)


def test_case_key_is_stable_and_sensitive():
    a = Case(surface="sinewave2d", layout=program_request(kind="ring", pitch=(2.0, 1.0)))
    b = Case(surface="sinewave2d", layout=program_request(kind="ring", pitch=(2.0, 1.0)))
    c = Case(surface="sinewave2d", layout=program_request(kind="ring", pitch=(2.0, 0.5)))
    assert a.key() == b.key() != c.key()
    assert len(a.key()) == 16


def invoke(*args):
    return CliRunner().invoke(main, list(args))


def test_json_output_is_one_object_with_the_documented_keys():
    r = invoke("predict", "--surface", "sinewave2d", "--drho-um", "4", "--dtheta-deg", "2", "--json")
    assert r.exit_code == 0, r.output
    data = json.loads(r.stdout)  # exactly one JSON document, nothing else on stdout
    assert REQUIRED | {"drho_um", "dtheta_deg"} <= set(data)
    assert data["drho_um"] == 4.0 and data["dtheta_deg"] == 2.0


def test_threads_option_gives_the_same_prediction():
    args = ("predict", "--surface", "sinewave2d", "--drho-um", "4", "--dtheta-deg", "2", "--json")
    one, two = invoke(*args, "--threads", "1"), invoke(*args, "--threads", "2")
    assert one.exit_code == 0 and two.exit_code == 0, one.output + two.output
    a, b = json.loads(one.stdout), json.loads(two.stdout)
    assert a["pv_nm"] == b["pv_nm"] and a["rms_nm"] == b["rms_nm"] and a["n_eval"] == b["n_eval"]


def test_readable_summary_names_units():
    r = invoke("predict", "--surface", "lens_array", "--dx-um", "16", "--dy-um", "16")
    assert r.exit_code == 0, r.output
    for text in ("P-V", "nm", "µm", "control points", "interp."):
        assert text in r.stdout


@pytest.mark.parametrize(
    "args, message",
    [
        (["--surface", "nope", "--drho-um", "2", "--dtheta-deg", "1"], "unknown surface 'nope'"),
        (
            ["--surface", "sinewave2d", "--drho-um", "-2", "--dtheta-deg", "1"],
            "--drho-um: Input should be greater than 0",
        ),
        (
            ["--surface", "sinewave2d", "--drho-um", "2", "--dtheta-deg", "0"],
            "--dtheta-deg: Input should be greater than 0",
        ),
        (
            ["--surface", "lens_array", "--dx-um", "2", "--dy-um", "nan"],
            "'--dy-um': nan is not a finite number",
        ),
        (
            ["--surface", "sinewave2d", "--points", "1e5", "--aspect", "-1"],
            "--aspect: Input should be greater than 0",
        ),
        (
            ["--surface", "sinewave2d", "--drho-um", "2", "--dtheta-deg", "1", "--feed-um", "inf"],
            "'--feed-um': inf is not a finite number",
        ),
        (
            ["--surface", "sinewave2d", "--drho-um", "2", "--dtheta-deg", "1", "--n-theta", "0"],
            "--n-theta: Input",
        ),
        (
            ["--surface", "sinewave2d", "--drho-um", "2", "--dtheta-deg", "1", "--max-nodes", "0"],
            "'--max-nodes'",
        ),
        (["--surface", "sinewave2d", "--drho-um", "0.5", "--dtheta-deg", "0.1"], "over the capacity"),
        (["--surface", "sinewave2d", "--drho-um", "2", "--dtheta-deg", "1", "--points", "1000"], "not both"),
        (["--surface", "sinewave2d", "--points", "1000"], "--aspect"),
        (
            ["--surface", "sinewave2d", "--dx-um", "2", "--dy-um", "1"],
            "belongs to mesh layouts (--layout mesh), not to a ring layout",
        ),
        (
            ["--surface", "sinewave2d", "--points", "1000", "--aspect", "1", "--chord-um", "0.5"],
            "--chord-um belongs to spiral programs (--layout spiral), not to a ring layout",
        ),
        (["--surface", "sinewave2d", "--drho-um", "2"], "--dtheta-deg is missing"),
        (["--strict", "--surface", "sinewave2d", "--drho-um", "2", "--dtheta-deg", "0.7"], "not divide 360"),
        (["--surface", "lens_array", "--points", "5000000", "--aspect", "1"], "over the capacity"),
        (
            ["--surface", "sinewave2d", "--drho-um", "2", "--dtheta-deg", "1", "--points-per-feed", "3"],
            "even",
        ),
        (
            ["--surface", "sinewave2d", "--drho-um", "2", "--dtheta-deg", "1", "--machine", "x"],
            "unknown machine",
        ),
    ],
)
def test_invalid_input_exits_nonzero_with_a_message(args, message):
    r = invoke("predict", *args)
    assert r.exit_code != 0
    assert message in r.output


def test_console_script_is_installed():
    beside = Path(sys.executable).with_name("ftsweep")  # the environment running the tests
    exe = str(beside) if beside.exists() else shutil.which("ftsweep")
    assert exe is not None, "the ftsweep console script is not on PATH; install the package"
    out = subprocess.run(
        [exe, "predict", "--surface", "sinewave2d", "--drho-um", "10", "--dtheta-deg", "5", "--json"],
        capture_output=True,
        text=True,
        check=True,
        env=os.environ.copy(),
    )
    assert json.loads(out.stdout)["n_points"] == 101 * 72


@pytest.mark.parametrize(
    "args, option",
    [
        (["sweep", "sinewave-ring", "--workers", "0"], "--workers"),
        (["predict", "--surface", "sinewave2d", "--threads", "0"], "--threads"),
        (["sweep", "sinewave-ring", "--max-cases", "-3"], "--max-cases"),
        (["sweep", "sinewave-ring", "--prune", "1"], "--prune"),
        (["select", "outputs/none.zarr", "--tolerance-nm", "nan"], "--tolerance-nm"),
        (["select", "outputs/none.zarr", "--budget-points", "0"], "--budget-points"),
        (["verify", "none.h", "--pv-tolerance-nm", "-1"], "--pv-tolerance-nm"),
        (["report", "outputs/none.zarr", "--map-bins", "4"], "--map-bins"),
    ],
)
def test_option_ranges_are_refused_before_anything_runs(args, option):
    # click's typed ranges check these options when they are parsed, naming the option
    r = invoke(*args)
    assert r.exit_code == 2, r.output
    assert f"Invalid value for '{option}'" in r.output
