"""Programs real controllers read (docs/controllers.md): the controller's interpolation in the
one simulator, the dialects written and read back, programs from elsewhere predicted, and
the compiled reference interpolator."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st
from support.places import REPO

from ftsweep.cli.main import main
from ftsweep.engine.case import Case, program_request
from ftsweep.exports import dialects, nc
from ftsweep.simulate import run_case
from ftsweep.stages.interpolation import segments


# ----------------------------------------------------------------------- closed forms
@given(st.floats(-5, 5), st.floats(-50, 50), st.floats(1e-4, 5), st.floats(0, 1))
def test_a_constant_velocity_pvt_segment_moves_p_equals_v_t(p0, v, t, u):
    """PVT with equal end velocities V and P1 = P0 + V·T is the line P = P0 + V·t."""
    d0, d1 = segments.pvt_tangents(np.array([v, v]), np.array([t]))
    got = segments.hermite(p0, p0 + v * t, float(d0[0]), float(d1[0]), u)
    assert got == pytest.approx(p0 + v * t * u, abs=1e-12 * (1 + abs(v * t)))


@given(st.lists(st.floats(-10, 10), min_size=4, max_size=40))
def test_a_spline1_way_point_lies_off_its_control_point_by_the_difference_of_differences(p):
    """Uniform cubic B-spline: y_n − P_n = (D_n+1 − D_n)/6 with D_n = P_n − P_n−1."""
    p = np.array(p)
    way, _, _ = segments.bspline_segments(p)
    d = np.diff(p)
    np.testing.assert_allclose(way[1:-1] - p[1:-1], (d[1:] - d[:-1]) / 6.0, atol=1e-12)


@settings(max_examples=50)
@given(st.lists(st.floats(-3, 3), min_size=4, max_size=4), st.integers(3, 40))
def test_hermite_segments_with_exact_tangents_reproduce_a_cubic(c, n):
    x = np.sort(np.random.default_rng(n).uniform(0, 10, n))
    x = x[np.concatenate([[True], np.diff(x) > 1e-3])]
    f = np.polynomial.Polynomial(c)
    d0, d1 = f.deriv()(x[:-1]) * np.diff(x), f.deriv()(x[1:]) * np.diff(x)
    q = np.linspace(x[0], x[-1], 97)
    np.testing.assert_allclose(segments.evaluate(x, f(x), d0, d1, q), f(q), atol=1e-9)


def test_the_natural_spline_is_the_b_spline_of_its_control_points():
    """The control points export writes put the B-spline through the planned way-points."""
    y = np.sin(np.linspace(0, 7, 200)) + 0.1 * np.linspace(0, 7, 200) ** 2
    way, d0, d1 = segments.bspline_segments(segments.control_points(y))
    n0, n1 = segments.natural_spline(np.arange(y.size, dtype=float), y)
    np.testing.assert_allclose(way, y, atol=1e-12)
    np.testing.assert_allclose(d0, n0, atol=1e-12)
    np.testing.assert_allclose(d1, n1, atol=1e-12)


# ----------------------------------------------------------------------- the one simulator
def _seed003(machine: str) -> dict:
    case = Case(
        surface="sinusoidal_mesh",
        machine=machine,
        cutting="seed003",
        layout=program_request(kind="spiral", chord_um=0.5, residual_um=0.5),
    )
    return run_case(case)


def test_a_pvt_controller_needs_fewer_points_for_seed_003s_budget():
    """Seed 003 (Δcho = Δres = 0.5 µm): cubic segments meet the chord budget with fewer
    points than linear ones (measured 9,747 against 18,380), the P-V within eq. 7's 2 µm."""
    linear, pvt = _seed003("sts-nanoform"), _seed003("sts-pmac-pvt")
    assert pvt["n_points"] < 0.7 * linear["n_points"]
    assert pvt["chord_error_nm"] <= 500.0 * (1 + 1e-9)
    assert pvt["pv_nm"] <= 2000.0 and linear["pv_nm"] <= 2000.0


def test_spline1_refuses_a_segment_time_that_is_not_whole_time_steps():
    """720 points a revolution at 6 rpm: 13.888… ms a segment, not whole 1/4 µs steps."""
    from ftsweep.engine.case import CaseError

    case = Case(
        surface="sinusoidal_mesh",
        machine="sts-pmac-spline",
        cutting="seed003-6rpm",
        layout=program_request(kind="spiral", points_per_rev=720),
    )
    with pytest.raises(CaseError, match=r"0.25 µs steps: these take 13.8889 ms \(use the points_per_rev"):
        run_case(case)


# ----------------------------------------------------------------------- export, read, verify
def _sweep(tmp: Path, name: str, text: str) -> Path:
    (tmp / f"{name}.yaml").write_text(text)
    cube = tmp / f"{name}.zarr"
    r = CliRunner().invoke(
        main, ["sweep", str(tmp / f"{name}.yaml"), "--out", str(cube), "--scheduler", "synchronous"]
    )
    assert r.exit_code == 0, r.output
    return cube


SPIRAL = "surface: sinusoidal_mesh\nlayout: spiral\nmachine: {m}\ncutting: {c}\naxes:\n  {axis}\n"


@pytest.fixture(scope="module")
def moore(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    tmp = tmp_path_factory.mktemp("moore")
    cube = _sweep(tmp, "m", SPIRAL.format(m="sts-moore", c="seed003", axis="chord_um: [0.5]"))
    out = tmp / "p.nc"
    r = CliRunner().invoke(main, ["export", str(cube), "--case", "0", "--dialect", "iso-sts", "-o", str(out)])
    assert r.exit_code == 0, r.output
    return cube, out


def test_an_iso_sts_export_predicts_the_cubes_pv_and_verifies(moore):
    import xarray as xr

    cube, out = moore
    r = CliRunner().invoke(
        main,
        ["predict", "--program", str(out), "--surface", "sinusoidal_mesh", "--cutting", "seed003", "--json"],
    )
    assert r.exit_code == 0, r.output
    got = json.loads(r.output)
    cube_pv = float(xr.open_zarr(cube)["pv_nm"].values.ravel()[0])
    assert got["pv_nm"] == pytest.approx(cube_pv, rel=0.01)
    assert got["dialect"] == "iso-sts" and got["interpolation"] == "linear"
    v = CliRunner().invoke(main, ["verify", str(out)])
    assert v.exit_code == 0, v.output


def _predicted(tmp_path: Path, name: str, machine: str, cutting: str, axis: str) -> tuple[Path, dict]:
    """A spiral case's cube, and predict --program's reading of its export."""
    cube = _sweep(tmp_path, name, SPIRAL.format(m=machine, c=cutting, axis=axis))
    out = tmp_path / f"{name}.pmc"
    r = CliRunner().invoke(main, ["export", str(cube), "--case", "0", "-o", str(out)])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(
        main,
        ["predict", "--program", str(out), "--surface", "sinusoidal_mesh", "--cutting", cutting, "--json"],
    )
    assert r.exit_code == 0, r.output
    return cube, json.loads(r.output)


def test_a_pvt_program_read_back_predicts_the_cubes_part(tmp_path):
    """Two samplings of one program agree: the cube's (the planned spiral through the line
    engine) and predict --program's (the file's PVT segments as the passes they make over
    rays, no spiral assumed). 2 %: the file's part is judged only on the ring its passes
    fully machine, the cube's to the aperture's edge (its spiral continued beyond its start)."""
    import xarray as xr

    cube, got = _predicted(tmp_path, "pvt", "sts-pmac-pvt", "seed003", "chord_um: [1.0]")
    assert got["interpolation"] == "pvt"
    assert got["pv_nm"] == pytest.approx(float(xr.open_zarr(cube)["pv_nm"].values.ravel()[0]), rel=0.02)


def test_spline1_and_pvt_files_of_the_same_points_predict_the_same_part(tmp_path):
    """On evenly spaced points the natural spline a PVT file's velocities come from and the
    B-spline of a SPLINE1 file's control points are one cubic (docs/controllers.md): read
    back through their own segment forms (Hermite velocities; B-spline way-points), the two
    files predict one part, to the files' rounding (positions and velocities printed at
    6 decimals, 1 nm: 0.03 % of the P-V here, hence 1e-3)."""
    _, pvt = _predicted(tmp_path, "p", "sts-pmac-pvt", "seed003-6rpm", "points_per_rev: [500]")
    _, spline = _predicted(tmp_path, "s", "sts-pmac-spline", "seed003-6rpm", "points_per_rev: [500]")
    assert (pvt["interpolation"], spline["interpolation"]) == ("pvt", "spline1")
    assert spline["pv_nm"] == pytest.approx(pvt["pv_nm"], rel=1e-3)
    assert spline["rms_nm"] == pytest.approx(pvt["rms_nm"], rel=1e-3)


@pytest.mark.skipif(not shutil.which("cc"), reason="no C compiler on this machine")
def test_verify_compiled_reads_g_code_on_every_axis(moore):
    """The C reference reads ISO STS G93 blocks (F the block's seconds on sts-moore, C modulo
    360 the shorter way) as linear in time on every axis, as the simulator forms them."""
    _, out = moore
    r = CliRunner().invoke(main, ["verify", str(out), "--compiled", "--json"])
    assert r.exit_code == 0, r.output
    axes = json.loads(r.output)["compiled_axes"]
    assert set(axes) == {"C", "X", "Z", "Z_simulated"} and all(d <= b for d, b in axes.values())


def test_predict_program_draws_its_error_map(moore, tmp_path):
    _, out = moore
    png = tmp_path / "map.png"
    args = ["predict", "--program", str(out), "--surface", "sinusoidal_mesh", "--cutting", "seed003"]
    r = CliRunner().invoke(main, [*args, "--map", str(png), "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["map"] == str(png) and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    r = CliRunner().invoke(main, ["predict", "--program", str(out), "--map", str(png)])
    assert r.exit_code != 0 and "--map needs --surface" in r.output


def test_one_changed_digit_is_refused(moore, tmp_path):
    _, out = moore
    lines = out.read_text().split("\n")
    k = next(i for i, line in enumerate(lines) if line.startswith("G01 C") and i > 30)
    for name, fix_crc in (("edited", False), ("recrc", True)):
        bad = tmp_path / f"{name}.nc"
        shutil.copy(out.with_name(out.name + ".json"), bad.with_name(bad.name + ".json"))
        changed = list(lines)
        changed[k] = (
            changed[k].replace("Z-0.", "Z-1.", 1)
            if "Z-0." in changed[k]
            else changed[k].replace("Z0.", "Z1.", 1)
        )
        if fix_crc:  # an editor who also recomputes the CRC and the hashes: the line check names it
            text, _ = nc._with_crc(changed[:-1], "iso-sts")
            changed = [*text, ""]
        bad.write_text("\n".join(changed))
        r = CliRunner().invoke(main, ["verify", str(bad)])
        assert r.exit_code == 1
        assert (
            ("CRC32 mismatch" in r.output) or ("does not belong" in r.output) or (f"line {k + 1}" in r.output)
        )


def test_an_independent_gcode_parser_reads_the_same_moves(moore):
    gcodeparser = pytest.importorskip("gcodeparser")
    _, out = moore
    text = out.read_text()
    moves = dialects.read(text.split("\n")[:-1], "iso-sts", _machine("sts-moore").controller)
    parsed = [
        g.params
        for g in gcodeparser.parse_gcode_lines(text, include_comments=False)
        if g.command == ("G", 1) and "C" in g.params and "F" in g.params and g.params["F"] != 100.0
    ]
    assert len(parsed) == moves.n_points - 1
    c = np.array([p["C"] for p in parsed])
    np.testing.assert_allclose(dialects.wrapped(moves.c_deg[1:], 6), c, atol=1e-9)
    np.testing.assert_allclose(moves.x_mm[1:], [p["X"] for p in parsed], atol=1e-12)
    np.testing.assert_allclose(moves.z_mm[1:], [p["Z"] for p in parsed], atol=1e-12)
    # sts-moore's F under G93 is the block's time in seconds
    np.testing.assert_allclose(moves.seconds, [p["F"] for p in parsed], rtol=1e-6)


def test_linuxcnc_rs274_interprets_the_linuxcnc_dialect(tmp_path):
    """LinuxCNC's own interpreter (rs274, canonical output at 4 decimals) runs the linuxcnc
    dialect: the same X, Z, C on every inverse-time block as the strict reader, and its feed
    rate the block's F times its XZ length."""
    import re
    import subprocess

    rs274 = shutil.which("rs274")
    if rs274 is None:
        pytest.skip(
            "LinuxCNC's standalone rs274 is not installed (.ci/run installs linuxcnc-uspace where apt is)"
        )
    cube = _sweep(tmp_path, "l", SPIRAL.format(m="sts-linuxcnc", c="seed003", axis="chord_um: [0.5]"))
    out = tmp_path / "p.ngc"
    r = CliRunner().invoke(main, ["export", str(cube), "--case", "0", "-o", str(out)])
    assert r.exit_code == 0, r.output
    done = subprocess.run(
        [rs274, "-g", str(out)], capture_output=True, text=True, timeout=600, stdin=subprocess.DEVNULL
    )
    assert done.returncode == 0, done.stdout[-500:] + done.stderr[-500:]
    text = done.stdout
    start = text.index("feed mode set to inverse time")
    body = text[start : text.index("feed mode set to units per minute", start)]
    feeds = [[float(v) for v in m.split(",")] for m in re.findall(r"STRAIGHT_FEED\(([^)]*)\)", body)]
    rates = [float(v) for v in re.findall(r"SET_FEED_RATE\(([^)]*)\)", body)]
    moves = dialects.read(out.read_text().split("\n")[:-1], "linuxcnc")
    assert len(feeds) == moves.n_points - 1 == len(rates)
    got = np.array(feeds)
    np.testing.assert_allclose(got[:, 0], moves.x_mm[1:], atol=5.1e-5)
    np.testing.assert_allclose(got[:, 2], moves.z_mm[1:], atol=5.1e-5)
    np.testing.assert_allclose(got[:, 5], moves.c_deg[1:], atol=5.1e-5)
    length = np.hypot(np.diff(moves.x_mm), np.diff(moves.z_mm))
    np.testing.assert_allclose(rates, 60.0 / moves.seconds * length, atol=5.1e-5, rtol=1e-6)


MOORE_STYLE = """%
O1000
(hand-written Moore-style spiral: 720 points per revolution, 10 revolutions, 10 um/rev)
G52 G63 G71 G103 G40 G18 G90
G54
T0101
M78
M26.1
#100=720.
#101=[360./#100]
#102=0
G94 G01 Z1.0 F100.
G01 X2.000000 C0.000 F100.
G01 Z0.0 F10.
G93 F0.0416667
WHILE [#102 LT [10*#100]] DO1
#102=#102+1
C[#102*#101] X[2.0-#102*0.01/#100] Z0.0
END1
G94
G01 Z1.0 F100.
M29
M30
%
"""


def test_a_hand_written_moore_program_is_read(tmp_path):
    path = tmp_path / "moore.nc"
    path.write_text(MOORE_STYLE)
    r = CliRunner().invoke(main, ["predict", "--program", str(path), "--json"])
    assert r.exit_code == 0, r.output
    got = json.loads(r.output)
    assert got["n_points"] == 7201
    assert got["revolutions"] == pytest.approx(10.0, abs=1e-9)
    assert got["points_per_rev"] == pytest.approx(720.0)
    for stat in ("min", "median", "max"):
        assert got["feed_um_per_rev"][stat] == pytest.approx(10.0, rel=1e-6)
    # sts-moore's F under G93 is seconds per block: 0.5° in 1/24 s, 12°/s, 2 rpm
    assert got["machine"] == "sts-moore" and "default for iso-sts" in got["machine_from"]
    assert got["spindle_rpm"] == pytest.approx(2.0, rel=1e-5)


@pytest.mark.parametrize(
    ("line", "named"),
    [
        ("IF [1.0 GT 0.5] GOTO 10", "no block N10"),
        ("C[#999*2.] X1.0 Z0.0", "#999 is used before"),
        ("G02 X1.0 Z0.0", "circular"),
        ("C1.0 X1 Z0.0", "no decimal point"),
        ("M98 P100", "subprogram"),
        ("/C1.0 X1.0 Z0.0", "block-delete"),
    ],
)
def test_what_the_reader_cannot_evaluate_is_refused_by_line(line, named):
    lines = ["G90 G18", "G01 X2.0 C0.0 Z0.0 F100.", "G93 F100.", line, "M30"]
    with pytest.raises(dialects.DialectError, match=named) as err:
        dialects.read(lines, "iso-sts")
    assert "line 4" in str(err.value)


def test_a_dialect_the_machines_controller_does_not_read_is_refused(tmp_path):
    """A PVT machine's cube as G-code or as ftsweep's linear text would cut another part; the
    refusal names the machines whose controllers read the dialect asked for."""
    cube = _sweep(tmp_path, "p", SPIRAL.format(m="sts-pmac-pvt", c="seed003", axis="chord_um: [1.0]"))
    out = str(tmp_path / "x.nc")
    r = CliRunner().invoke(main, ["export", str(cube), "--case", "0", "--dialect", "iso-sts", "-o", out])
    assert r.exit_code == 1 and "has a pmac-pvt controller, which does not read iso-sts" in r.output
    assert "export --dialect pmac-pvt" in r.output and "reads iso-sts (--machine sts-moore)" in r.output
    r = CliRunner().invoke(main, ["export", str(cube), "--case", "0", "--dialect", "text", "-o", out])
    assert r.exit_code == 1 and "interpolates pvt" in r.output


def test_export_for_another_machine_plans_and_predicts_the_case_there(moore, tmp_path):
    """The Moore cube's spiral as a PVT program for a PMAC lathe: planned for that controller,
    predicted there, its P-V stated, and the file verifies as the cube's case for that machine;
    a machine that cannot take it is refused naming why."""
    cube, _ = moore
    out = tmp_path / "pvt.pmc"
    r = CliRunner().invoke(
        main, ["export", str(cube), "--case", "0", "--machine", "sts-pmac-pvt", "-o", str(out)]
    )
    assert r.exit_code == 0, r.output
    assert (
        "machine      sts-pmac-pvt: planned and predicted there (the cube's case, for sts-moore:" in r.output
    )
    meta = json.loads(out.with_name(out.name + ".json").read_text())
    assert meta["dialect"] == "pmac-pvt" and meta["case"]["machine"] == "sts-pmac-pvt"
    assert meta["planned_for"]["cube"]["machine"] == "sts-moore"
    # the P-V stated is the prediction on the PMAC machine, which predict --program confirms
    p = CliRunner().invoke(
        main,
        ["predict", "--program", str(out), "--surface", "sinusoidal_mesh", "--cutting", "seed003", "--json"],
    )
    assert p.exit_code == 0, p.output
    assert json.loads(p.output)["pv_nm"] == pytest.approx(meta["pv_nm_as_written"], rel=0.01)
    v = CliRunner().invoke(main, ["verify", str(out)])
    assert v.exit_code == 0, v.output
    assert "machine sts-pmac-pvt" in v.output and "(number 0) is the file's case" in v.output
    # a dialect the new machine does not read, an unknown machine, a table for a program controller
    r = CliRunner().invoke(
        main,
        [
            "export",
            str(cube),
            "--case",
            "0",
            "--machine",
            "sts-pmac-pvt",
            "--dialect",
            "iso-sts",
            "-o",
            str(out),
            "--force",
        ],
    )
    assert r.exit_code == 1 and "does not read iso-sts" in r.output and "--machine sts-moore" in r.output
    r = CliRunner().invoke(
        main, ["export", str(cube), "--case", "0", "--machine", "sts-pmac", "-o", str(out), "--force"]
    )
    assert r.exit_code == 1 and "unknown machine 'sts-pmac'" in r.output and "did you mean" in r.output
    ring = _sweep(
        tmp_path, "ring", "surface: sinewave2d\nlayout: ring\naxes:\n  points: [20000]\n  aspect: [8]\n"
    )
    r = CliRunner().invoke(
        main, ["export", str(ring), "--case", "0", "--machine", "sts-moore", "-o", str(tmp_path / "r.h")]
    )
    assert r.exit_code == 1 and "reads iso-sts programs, not a ring table" in r.output
    assert "sweep the part as a path program (layout: spiral)" in r.output and "fts-1m" in r.output
    # a table asked for as a PVT program: why not, and what gives one
    r = CliRunner().invoke(
        main, ["export", str(ring), "--case", "0", "--dialect", "pmac-pvt", "-o", str(tmp_path / "r.pmc")]
    )
    assert r.exit_code == 1 and "own format only" in r.output and "layout: spiral" in r.output


# ----------------------------------------------------------------------- the compiled reference
needs_cc = pytest.mark.skipif(
    not any(shutil.which(c) for c in ("cc", "gcc", "clang")), reason="no C compiler on this machine"
)


@needs_cc
@pytest.mark.parametrize(
    ("name", "text", "suffix"),
    [
        ("ring", "surface: sinewave2d\nlayout: ring\naxes:\n  points: [20000]\n  aspect: [8]\n", ".h"),
        ("mesh", "surface: lens_array\nlayout: mesh\naxes:\n  points: [20000]\n  aspect: [1]\n", ".h"),
        ("pvt", SPIRAL.format(m="sts-pmac-pvt", c="seed003", axis="chord_um: [1.0]"), ".pmc"),
        (
            "spline1",
            SPIRAL.format(m="sts-pmac-spline", c="seed003-6rpm", axis="points_per_rev: [500]"),
            ".pmc",
        ),
    ],
)
def test_verify_compiled_agrees_with_the_simulator(tmp_path, name, text, suffix):
    cube = _sweep(tmp_path, name, text)
    out = tmp_path / f"{name}{suffix}"
    r = CliRunner().invoke(main, ["export", str(cube), "--case", "0", "-o", str(out)])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["verify", str(out), "--compiled", "--json"])
    assert r.exit_code == 0, r.output
    record = json.loads(r.output)
    assert record["compiled_points"] >= 100_000
    # every axis the file moves, each within its rounding bound: lengths 1e-9 µm (plus
    # 1e-14 of their size), C the same in thousandths of a degree
    if suffix == ".h":  # a table header: its lookups
        assert record["compiled_max_diff_um"] <= 1e-9
        return
    axes = record["compiled_axes"]
    assert {"C", "X", "Z", "Z_simulated"} <= set(axes) and all(d <= b for d, b in axes.values())
    assert all(axes[a][0] <= 1e-9 for a in ("X", "Z", "Z_simulated"))


@needs_cc
def test_the_compiled_reference_sees_a_swapped_tangent(tmp_path):
    """The comparison can fail: a program whose velocities the simulator reads otherwise."""
    from ftsweep.exports import compiled

    m = dialects.Moves(
        np.radians(np.arange(4000) * 0.5) * 0 + np.arange(4000) * 0.5,
        8.0 - np.arange(4000) * 0.5 / 360 * 0.01,
        np.sin(np.arange(4000) * 0.01) * 0.1,
        np.full(3999, 0.01),
        velocity={"C": np.full(4000, 50.0), "X": np.zeros(4000), "Z": np.cos(np.arange(4000) * 0.01)},
        interpolation="pvt",
    )
    lines = dialects.render(m, "pmac-pvt", ["x"], nc.controller_of(_machine("sts-pmac-pvt"), "pmac-pvt"))
    path = tmp_path / "p.pmc"
    path.write_text("\n".join(lines) + "\n")
    ctrl = nc.controller_of(_machine("sts-pmac-pvt"), "pmac-pvt")
    read = dialects.read(lines, "pmac-pvt", ctrl)
    from ftsweep.kinds.spiral.dialect import ADAPTER

    axes = compiled.check_program(path, read, ADAPTER, ctrl)["compiled_axes"]
    assert set(axes) == {"C", "X", "Z", "Z_simulated"} and all(d <= b for d, b in axes.values())
    read.velocity["Z"] = read.velocity["Z"][::-1].copy()
    with pytest.raises(Exception, match="Z at points along the path"):
        compiled.check_program(path, read, ADAPTER, ctrl)
    # an axis the simulator alone never evaluates is compared too
    read = dialects.read(lines, "pmac-pvt", ctrl)
    read.velocity["X"] = read.velocity["X"] + 1e-3
    with pytest.raises(Exception, match="X at points along the path"):
        compiled.check_program(path, read, ADAPTER, ctrl)


def _machine(name: str):
    from ftsweep.inputs import catalogs

    return catalogs.entry("machines", name)


def test_dialect_programs_state_their_limits():
    m = _machine("sts-moore")
    assert m.controller.max_blocks == 10_000_000 and m.interpolation == "linear"
    with pytest.raises(ValueError, match="commands pvt"):
        from ftsweep.inputs.catalogs import Controller

        Controller(dialect="pmac-pvt", interpolation="linear")
    moves = dialects.Moves(np.arange(5.0), np.ones(5), np.zeros(5), np.full(4, 10.0))
    ctrl = m.controller.model_copy(update={"max_segment_s": 1.0})
    with pytest.raises(Exception, match="longer than the controller"):
        dialects.check_limits(moves, ctrl)
    assert math.isfinite(dialects.summary(moves)["revolutions"])


def test_a_program_over_the_controllers_limits_is_refused_by_name():
    ctrl = _machine("sts-pmac-spline").controller
    # the I42 entry: TM (or TA) in ms at 1/4 µs, so 10.5 ms is a time SPLINE1 runs; 10.0001 ms is not
    dialects.check_limits(dialects.Moves(np.arange(5.0), np.ones(5), np.zeros(5), np.full(4, 0.0105)), ctrl)
    moves = dialects.Moves(np.arange(5.0), np.ones(5), np.zeros(5), np.full(4, 0.0100001))
    with pytest.raises(Exception, match=r"one time \(TM\) of whole 0.25 µs steps: these take 10.0001 ms"):
        dialects.check_limits(moves, ctrl)
    uneven = dialects.Moves(np.arange(5.0), np.ones(5), np.zeros(5), np.array([0.01, 0.01, 0.02, 0.01]))
    with pytest.raises(Exception, match=r"these take 10 to 20 ms"):
        dialects.check_limits(uneven, ctrl)
    with pytest.raises(Exception, match="more than the controller's 3"):
        dialects.check_limits(moves, ctrl.model_copy(update={"max_blocks": 3}))


def test_verify_compiled_says_when_there_is_no_compiler(monkeypatch):
    from ftsweep.errors import ExportError
    from ftsweep.exports import compiled

    monkeypatch.setenv("CC", "")
    monkeypatch.setattr(shutil, "which", lambda name: None)
    with pytest.raises(ExportError, match="needs a C compiler"):
        compiled.compiler()


@pytest.mark.integration
def test_a_loop_that_does_not_end_is_refused(monkeypatch):
    from ftsweep.inputs.programs import gcode

    monkeypatch.setattr(gcode, "WORK_FLOOR", 10_000)
    lines = ["G90 G18", "#1=0", "WHILE [#1 LT 1] DO1", "#2=1", "END1", "M30"]
    with pytest.raises(dialects.DialectError, match="a loop that does not end"):
        dialects.read(lines, "iso-sts")


def test_a_billion_pass_loop_is_refused_within_the_work_budget():
    # counted work, not time: the reader stops once its lines and expression nodes pass the budget
    from ftsweep.inputs.programs import gcode

    lines = [
        "G90 G21 G18 G94",
        "#1 = 0",
        "G93",
        "WHILE [#1 LT 1000000000] DO1",
        "G01 C[#1*0.1] X[10.0-#1*0.00001] Z0.0 F0.001",
        "#1 = #1 + 1",
        "END1",
        "M30",
    ]
    from ftsweep.inputs.controllers import Controller

    ctrl = Controller(dialect="iso-sts", interpolation="linear", g93_f="seconds")
    reader = gcode.IsoReader(lines, "iso-sts", ctrl)
    with pytest.raises(dialects.DialectError, match=r"^line \d+.*work passed 1,000,000 units"):
        reader.run()
    # over by at most the line it stopped on (its own nodes and one more line)
    assert gcode.WORK_FLOOR < reader.work <= gcode.WORK_FLOOR + 20


@pytest.mark.parametrize(
    ("line", "words"),
    [("G01 C[#7] X1.0 Z0.0 F1.0", "#7 is used before it is set"), ("#2 = 1.0/[#1-#1]", "division by zero")],
)
def test_an_expression_names_its_unset_variable_or_zero_division(line, words):
    lines = ["G90 G18", "#1 = 2.0", "G93", line, "M30"]
    with pytest.raises(dialects.DialectError, match=f"line 4 .*{words}"):
        dialects.read(lines, "iso-sts")


def test_pvt_segment_times_are_whole_controller_steps(tmp_path):
    """A PVT program's points lie on whole 0.25 µs steps of the spindle's turn, so every
    segment time it prints is exact; its C velocity is the spindle's."""
    cube = _sweep(tmp_path, "p", SPIRAL.format(m="sts-pmac-pvt", c="seed003", axis="chord_um: [1.0]"))
    out = tmp_path / "p.pmc"
    assert CliRunner().invoke(main, ["export", str(cube), "--case", "0", "-o", str(out)]).exit_code == 0
    lines = out.read_text().split("\n")
    times = [float(line[3:]) for line in lines if line.startswith("PVT")]
    steps = np.array(times) / 0.00025
    assert len(times) > 10 and np.all(np.abs(steps - np.round(steps)) < 1e-6)
    moves = dialects.read(lines[:-1], "pmac-pvt")
    assert np.allclose(moves.velocity["C"][1:-1], 6.63 * 6.0)  # deg/s
    # the program stops after its last point: one more segment to rest, at a constant
    # deceleration (the cubic through v and 0 over a distance v·T/2), then leaves the part
    assert moves.stopped and all(v[-1] == 0.0 for v in moves.velocity.values())
    t_stop = moves.seconds[-1]
    assert t_stop >= moves.seconds[-2] - 1e-12
    assert moves.c_deg[-1] - moves.c_deg[-2] == pytest.approx(0.5 * 6.63 * 6.0 * t_stop, abs=2e-6)
    assert lines[-4:-1] == ["RAPID", lines[-3], "CLOSE"] and lines[-3].startswith("Z")


def test_predict_program_reads_against_the_machine_the_file_names(moore, tmp_path):
    """Without --machine, the machine an ftsweep file's header names (when the catalog has it);
    --machine overrides it; a name the catalog lacks falls back to the default, saying so."""
    _, out = moore
    text = out.read_text()
    assert "machine sts-moore" in text

    def machine_of(path: Path, *extra: str) -> dict:
        r = CliRunner().invoke(main, ["predict", "--program", str(path), *extra, "--json"])
        assert r.exit_code == 0, r.output
        got = json.loads(r.output)
        return {"machine": got["machine"], "from": got["machine_from"]}

    assert machine_of(out) == {"machine": "sts-moore", "from": "named by the file"}
    other = tmp_path / "nanoform.nc"
    other.write_text(text.replace("machine sts-moore", "machine sts-nanoform"))
    # sts-nanoform declares no controller: the ISO defaults read F as inverse minutes, which
    # makes this file's F (seconds per block) a spindle no lathe turns, refused by name
    r = CliRunner().invoke(main, ["predict", "--program", str(other), "--json"])
    assert r.exit_code == 1 and "see machine.controller.g93_f" in r.output
    assert machine_of(other, "--g93-f", "seconds") == {"machine": "sts-nanoform", "from": "named by the file"}
    assert machine_of(other, "--machine", "sts-moore") == {"machine": "sts-moore", "from": "--machine"}
    unknown = tmp_path / "unknown.nc"
    unknown.write_text(text.replace("machine sts-moore", "machine lathe-from-elsewhere"))
    got = machine_of(unknown)
    assert got["machine"] == "sts-moore" and "'lathe-from-elsewhere', which the catalog lacks" in got["from"]
    r = CliRunner().invoke(main, ["predict", "--program", str(other), "--g93-f", "seconds"])
    assert "machine      sts-nanoform (named by the file)" in r.output


def test_a_file_written_for_another_profile_is_refused_by_verify(moore, tmp_path):
    """The header states the conventions the file relies on; on a machine whose profile now
    reads F otherwise, verify refuses it, naming the convention."""
    _, out = moore
    text = out.read_text()
    assert "(conventions: G93 F = block time in s, power-on G01 G94 G90" in text
    folder = tmp_path / "catalogs"
    shutil.copytree(REPO / "catalogs", folder)
    machines = folder / "machines.yaml"
    entry = machines.read_text().split("sts-moore:", 1)
    machines.write_text(
        entry[0] + "sts-moore:" + entry[1].replace("g93_f: seconds", "g93_f: inverse_minutes", 1)
    )
    r = CliRunner().invoke(main, ["verify", str(out)], env={"FTSWEEP_CATALOGS": str(folder)})
    assert r.exit_code == 1 and "controller.g93_f" in r.output


def test_each_dialects_header_states_only_its_own_units(moore):
    _, out = moore
    units = next(line for line in out.read_text().splitlines() if "units:" in line)
    assert "G93 F inverse time" in units and "PVT" not in units and " W " not in units


def test_a_pvt_programs_header_counts_the_points_export_and_verify_count(tmp_path):
    """The stop a PVT program adds past the centre is one of its points: the header says so
    and its count is the sidecar's (what export and verify print)."""
    cube, _ = _predicted(tmp_path, "stop", "sts-pmac-pvt", "seed003", "chord_um: [1.0]")
    program = tmp_path / "stop.pmc"
    meta = json.loads(program.with_name(program.name + ".json").read_text())
    stop = [line for line in program.read_text().splitlines() if line.startswith("; stop:")]
    assert stop == [
        f"; stop: one point past the {meta['n_points'] - 1} planned brings every axis to rest, "
        f"{meta['n_points']} points in all"
    ]


def test_a_spiral_sweeps_summary_names_its_rule_axis_with_its_values(tmp_path):
    text = SPIRAL.format(m="sts-moore", c="seed003", axis="chord_um: [0.5, 1.0]")
    (tmp_path / "s.yaml").write_text(text)
    r = CliRunner().invoke(
        main,
        ["sweep", str(tmp_path / "s.yaml"), "--out", str(tmp_path / "s.zarr"), "--scheduler", "synchronous"],
    )
    assert r.exit_code == 0, r.output
    assert "best P-V per chord_um (among the cases select may choose):" in r.output
    rows = r.output.split("P-V nm\n", 1)[1].splitlines()[:2]
    assert [row.split()[0] for row in rows] == ["0.5", "1"]  # not 0 and 1
