"""Layered spirals ([3]) in controllers' G-code dialects (docs/controllers.md): one cut a
segment of the layered plan, Z the slide's offset in its layer and W the servo's stroke,
read back cut by cut, verified and re-simulated as the single pass the layers split."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from ftsweep.cli.main import main
from ftsweep.engine.case import Case, program_request
from ftsweep.engine.planning import layer_plan, resolve_specs
from ftsweep.exports import dialects, nc
from ftsweep.inputs import catalogs
from ftsweep.inputs.programs.moves import DialectError, Moves
from ftsweep.simulate import resolve_case

SWEEP = "surface: small_sine\nlayout: spiral\nmachine: short-fts\naxes: {points_per_rev: [60]}\n"


@pytest.fixture(scope="module")
def layered(tmp_path_factory, module_catalog_dir) -> tuple[Path, dict, Path]:
    tmp = tmp_path_factory.mktemp("layered")
    (tmp / "l.yaml").write_text(SWEEP)
    cube = tmp / "l.zarr"
    env = {"FTSWEEP_CATALOGS": str(module_catalog_dir)}
    r = CliRunner().invoke(
        main, ["sweep", str(tmp / "l.yaml"), "--out", str(cube), "--scheduler", "synchronous"], env=env
    )
    assert r.exit_code == 0, r.output
    out = tmp / "l.nc"
    r = CliRunner().invoke(
        main, ["export", str(cube), "--case", "0", "--dialect", "iso-sts", "-o", str(out)], env=env
    )
    assert r.exit_code == 0, r.output
    return cube, env, out


def _plan(folder: Path):  # type: ignore[no-untyped-def]
    case = Case(
        surface="small_sine", machine="short-fts", layout=program_request(kind="spiral", points_per_rev=60)
    )
    rcase = resolve_case(case, specs=resolve_specs(case, folder))
    return rcase, layer_plan(rcase, np.asarray(rcase.values))


def test_every_segment_of_the_plan_is_a_cut_at_its_layers_offset(layered, module_catalog_dir):
    """The file's cuts are the plan's segments in order: each at its layer's Z offset, from
    the segment's start to its end; W within the stroke; Z + W the single pass's command at
    every program point a cut passes with its servo inside the stroke."""
    _, _, out = layered
    rcase, plan = _plan(module_catalog_dir)
    moves = dialects.read(out.read_text().splitlines(), "iso-sts")
    cuts = moves.cuts()
    keep = plan.seg_end > plan.seg_start
    assert len(cuts) == int(keep.sum()) > 100
    assert moves.w_mm is not None
    w = moves.w_mm * 1e3
    assert w.min() >= 0.0 and w.max() <= plan.travel_um + 1e-9
    offsets = plan.offsets_um[plan.seg_layer[keep]]
    for (lo, hi), z in zip(cuts, offsets, strict=True):
        np.testing.assert_allclose(moves.z_mm[lo:hi] * 1e3, z, atol=5e-4)  # printed to 1 nm
    path, values = rcase.layout, np.asarray(rcase.values)
    c = moves.c_deg
    lo, hi = cuts[0]
    turns = np.round((np.degrees(plan.seg_start[keep][0]) - c[lo]) / 360.0)
    phi = np.radians(c[lo:hi] + 360.0 * turns)
    on_point = np.isin(np.round(phi, 9), np.round(path.phi, 9))
    inside = (w[lo:hi] > 0.0) & (w[lo:hi] < plan.travel_um)
    tool = moves.z_mm[lo:hi] * 1e3 + w[lo:hi]
    expected = np.interp(phi, path.phi, values)
    assert (on_point & inside).any()
    np.testing.assert_allclose(tool[on_point & inside], expected[on_point & inside], atol=1.1e-3)


def test_a_layered_program_verifies_and_leaves_the_cubes_part(layered):
    cube, env, out = layered
    import xarray as xr

    r = CliRunner().invoke(main, ["verify", str(out), "--json"], env=env)
    assert r.exit_code == 0, r.output
    record = json.loads(r.stdout)
    assert record["cuts"] > 100 and record["n_points"] > 18001
    assert record["pv_nm"] == pytest.approx(float(xr.open_zarr(cube)["pv_nm"].values.ravel()[0]), rel=0.01)


def test_one_changed_servo_digit_is_refused(layered, tmp_path):
    _, env, out = layered
    lines = out.read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.startswith("G01 C") and " W0.0002" in ln)
    lines[k] = lines[k].replace(" W0.0002", " W0.0003", 1)
    bad = tmp_path / "bad.nc"
    bad.write_text("\n".join(lines) + "\n")
    (tmp_path / "bad.json").write_text(out.with_name(out.name + ".json").read_text())
    r = CliRunner().invoke(main, ["verify", str(bad)], env=env)
    assert r.exit_code == 1 and "CRC" in r.output


def test_a_maintained_parser_reads_the_same_cuts(layered):
    """gcodeparser (PyPI) on the layered ISO program: the same C, X, W on every G93 block."""
    gcodeparser = pytest.importorskip("gcodeparser")
    _, _, out = layered
    text = out.read_text()
    moves = dialects.read(text.splitlines(), "iso-sts")
    blocks = [
        g.params
        for g in gcodeparser.parse_gcode_lines(text, include_comments=False)
        if g.command == ("G", 1) and "W" in g.params and "F" in g.params and g.params["F"] != 100.0
    ]
    firsts = {lo for lo, _ in moves.cuts()}
    rest = np.array([k for k in range(moves.n_points) if k not in firsts])
    assert len(blocks) == rest.size
    assert moves.w_mm is not None
    np.testing.assert_allclose([b["W"] for b in blocks], moves.w_mm[rest], atol=1e-12)
    np.testing.assert_allclose([b["X"] for b in blocks], moves.x_mm[rest], atol=1e-12)
    np.testing.assert_allclose([b["C"] for b in blocks], dialects.wrapped(moves.c_deg[rest], 6), atol=1e-9)


def test_predict_summarises_a_layered_program_and_predicts_its_cuts(layered):
    _, env, out = layered
    r = CliRunner().invoke(
        main, ["predict", "--program", str(out), "--machine", "short-fts", "--json"], env=env
    )
    assert r.exit_code == 0, r.output
    info = json.loads(r.stdout)
    assert info["cuts"] > 100 and "w_accel_m_s2" in info["axes"]
    # with its surface, the cuts' passes (the tool at Z + W) are simulated as the controller
    # runs them. The export's sidecar records the single pass the cuts merge into; where a cut
    # ends with its servo clipped at the bottom of its stroke, the tool over the cut's last
    # segment stands above that single pass and no other cut passes there, so the cuts leave
    # a little more material: 431 nm against 407 nm here (6 %), hence the one-sided band
    r = CliRunner().invoke(
        main,
        ["predict", "--program", str(out), "--machine", "short-fts", "--surface", "small_sine", "--json"],
        env=env,
    )
    assert r.exit_code == 0, r.output
    got = json.loads(r.stdout)
    side = json.loads(out.with_name(out.name + ".json").read_text())
    assert side["pv_nm_as_written"] * 0.99 <= got["pv_nm"] <= side["pv_nm_as_written"] * 1.10


def test_the_reader_takes_several_cuts_and_unwraps_each():
    lines = [
        "G52 G63 G71 G103 G40 G18 G90",
        "G94 G01 Z1.0 F100.0",
        "G01 X1.0 C350.0 W0.1 F100.0",
        "G01 Z0.0 F10.0",
        "G93",
        "G01 C10.0 X0.99 W0.2 F60.0",
        "G94",
        "G01 Z1.0 F100.0",
        "G01 X0.98 C20.0 W0.1 F100.0",
        "G01 Z0.5 F10.0",
        "G93",
        "G01 C30.0 X0.97 W0.3 F30.0",
        "G01 C40.0 X0.96 W0.2 F30.0",
        "G94",
        "M30",
    ]
    m = dialects.read(lines, "iso-sts")
    assert m.cuts() == [(0, 2), (2, 5)]
    np.testing.assert_allclose(m.c_deg, [350.0, 370.0, 20.0, 30.0, 40.0])
    np.testing.assert_allclose(m.z_mm, [0.0, 0.0, 0.5, 0.5, 0.5])
    assert m.w_mm is not None
    np.testing.assert_allclose(m.w_mm, [0.1, 0.2, 0.1, 0.3, 0.2])
    assert (
        np.isnan(m.seconds[1]) and m.seconds[0] == pytest.approx(1.0) and m.seconds[2] == pytest.approx(2.0)
    )
    s = dialects.summary(m)
    assert s["cuts"] == 2 and s["machining_s"] == pytest.approx(5.0)


def test_pmac_dialects_refuse_a_layered_program_by_name():
    m = Moves(
        np.array([0.0, 1.0, 2.0]),
        np.array([1.0, 1.0, 1.0]),
        np.zeros(3),
        np.array([0.1, np.nan]),
        w_mm=np.zeros(3),
        cut_starts=np.array([2]),
        velocity={a: np.zeros(3) for a in "CXZ"},
        interpolation="pvt",
    )
    ctrl = nc.controller_of(catalogs.entry("machines", "sts-pmac-pvt"), "pmac-pvt")
    with pytest.raises(DialectError, match="layered program"):
        dialects.render(m, "pmac-pvt", [], ctrl)
