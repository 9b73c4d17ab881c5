"""Programs written as shops' CAM and controllers' manuals write them, read as their
controller reads them (the machine's profile, docs/controllers.md) and predicted: each with
its expected summary, and where ftsweep can predict it an independent expected form error
(the cusp height f²/8r of a constant-feed turn on a flat part, model §5)."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given
from hypothesis import strategies as st

from ftsweep.cli.main import main
from ftsweep.exports import dialects, nc
from ftsweep.inputs.controllers import Controller

# the part: a 0.5 mm spiral at 10 µm/rev, 1° a block (360 points a revolution, 50
# revolutions), each block 1 ms (F0.001 read as seconds per block: 1000°/s, 166.7 rpm)
RADIUS_MM, FEED_UM, STEP_DEG, BLOCK_S = 0.5, 10.0, 1.0, 0.001
REVS = round(RADIUS_MM * 1e3 / FEED_UM)
N_BLOCKS = REVS * round(360 / STEP_DEG)
NOSE_UM = 500.0
CUSP_NM = FEED_UM**2 / (8.0 * NOSE_UM) * 1e3  # 25 nm


def points(reverse: bool = False, feed_um: float = FEED_UM, g: str = "") -> list[str]:
    """The point blocks a CAM writes: C modulo 360 at 6 decimals, X and Z in mm, no G word
    (G01 is modal), F once before them (``g``: a G word on every block, e.g. 'G01 ')."""
    out = []
    for k in range(1, N_BLOCKS + 1):
        c = (k * STEP_DEG) % 360.0
        c = (360.0 - c) % 360.0 if reverse else c
        x = RADIUS_MM - k * STEP_DEG / 360.0 * feed_um * 1e-3
        out.append(f"{g}C{c:.6f} X{x:.6f} Z0.000000")
    return out


def moore_650fg(body: list[str] | None = None, passes: int = 3) -> str:
    """A program as another tool writes it for a Moore Nanotech 650FG: a macro header, the
    passes in a WHILE loop each under its own G52 Z offset (the last at 0), whole-mm words,
    G93 point blocks without a G word, M26.1 … M29 M30."""
    blocks = points() if body is None else body
    head = f"""%
O0100
(STS PROGRAM FOR MOORE NANOTECH 650FG - FLAT, R0.5 TOOL)
#1={passes} (PASSES)
#2=0.002 (DEPTH OF CUT MM)
#3=1 (PASS)
G52 G63 G71 G103 G40 G18 G90
G54
T0101
M78
M26.1
WHILE [#3 LE #1] DO1
#8=[#1-#3]*#2
G52 Z[#8]
G94 Z20 F500
X{RADIUS_MM:.1f} C0.
Z0.1
Z0.
G93 F{BLOCK_S:g}"""
    tail = """G94 Z20 F500
#3=#3+1
END1
G52
M29
M30
%"""
    return "\n".join([head, *blocks, tail]) + "\n"


def predict(tmp_path: Path, text: str, *args: str) -> tuple[int, str]:
    path = tmp_path / "part.nc"
    path.write_text(text)
    r = CliRunner().invoke(main, ["predict", "--program", str(path), *args, "--json"])
    return r.exit_code, r.output


def _read(text: str, machine: str = "sts-moore") -> dialects.Moves:
    lines = text.rstrip("\n").split("\n")
    return dialects.read(lines, dialects.detect(lines), nc.profile_for(machine, dialects.detect(lines)))


@pytest.fixture(scope="module")
def flat_catalogs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from support.catalogs import make_catalog_dir

    return make_catalog_dir(tmp_path_factory.mktemp("shop") / "catalogs")


def test_a_moore_program_from_another_tool_is_read_as_published(tmp_path):
    code, out = predict(tmp_path, moore_650fg(), "--machine", "sts-moore")
    assert code == 0, out
    got = json.loads(out)
    # every pass is a cut of the file's points: its start and its N blocks
    assert got["cuts"] == 3 and got["n_points"] == 3 * (N_BLOCKS + 1)
    assert got["revolutions"] == pytest.approx(3 * REVS, rel=1e-9)
    assert got["points_per_rev"] == pytest.approx(360.0, rel=1e-9)
    assert got["points_per_rev_range"] == {"min": 360.0, "median": 360.0, "max": 360.0}
    assert got["feed_um_per_rev"]["median"] == pytest.approx(FEED_UM, rel=1e-4)
    # F0.001 as seconds per block: 1° a ms, a lathe's 166.7 rpm
    assert got["spindle_rpm"] == pytest.approx(STEP_DEG / 360.0 / BLOCK_S * 60.0, rel=1e-6)
    assert got["spindle_direction"] == "C increasing"
    assert "G93 F = block time in s" in got["conventions"][0]
    assert got["machining_s"] == pytest.approx(3 * N_BLOCKS * BLOCK_S, rel=1e-9)


def test_its_g52_offsets_set_each_pass_and_its_z20_is_whole_mm():
    moves = _read(moore_650fg())
    for k, (lo, hi) in enumerate(moves.cuts()):
        # each cut starts where the approach left the tool: Z0. at its pass's offset
        offset = (2 - k) * 0.002
        np.testing.assert_allclose(moves.z_mm[lo:hi], offset, atol=1e-12)
    assert any("G52" in n for n in moves.notes)


def test_its_form_error_is_the_feeds_cusp(tmp_path, flat_catalogs):
    """On a flat part the last pass leaves the cusps f²/8r between its turns (model §5)."""
    code, out = _with_catalogs(
        flat_catalogs, tmp_path, moore_650fg(), "--surface", "flat", "--nose-radius-um", str(NOSE_UM)
    )
    assert code == 0, out
    got = json.loads(out)
    # beyond the centre the peaks are the exact arcs' meeting points, the valleys within a node step
    assert got["pv_beyond_centre_nm"] == pytest.approx(CUSP_NM, rel=0.02)
    assert got["pv_nm"] >= got["pv_centre_nm"] > got["pv_beyond_centre_nm"]
    assert got["extremes"]["highest"]["error_nm"] > got["extremes"]["lowest"]["error_nm"]


def _with_catalogs(folder: Path, tmp_path: Path, text: str, *args: str) -> tuple[int, str]:
    path = tmp_path / "part.nc"
    path.write_text(text)
    r = CliRunner().invoke(
        main,
        ["predict", "--program", str(path), "--machine", "sts-moore", *args, "--json"],
        env={"FTSWEEP_CATALOGS": str(folder)},
    )
    return r.exit_code, r.output


# ------------------------------------------------------------- each misreading, modelled or refused
def test_f_read_as_inverse_minutes_is_refused_naming_the_convention(tmp_path):
    code, out = predict(tmp_path, moore_650fg(), "--machine", "sts-moore", "--g93-f", "inverse_minutes")
    assert code == 1
    # 1° in 1000 minutes: 2.8e-06 rpm
    assert "line 20: G93 F0.001 as inverse minutes gives a spindle of 2.78e-06 rpm" in out
    assert "see machine.controller.g93_f" in out


def test_a_dwell_is_time_not_a_move():
    text = moore_650fg(passes=1).replace("Z0.\nG93", "Z0.\nG04 X1.0\nG04 P500\nG93")
    moves = _read(text)
    assert moves.dwell_s == pytest.approx(1.5)  # X in s, P in ms on this profile
    assert moves.x_mm[0] == pytest.approx(RADIUS_MM)  # X1.0 of the dwell moved nothing
    linuxcnc = Controller(dialect="linuxcnc", interpolation="linear")
    assert linuxcnc.dwell_p == "s"  # LinuxCNC's P is seconds


def test_a_spindle_turning_the_other_way_is_read_and_predicted(tmp_path, flat_catalogs):
    text = moore_650fg(points(reverse=True), passes=1)
    code, out = _with_catalogs(
        flat_catalogs, tmp_path, text, "--surface", "flat", "--nose-radius-um", str(NOSE_UM)
    )
    assert code == 0, out
    got = json.loads(out)
    assert got["spindle_direction"] == "C decreasing"
    assert got["revolutions"] == pytest.approx(REVS, rel=1e-9)
    assert got["spindle_rpm"] == pytest.approx(STEP_DEG / 360.0 / BLOCK_S * 60.0, rel=1e-6)
    assert got["pv_beyond_centre_nm"] == pytest.approx(CUSP_NM, rel=0.02)


def test_c_turning_back_within_a_cut_is_refused_by_line():
    body = points()[:50] + ["C45.000000 X0.49 Z0.0"]
    with pytest.raises(dialects.DialectError, match=r"line 70 .*C turns back"):
        _read(moore_650fg(body, passes=1))


def test_linuxcnc_needs_f_on_every_inverse_time_block(tmp_path):
    text = LINUXCNC.format(f_rest="")
    with pytest.raises(dialects.DialectError, match=r"line 6 .*without its own F"):
        _read(text, "sts-linuxcnc")
    good = _read(LINUXCNC.format(f_rest=" F60000.0"), "sts-linuxcnc")
    assert good.n_points == 4 and np.allclose(good.seconds, 0.001)
    rs274 = shutil.which("rs274")
    if rs274 is not None:  # LinuxCNC's own interpreter refuses the same file
        path = tmp_path / "f.ngc"
        path.write_text(text)
        run = subprocess.run([rs274, "-g", str(path)], capture_output=True, text=True, timeout=60)
        assert run.returncode != 0 and "F word missing with inverse time" in run.stdout + run.stderr


LINUXCNC = """G21 G18 G90 G40 G49 G61
G0 X1.0 C0.0
G1 Z0.0 F10.0
G93
G1 C1.0 X0.99997 Z0.0 F60000.0
G1 C2.0 X0.99994 Z0.0{f_rest}
G1 C3.0 X0.99992 Z0.0{f_rest}
G94
M2
"""


def test_cutting_under_g94_is_refused_by_line():
    body = ["G94", *[f"G01 {b} F500." for b in points()[:5]]]
    text = moore_650fg(body, passes=1).replace("G93 F0.001\n", "")
    with pytest.raises(dialects.DialectError, match=r"line 22 .*turn C under G94"):
        _read(text)


def test_a_bare_program_is_read_from_the_profiles_power_on_state():
    bare = "\n".join(points()[:100]) + "\n"
    # the Moore's power-on feed mode is G94: point blocks alone are a cut it does not time
    with pytest.raises(dialects.DialectError, match=r"line 4 .*power-on feed mode is G94"):
        _read(bare)
    # under G93 the cut starts at the first block (no position is given before it)
    moves = _read("G93 F0.001\n" + bare)
    assert moves.n_points == 100 and moves.c_deg[0] == pytest.approx(1.0)


def test_whole_number_words_follow_the_profile():
    text = moore_650fg(passes=1)
    with pytest.raises(
        dialects.DialectError, match=r"line 15, column 5 .*Z20 has no decimal point.*whole_number_words"
    ):
        _read(text, "sts-nanoform")
    fanuc = Controller(
        dialect="iso-sts", whole_number_words="increments", input_increment_um=1.0, g93_f="seconds"
    )
    moves = dialects.read(
        ["G90 G18", "G01 X500 C0 Z100", "G93 F0.001", "C1. X0.49 Z0.", "M30"], "iso-sts", fanuc
    )
    assert moves.x_mm[0] == pytest.approx(0.5) and moves.z_mm[0] == pytest.approx(0.1)


def test_if_goto_loops_read_as_while_loops():
    text = moore_650fg(points()[:720], passes=2)
    jumped = text.replace("WHILE [#3 LE #1] DO1", "N10").replace("END1", "IF [#3 LE #1] GOTO 10")
    a, b = _read(text), _read(jumped)
    np.testing.assert_array_equal(a.c_deg, b.c_deg)
    np.testing.assert_array_equal(a.z_mm, b.z_mm)
    assert a.cuts() == b.cuts()


def test_incremental_blocks_and_macro_functions():
    lines = [
        "G90 G18",
        "#100 = 1",
        "#101 = SQRT[4.0] * #100",
        "G01 X[#101] C0. Z0.",
        "G93 F0.001",
        "G91",
        "C1. X-0.0001 Z0.",
        "C1. X-0.0001 Z0.",
        "G90",
        "M30",
    ]
    moves = dialects.read(lines, "iso-sts", nc.profile_for("sts-moore", "iso-sts"))
    np.testing.assert_allclose(moves.x_mm, [2.0, 1.9999, 1.9998])
    np.testing.assert_allclose(moves.c_deg, [0.0, 1.0, 2.0])


def test_an_f_outside_the_controllers_range_is_refused():
    fanuc = Controller(dialect="iso-sts", f_min=0.001, f_max=9999.999)
    with pytest.raises(dialects.DialectError, match=r"line 3, column 5 .*F26641.5 is outside"):
        dialects.read(
            ["G90 G18", "G01 X1. C0. Z0.", "G93 F26641.496021", "C1. X0.99 Z0.", "M30"], "iso-sts", fanuc
        )


def test_a_varying_feed_is_predicted_pass_by_pass(tmp_path, flat_catalogs):
    """A feed that grows linearly with the radius: no spiral of constant feed; on a flat part
    the largest cusp is that of the largest feed inside the judged ring, f²/8r."""
    out = []
    x, k = RADIUS_MM, 0
    while x > 0.01:
        k += 1
        feed_um = 4.0 + 12.0 * x / RADIUS_MM  # 16 µm/rev at the edge, 4 at the centre
        x -= STEP_DEG / 360.0 * feed_um * 1e-3
        out.append(f"C{(k * STEP_DEG) % 360.0:.6f} X{x:.6f} Z0.000000")
    code, got = _with_catalogs(
        flat_catalogs,
        tmp_path,
        moore_650fg(out, passes=1),
        "--surface",
        "flat",
        "--nose-radius-um",
        str(NOSE_UM),
    )
    assert code == 0, got
    info = json.loads(got)
    outer_mm = info["judged_radii_mm"][1]
    feed_there = 4.0 + 12.0 * outer_mm / RADIUS_MM
    assert info["feed_um_per_rev"]["max"] > 1.3 * info["feed_um_per_rev"]["min"]
    # the cusp grows with the feed: the judged ring's outer cusps bound the P-V
    assert info["pv_beyond_centre_nm"] == pytest.approx(feed_there**2 / (8.0 * NOSE_UM) * 1e3, rel=0.05)


# ------------------------------------------------------------------------------------- PMAC
PMAC_MANUAL = """CLOSE
OPEN PROG 1 CLEAR
ABS
RAPID
Z1
C0X1Z0
INC
PVT100
C36:360X-0.001:-0.01Z0:0
C36:360X-0.001:-0.01Z0:0
C36:360 X-0.001:-0.01 Z0:0
CLOSE
"""


def test_the_pmac_reader_takes_the_manuals_syntax():
    """Integers, words without spaces, INC after ABS, ``PVT<ms>``: velocities in units per
    Ix90 ms (1000 by default: per second)."""
    moves = dialects.read(PMAC_MANUAL.split("\n"), "pmac-pvt", nc.profile_for("sts-pmac-pvt", "pmac-pvt"))
    np.testing.assert_allclose(moves.c_deg, [0.0, 36.0, 72.0, 108.0])
    np.testing.assert_allclose(moves.x_mm, [1.0, 0.999, 0.998, 0.997])
    np.testing.assert_allclose(moves.seconds, 0.1)
    np.testing.assert_allclose(moves.velocity["C"], [0.0, 360.0, 360.0, 360.0])  # from rest after RAPID
    per_minute = Controller(dialect="pmac-pvt", interpolation="pvt", ix90_ms=60000.0)
    slow = dialects.read(PMAC_MANUAL.split("\n"), "pmac-pvt", per_minute)
    np.testing.assert_allclose(slow.velocity["C"], [0.0, 6.0, 6.0, 6.0])


def test_pmac_time_rules_follow_the_profile():
    """Times in ms on the controller's 1/4 µs steps; Power PMAC's spline<ms> carries its time,
    a Turbo PMAC's spline mode is SPLINE1."""
    text = PMAC_MANUAL.replace("PVT100", "PVT60.36925").split("\n")
    assert dialects.read(text, "pmac-pvt").seconds[0] == pytest.approx(0.06036925, abs=1e-15)
    # 60.3692501 ms is stored as the nearest 1/4 µs step
    finer = PMAC_MANUAL.replace("PVT100", "PVT60.3692501").split("\n")
    assert dialects.read(finer, "pmac-pvt").seconds[0] == pytest.approx(0.06036925, abs=1e-15)
    spline = [
        "OPEN PROG 1 CLEAR",
        "ABS",
        "RAPID",
        "C0 X1 Z0",
        "spline10",
        "C36 X0.999 Z0",
        "C72 X0.998 Z0",
        "CLOSE",
    ]
    power = Controller(dialect="pmac-spline", interpolation="spline1", pmac_syntax="power")
    assert dialects.read(spline, "pmac-spline", power).n_points == 3
    with pytest.raises(dialects.DialectError, match=r"line 5 .*spline is SPLINE1, timed by TM \(I42=0\)"):
        dialects.read(spline, "pmac-spline")


SPLINE_TURBO = [
    "OPEN PROG 1 CLEAR",
    "ABS",
    "RAPID",
    "C0 X1 Z0",
    "SPLINE1 {word}4",
    "C36 X0.999 Z0",
    "C72 X0.998 Z0",
    "C108 X0.997 Z0",
    "CLOSE",
]


@pytest.mark.parametrize(("i42", "good", "bad"), [(0, "TM", "TA"), (1, "TA", "TM")])
def test_i42_selects_the_word_that_times_spline_and_pvt_moves(i42, good, bad):
    """The Turbo PMAC Software Reference's I42 entry: 0 makes TM, 1 makes TA the SPLINE and
    PVT move time; the other word inside those modes is refused naming I42."""
    ctrl = Controller(dialect="pmac-spline", interpolation="spline1", i42=i42)
    text = [ln.format(word=good) for ln in SPLINE_TURBO]
    moves = dialects.read(text, "pmac-spline", ctrl)
    np.testing.assert_allclose(moves.seconds, 0.004)
    with pytest.raises(
        dialects.DialectError, match=rf"^line 5 .*{bad}4 in SPLINE1 mode: under I42={i42} .*{good}"
    ):
        dialects.read([ln.format(word=bad) for ln in SPLINE_TURBO], "pmac-spline", ctrl)


@pytest.mark.parametrize("i42", [0, 1])
def test_pvt_data_sets_the_time_in_either_mode_and_tm_is_honoured_in_pvt_mode(i42):
    """``PVT<ms>`` sets the move time whatever I42 says; under I42 = 0 a TM8 in PVT mode
    times the segments after it exactly as PVT8 would."""
    ctrl = Controller(dialect="pmac-pvt", interpolation="pvt", i42=i42)
    assert dialects.read(PMAC_MANUAL.split("\n"), "pmac-pvt", ctrl).seconds == pytest.approx([0.1] * 3)
    lines = PMAC_MANUAL.split("\n")
    lines.insert(9, "TM8" if i42 == 0 else "TA8")  # after the first PVT move
    as_pvt = PMAC_MANUAL.split("\n")
    as_pvt.insert(9, "PVT8")
    got, want = dialects.read(lines, "pmac-pvt", ctrl), dialects.read(as_pvt, "pmac-pvt", ctrl)
    np.testing.assert_allclose(got.seconds, [0.1, 0.008, 0.008])
    np.testing.assert_allclose(got.seconds, want.seconds)
    other = PMAC_MANUAL.split("\n")
    other.insert(9, "TA8" if i42 == 0 else "TM8")
    with pytest.raises(dialects.DialectError, match=rf"^line 10 .*in PVT mode: under I42={i42}"):
        dialects.read(other, "pmac-pvt", ctrl)


@pytest.mark.parametrize(
    ("edit", "why"),
    [
        (
            ("PVT100", "PVT0.0000001"),
            r"^line 8 .*segment time PVT0.0000001 ms is outside .*0.44211 ms servo cycle",
        ),
        (("PVT100", "PVT5000"), r"^line 8 .*PVT5000 ms is outside .*4095.9998 ms\]"),
        (("C36:360X", "C36:" + "9" * 400 + ".0X"), r"^line 9 .*C velocity 9+… is not a finite number"),
        (
            ("X-0.001:-0.01Z0:0\nC36:360 X", "X-0.001:-0.01Z0:0\nC36:360 X" + "1" * 400 + ".5"),
            r"^line 11 .*X position .* is not a finite number",
        ),
    ],
)
def test_absurd_pmac_times_and_numbers_are_refused_by_line(edit, why):
    text = PMAC_MANUAL.replace(*edit, 1)
    with pytest.raises(dialects.DialectError, match=why):
        dialects.read(text.split("\n"), "pmac-pvt")


def test_c_modulo_360_needs_a_c_motor_that_rolls_over():
    """C written modulo 360 on a profile without rollover (Ixx27 = 0) is refused naming the
    line and Ixx27; with rollover every move takes the shorter way round."""
    blocks = [f"C{(36.0 * k) % 360:g}:360 X{1 - 0.001 * k:g}:-0.01 Z0:0" for k in range(1, 16)]
    text = ["OPEN PROG 1 CLEAR", "ABS", "RAPID", "C0 X1 Z0", "PVT100", *blocks, "CLOSE"]
    with pytest.raises(dialects.DialectError, match=r"^line 15: C goes from 324 to 0.*\(Ixx27 = 0"):
        dialects.read(text, "pmac-pvt", nc.profile_for("sts-pmac-pvt", "pmac-pvt"))
    rolls = Controller(dialect="pmac-pvt", interpolation="pvt", c_wrap="revolution")
    np.testing.assert_allclose(dialects.read(text, "pmac-pvt", rolls).c_deg, 36.0 * np.arange(16))


def test_the_pmac_time_unit_is_named_per_controller_family():
    turbo = Controller(dialect="pmac-pvt", interpolation="pvt")
    power = Controller(dialect="pmac-pvt", interpolation="pvt", pmac_syntax="power")
    want = "Isx90=1000 velocity per 1 s, I42=0 segment time by TM or PVT<ms>"
    assert turbo.conventions()[0].startswith(want)
    assert power.conventions()[0].startswith("Coord[x].FeedTime=1000 velocity per 1 s")


# -------------------------------------------------------------------- what gcodeparser is not
def test_gcodeparser_is_not_a_controllers_reading():
    """gcodeparser (PyPI) is a tokenizer: it drops modal blocks without a G word and reads
    G-code inside comments, so the tests use it only on ftsweep's own exports (a G word on
    every block, no code in comments) and LinuxCNC's rs274 as the independent reader."""
    gcodeparser = pytest.importorskip("gcodeparser")
    text = moore_650fg(points()[:360], passes=1)
    parsed = gcodeparser.parse_gcode_lines(text, include_comments=False)
    moves = _read(text)
    cutting = [g for g in parsed if "C" in g.params and g.command == ("G", 1)]
    assert moves.n_points == 361 and len(cutting) < 360  # the point blocks carry no G word
    # a comment holding G-code is read as a move, even with comments excluded
    commented = gcodeparser.parse_gcode_lines("(G01 X5.0)\nG01 X1.0\n", include_comments=False)
    assert [g.params.get("X") for g in commented] == [5.0, 1.0]
    assert _read("G90 G18\n(G01 X5.0)\nG01 X1. C0. Z0.\nG93 F0.001\nC1. X0.99 Z0.\n").x_mm[0] == 1.0


@pytest.mark.skipif(not shutil.which("cc"), reason="no C compiler on this machine")
def test_the_compiled_reference_reads_the_manuals_pmac_as_the_reader_does(tmp_path):
    """INC, integers, words without spaces and velocities per Ix90 ms: the C reference
    (written from the manual, its PVT the cubic in time in powers of t) and the reader with
    the simulator's Hermite segments give every axis alike."""
    from ftsweep.exports import compiled

    path = tmp_path / "manual.pmc"
    path.write_text(PMAC_MANUAL)
    for ix90 in (1000.0, 60000.0):
        ctrl = Controller(dialect="pmac-pvt", interpolation="pvt", ix90_ms=ix90)
        moves = dialects.read(PMAC_MANUAL.split("\n"), "pmac-pvt", ctrl)
        exe = compiled._build(tmp_path, [])
        run = subprocess.run(
            [str(exe), str(path), "7", f"{ix90:g}", "0", "0", "0"], capture_output=True, timeout=60
        )
        got = np.frombuffer(run.stdout, dtype=np.float64)
        want = compiled.file_segments(moves, 7)
        assert int(got[0]) == sum(compiled.AXIS_BITS[a] for a in want)
        np.testing.assert_allclose(
            got[1:].reshape(-1, len(want)), np.column_stack(list(want.values())), atol=1e-12
        )


def test_a_cumulative_c_past_the_controllers_soft_limit_is_refused_at_export():
    from ftsweep.exports.files import ProgramError

    moves = dialects.Moves(np.arange(5) * 500.0, np.linspace(1.0, 0.99, 5), np.zeros(5), np.full(4, 0.01))
    soft = Controller(dialect="linuxcnc", interpolation="linear", c_limit_deg=1500.0)
    with pytest.raises(ProgramError, match=r"C reaches 2,000° accumulated, past the controller's soft limit"):
        dialects.check_limits(moves, soft)
    dialects.check_limits(moves, soft.model_copy(update={"c_limit_deg": None}))  # a wrapped rotary: no limit


def test_a_programs_simulation_is_bounded_before_any_work(flat_catalogs):
    """Bounded work on any program: a ray's nodes and its crossings (one per revolution of
    every cut) are counted against the case's node budget before a ray is cast."""
    from ftsweep.engine.case import CaseError
    from ftsweep.engine.planning import resolve_specs
    from ftsweep.kinds.spiral.dialect import commanded_of, stand_in_case
    from ftsweep.simulate import run_case

    moves = _read(moore_650fg())
    case = stand_in_case("flat", "sts-moore", "reference")
    specs = resolve_specs(case, flat_catalogs)
    with pytest.raises(CaseError, match="evaluation nodes"):
        run_case(case, catalog_folder=flat_catalogs, specs=specs, program=commanded_of(moves), max_nodes=1e4)
    assert run_case(case, catalog_folder=flat_catalogs, specs=specs, program=commanded_of(moves))["pv_nm"] > 0


def test_a_pmac_cut_ends_at_rapid_and_its_retract_is_not_cut():
    text = PMAC_MANUAL.removesuffix("CLOSE\n") + "RAPID\nZ2\nCLOSE\n"
    moves = dialects.read(text.split("\n"), "pmac-pvt")
    assert moves.n_points == 4 and moves.z_mm[-1] == 0.0  # the retract to Z2 is not a point
    again = text.removesuffix("CLOSE\n") + "PVT100\nC36:360 X-0.001:-0.01 Z0:0\nCLOSE\n"
    with pytest.raises(dialects.DialectError, match="a second cut after RAPID"):
        dialects.read(again.split("\n"), "pmac-pvt")


def test_a_four_axis_program_is_predicted_as_its_tool_turns_over_the_part(tmp_path, flat_catalogs):
    """The same spiral written with the tool off the X axis (Y = 0.1 mm, X shortened so
    that the radius is the same, C turned back by the offset's angle) cuts the same part."""
    plain = moore_650fg(passes=1)
    blocks = []
    for k in range(1, N_BLOCKS + 1):
        r = RADIUS_MM - k * STEP_DEG / 360.0 * FEED_UM * 1e-3
        y = 0.1 * r / RADIUS_MM
        x = math.sqrt(r * r - y * y)
        c = (k * STEP_DEG - math.degrees(math.atan2(y, x))) % 360.0
        blocks.append(f"C{c:.6f} X{x:.6f} Y{y:.6f} Z0.000000")
    x0 = math.sqrt(RADIUS_MM**2 - 0.1**2)
    c0 = -math.degrees(math.atan2(0.1, x0)) % 360.0
    turned = moore_650fg(blocks, passes=1).replace(f"X{RADIUS_MM:.1f} C0.", f"X{x0:.6f} Y0.1 C{c0:.6f}")
    a = json.loads(
        _with_catalogs(flat_catalogs, tmp_path, plain, "--surface", "flat", "--nose-radius-um", "500")[1]
    )
    b = json.loads(
        _with_catalogs(flat_catalogs, tmp_path, turned, "--surface", "flat", "--nose-radius-um", "500")[1]
    )
    assert b["pv_nm"] == pytest.approx(a["pv_nm"], rel=0.01)


@pytest.mark.parametrize(
    ("block", "column", "why"),
    [
        ("G01 X1.0 Q5 Z0.0", 10, "the word Q is not one"),
        ("G01 C1.0 X1 Z0.0", 10, "X1 has no decimal point"),
        ("G01 X1.0 ?? Z0.", 10, "cannot read '??'"),
        ("G01 X1.0 G10 Z0.", 10, "G10 sets offsets"),
    ],
)
def test_a_refusal_names_line_column_word_and_reason(block, column, why):
    lines = ["G90 G18", "G01 X2.0 C0.0 Z0.0 F100.", "G93 F100.", block, "M30"]
    with pytest.raises(dialects.DialectError, match=rf"^line 4, column {column} .*{why}"):
        dialects.read(lines, "iso-sts")


def test_z20_is_twenty_millimetres_on_a_moore():
    lines = ["G90 G18", "G01 X1. C0.", "G94 Z20 F500", "G93 F0.001", "C1. X0.99999", "C2. X0.99998", "M30"]
    moves = dialects.read(lines, "iso-sts", nc.profile_for("sts-moore", "iso-sts"))
    np.testing.assert_allclose(moves.z_mm, 20.0)


@given(p=st.lists(st.floats(-10.0, 10.0), min_size=2, max_size=30))
def test_a_spline1_sequence_leaves_and_reaches_its_ends_at_rest(p):
    """The controller's added pieces (a zero-distance TA segment at each end): the path
    starts at the first control point and ends at the last, both with zero velocity, one
    segment more at each end than the control points make."""
    from ftsweep.stages.interpolation import segments

    y, d0, d1 = segments.added_pieces_segments(np.array(p))
    assert y.size == len(p) + 2 and d0.size == len(p) + 1
    assert y[0] == p[0] and y[-1] == p[-1] and d0[0] == 0.0 and d1[-1] == 0.0
    # the interior way-points are the uniform B-spline's (P_k-1 + 4 P_k + P_k+1)/6
    q = np.concatenate([[p[0]] * 2, p, [p[-1]] * 2])
    np.testing.assert_allclose(y[1:-1], (q[1:-3] + 4.0 * q[2:-2] + q[3:-1]) / 6.0, atol=1e-12)


@pytest.mark.skipif(not shutil.which("cc"), reason="no C compiler on this machine")
def test_a_power_pmac_spline_program_is_written_in_its_syntax_and_read_alike(tmp_path):
    """A Power PMAC profile writes spline<ms>; the reader and the C reference read it alike."""
    from ftsweep.exports import compiled

    ctrl = Controller(dialect="pmac-spline", interpolation="spline1", pmac_syntax="power")
    m = dialects.Moves(np.arange(6) * 36.0, np.linspace(1.0, 0.995, 6), np.zeros(6), np.full(5, 0.01))
    lines = dialects.render(m, "pmac-spline", ["power"], ctrl)
    assert "spline10" in lines and not any(ln.startswith("SPLINE1") for ln in lines)
    path = tmp_path / "p.pmc"
    path.write_text("\n".join(lines) + "\n")
    moves = dialects.read(lines, "pmac-spline", ctrl)
    exe = compiled._build(tmp_path, [])
    run = subprocess.run([str(exe), str(path), "5", "1000", "0", "0", "1"], capture_output=True, timeout=60)
    got = np.frombuffer(run.stdout, dtype=np.float64)
    want = compiled.file_segments(moves, 5)
    np.testing.assert_allclose(
        got[1:].reshape(-1, len(want)), np.column_stack(list(want.values())), atol=1e-12
    )


# ------------------------------------------------------------- programs as shops publish them
def published(body: list[str] | None = None, passes: int = 2, blank: bool = True) -> str:
    """A program shaped like a CAM's published Moore template: macro variables for the passes
    and the depth, a WHILE loop whose every pass shifts Z with ``G52 Z[#8]``, approaches in
    G94, then ``G93 F0.001`` and a zero-length first block where the approach left the tool,
    the points with C written modulo 360 (a whole revolution as C360.), an air return
    ``G93 F0.001 C0`` from C360 to C0, and blank lines between the sections."""
    gap = [""] if blank else []
    blocks = points() if body is None else body
    head = [
        "%",
        "O1000",
        "(MOORE 650FG STS TEMPLATE)",
        f"#100 = {passes} (NUMBER OF PASSES)",
        "#103 = 0.002 (DEPTH PER PASS)",
        "#8 = [#100 - 1] * #103",
        *gap,
        "G52 G63 G71 G103 G40 G18 G90",
        "G54",
        "T0101",
        "M78",
        "M26.1",
        *gap,
        "WHILE [#100 GT 0] DO1",
        "G52 Z[#8]",
        "G94 G01 Z20. F500.",
        f"X{RADIUS_MM:.6f} C0.",
        "Z0. F10.",
        "G93 F0.001",
        f"C0.000000 X{RADIUS_MM:.6f} Z0.000000",
    ]
    tail = [
        "G93 F0.001 C0",
        "G94 G01 Z20. F500.",
        "#8 = #8 - #103",
        "#100 = #100 - 1",
        "END1",
        *gap,
        "G52",
        "M29",
        "M30",
        "%",
    ]
    return "\n".join([*head, *gap, *blocks, *gap, *tail]) + "\n"


def whole_revolutions() -> list[str]:
    """:func:`points` as a CAM prints a whole revolution's C: 360., not 0."""
    return [b.replace("C0.000000 ", "C360.000000 ") for b in points()]


def test_a_published_template_is_read_as_its_controller_runs_it():
    """The zero-length first block and the air return C360 -> C0 move no axis: legal blocks
    that take their time; the template's loop gives one cut per pass."""
    text = published(whole_revolutions(), passes=3)
    moves = _read(text)
    lines = text.split("\n")
    assert len(moves.cuts()) == 3
    assert moves.n_points == 3 * (N_BLOCKS + 1)
    # per pass: the zero-length block and the air return stand still for 1 ms each
    assert moves.still_s == pytest.approx(3 * 2 * BLOCK_S)
    stills = [line for line, what in moves.not_cut if "moving no axis" in what]
    first = lines.index(f"C0.000000 X{RADIUS_MM:.6f} Z0.000000") + 1  # physical, blank lines counted
    back = lines.index("G93 F0.001 C0") + 1
    assert (first, back) == (20, first + N_BLOCKS + 3)  # a blank line before and after the points
    assert stills[:2] == [first, back]
    for k, (lo, hi) in enumerate(moves.cuts()):
        np.testing.assert_allclose(moves.z_mm[lo:hi], (2 - k) * 0.002, atol=1e-12)
        # a cut's start (where the approach left the tool) is named by its first block that turns C
        assert moves.point_lines[lo] == first + 2 and moves.point_lines[hi - 1] == back - 2
    summary = dialects.summary(moves)
    assert summary["spindle_rpm_range"]["min"] == pytest.approx(summary["spindle_rpm_range"]["max"])
    # a block's own drop is printed to 1 nm (6 decimals of mm): per block the feed is known to
    # 1 nm over the block's turn, 0.36 µm/rev here, where over a revolution the rounding averages out
    printed = 1e-3 * 360.0 / STEP_DEG
    assert summary["feed_um_per_rev_by_block"]["median"] == pytest.approx(FEED_UM, abs=printed)
    assert summary["feed_um_per_block"]["median"] == pytest.approx(FEED_UM * STEP_DEG / 360.0, abs=1e-3)
    assert summary["feed_um_per_rev"]["median"] == pytest.approx(FEED_UM, rel=1e-4)


def brute_force_pv_nm(moves: dialects.Moves, got: dict) -> float:
    """An independent P-V [nm] of a linear program on a flat part (model §5, §6) over the
    zone ftsweep judged: on rays at ftsweep's angles, every pass of every cut where C crosses
    the ray (X and Z linear in C between blocks) and the opposite ray's at −X, the lowest
    nose arc over nodes 0.25 µm apart, no hull and no kernel."""
    rc = got["nose_radius_um"]
    n = got["record"]["n_theta"]
    lo, hi = (v * 1e3 for v in got["judged_radii_mm"])
    r = np.arange(lo, hi, 0.25)
    worst = [math.inf, -math.inf]
    for theta in (np.arange(n) + 0.5) / n * 360.0:
        pos, z = [], []
        for side, sign in ((theta, 1.0), (theta + 180.0, -1.0)):
            for a, b in moves.cuts():
                c = moves.c_deg[a:b]
                k = np.arange(math.ceil((c[0] - side) / 360.0), math.floor((c[-1] - side) / 360.0) + 1)
                at = side + 360.0 * k
                pos.append(sign * np.interp(at, c, moves.x_mm[a:b]) * 1e3)
                z.append(np.interp(at, c, moves.z_mm[a:b]) * 1e3)
        p, zp = np.concatenate(pos), np.concatenate(z)
        d = r[:, None] - p[None, :]
        arcs = np.where(np.abs(d) < rc, zp[None, :] + rc - np.sqrt(np.maximum(rc * rc - d * d, 0.0)), np.inf)
        e = arcs.min(axis=1)
        worst = [min(worst[0], float(e.min())), max(worst[1], float(e.max()))]
    return (worst[1] - worst[0]) * 1e3


def test_a_published_templates_form_error_is_the_feeds_cusp(tmp_path, flat_catalogs):
    """The independent computation: on a flat part the last pass leaves the cusps f²/8r."""
    code, out = _with_catalogs(
        flat_catalogs,
        tmp_path,
        published(whole_revolutions()),
        "--surface",
        "flat",
        "--nose-radius-um",
        str(NOSE_UM),
    )
    assert code == 0, out
    got = json.loads(out)
    assert got["cuts"] == 2
    assert got["pv_beyond_centre_nm"] == pytest.approx(CUSP_NM, rel=0.02)
    # the whole judged zone, the centre included: a brute-force envelope of the file's passes
    want = brute_force_pv_nm(_read(published(whole_revolutions())), got)
    assert got["pv_nm"] == pytest.approx(want, rel=0.02)
    assert got["standstill_s"] == pytest.approx(4 * BLOCK_S)
    assert any("moving no axis" in p["what"] for p in got["not_cut"])


def test_a_bare_point_list_is_read_with_its_templates_preamble(tmp_path, flat_catalogs):
    """The list (C X Z blocks only) read after the template's lines up to where the points go
    predicts what the template with the list pasted in does."""
    text = published(whole_revolutions(), passes=1, blank=False).split("\n")
    cut = text.index("G93 F0.001") + 2  # after the zero-length block
    pre, bare = tmp_path / "template.nc", tmp_path / "list.nc"
    # a preamble opens no loop the list would have to close: the template's head, one pass
    head = [line for line in text[:cut] if not line.startswith("WHILE")]
    pre.write_text("\n".join(head) + "\n")
    bare.write_text("\n".join(whole_revolutions()) + "\n")
    env = {"FTSWEEP_CATALOGS": str(flat_catalogs)}
    args = [
        "predict",
        "--program",
        str(bare),
        "--preamble",
        str(pre),
        "--machine",
        "sts-moore",
        "--surface",
        "flat",
        "--nose-radius-um",
        str(NOSE_UM),
        "--json",
    ]
    r = CliRunner().invoke(main, args, env=env)
    assert r.exit_code == 0, r.output
    got = json.loads(r.output)
    assert got["preamble"] == str(pre) and got["started_from"].startswith("G01 G93 F0.001 G90, at C0 X0.5 Z0")
    assert got["n_points"] == N_BLOCKS + 1
    assert got["pv_beyond_centre_nm"] == pytest.approx(CUSP_NM, rel=0.02)
    pasted = _read(published(whole_revolutions(), passes=1, blank=False))
    assert got["pv_nm"] == pytest.approx(brute_force_pv_nm(pasted, got), rel=0.02)
    # without the preamble the list has no time (the Moore's power-on feed mode is G94)
    r = CliRunner().invoke(main, [a for a in args if a not in ("--preamble", str(pre))], env=env)
    assert r.exit_code != 0 and "power-on feed mode is G94" in r.output
    # a refusal names the list's own line, and a preamble's as such
    bad = whole_revolutions()
    bad[99] = "C45.000000 X0.49 Q1 Z0.0"
    bare.write_text("\n".join(bad) + "\n")
    r = CliRunner().invoke(main, args, env=env)
    assert r.exit_code != 0 and "line 100, column 18" in r.output
    bare.write_text("\n".join(whole_revolutions()) + "\n")
    pre.write_text("\n".join(head).replace("G54", "G54 Q1") + "\n")
    r = CliRunner().invoke(main, args, env=env)
    assert r.exit_code != 0 and "preamble line 8, column 5" in r.output
    pre.write_text("\n".join(text[:cut]) + "\n")  # the loop's WHILE without its END
    r = CliRunner().invoke(main, args, env=env)
    loop = text.index("WHILE [#100 GT 0] DO1") + 1
    assert r.exit_code != 0 and f"preamble line {loop} " in r.output and "has no END1" in r.output


def test_refusals_name_the_physical_line_after_blank_lines(tmp_path):
    """Blank and comment lines count as an editor counts them."""
    body = whole_revolutions()[:50] + ["C45.000000 X0.49 Z0.0"]  # C turns back at the 51st point
    text = published(body, passes=1)
    want = text.split("\n").index("C45.000000 X0.49 Z0.0") + 1
    path = tmp_path / "p.nc"
    path.write_text(text)
    with pytest.raises(dialects.DialectError, match=rf"^line {want} .*C turns back"):
        nc.read_any(path, "sts-moore")
    assert want == 72  # 69 written lines and 3 blank ones before it


def test_a_refusal_about_a_point_names_its_line(tmp_path):
    """The simulator's refusals about a point (here C turning back in a PMAC cut) name the
    point's line."""
    text = PMAC_MANUAL.replace("C36:360 X-0.001", "C-72:360 X-0.001")
    code, out = predict(tmp_path, text, "--surface", "sinewave2d", "--nose-radius-um", "500")
    assert code == 1 and "line 11: C stands still or turns back within a cut" in out, out


SHOP_CUTTING = """
shop-83rpm:
  description: 720 blocks a revolution of 1 ms each (83.33 rpm), 38.9 um/rev, as a CAM's Moore programs.
  feed_um: 38.9
  nose_radius_um: 500.0
  spindle_rpm: 83.33333333333333
"""


@pytest.mark.parametrize("machine", ["sts-moore", "sts-linuxcnc"])
def test_an_export_never_refuses_its_own_plan(tmp_path, machine):
    """At 720 points a revolution and 38.9 µm/rev, 1 ms a block, the spiral's last block into
    the centre is under the servo period: the plan merges it into the one before, the header
    says so, and the program exports and verifies."""
    from support.catalogs import make_catalog_dir

    folder = make_catalog_dir(tmp_path / "catalogs")
    with (folder / "cutting.yaml").open("a") as fh:
        fh.write(SHOP_CUTTING)
    env = {"FTSWEEP_CATALOGS": str(folder)}
    spec = tmp_path / "s.yaml"
    spec.write_text(
        f"surface: flat\nlayout: spiral\nmachine: {machine}\ncutting: shop-83rpm\n"
        "axes:\n  points_per_rev: [720]\n"
    )
    cube, out = tmp_path / "s.zarr", tmp_path / "p.nc"
    run = CliRunner()
    r = run.invoke(main, ["sweep", str(spec), "--out", str(cube), "--scheduler", "synchronous"], env=env)
    assert r.exit_code == 0, r.output
    r = run.invoke(main, ["export", str(cube), "--case", "0", "-o", str(out)], env=env)
    assert r.exit_code == 0, r.output
    end = next(line for line in out.read_text().split("\n") if "end: the last block" in line)
    last_ms = float(end.split("takes ")[1].split(" ms")[0])
    assert 1.0 <= last_ms < 2.0 and "merged into the one before it" in end
    r = run.invoke(main, ["verify", str(out)], env=env)
    assert r.exit_code == 0, r.output


def macro_free(passes: int = 2) -> str:
    """:func:`published` as a shop writes it without macros: each pass written out under its
    own literal ``G52 Z…``, a dwell before the cut, power-on G01 (no G word on the approach's
    X C block), blank lines."""
    out = ["%", "O1001", "(MACRO-FREE, TWO PASSES)", "", "G52 G63 G71 G103 G40 G18 G90", "G54"]
    for k in range(passes):
        out += [f"G52 Z{(passes - 1 - k) * 0.002:.3f}", "G94 Z20. F500.", f"X{RADIUS_MM:.6f} C0."]
        out += ["Z0. F10.", "G04 X0.5", "G93 F0.001", f"C0.000000 X{RADIUS_MM:.6f} Z0.000000", ""]
        out += [*whole_revolutions()[:720], "G93 F0.001 C0", "G94 Z20. F500.", ""]
    return "\n".join([*out, "G52", "M30", "%"]) + "\n"


@pytest.mark.skipif(not shutil.which("cc"), reason="no C compiler on this machine")
def test_the_compiled_reference_reads_a_shop_program_as_the_reader_does(tmp_path):
    """Power-on G01, G04 (a time, not a move to X 0.5 mm), G52 offsets (not moves), blank
    lines, a zero-length block and an air return: the C reference and the strict reader read
    the same cuts, every axis alike; a macro statement is refused by the reference by line."""
    path = tmp_path / "shop.nc"
    path.write_text(macro_free())
    r = CliRunner().invoke(
        main, ["predict", "--program", str(path), "--machine", "sts-moore", "--compiled", "--json"]
    )
    assert r.exit_code == 0, r.output
    got = json.loads(r.output)
    assert got["cuts"] == 2 and got["dwell_s"] == pytest.approx(1.0)
    axes = got["compiled"]["compiled_axes"]
    assert set(axes) == {"C", "X", "Z"} and all(d <= b for d, b in axes.values())
    path.write_text(published(whole_revolutions()[:720]))
    r = CliRunner().invoke(main, ["predict", "--program", str(path), "--machine", "sts-moore", "--compiled"])
    assert (
        r.exit_code == 1
        and "the reference interpolator refused" in r.output
        and "line 4: a macro" in r.output
    )


@pytest.mark.parametrize(
    ("block", "why"),
    [
        ("G93 F" + "9" * 400 + ".0", r"^line 20, column 5 .*F9+ is not a finite number"),
        ("#7 = " + "9" * 400, r"^line 20 .*#7 = 9+.*not a finite number"),
    ],
)
def test_non_finite_g_code_numbers_are_refused_by_line(block, why):
    """A 400-digit literal is infinite as a double: refused naming the word, never a spindle of
    0 rpm and an infinite time."""
    lines = published(whole_revolutions()[:50], passes=1).split("\n")
    lines[19] = block  # the cut's G93 F0.001
    with pytest.raises(dialects.DialectError, match=why):
        _read("\n".join(lines))


def test_a_pvt_velocity_over_the_machines_limit_is_refused_by_line(tmp_path):
    """xzc-pmac-pvt declares X 250 mm/s: a velocity word of 300 mm/s is refused naming its line."""
    text = PMAC_MANUAL.replace("C36:360 X-0.001:-0.01 Z0:0", "C36:360 X-0.001:-300 Z0:0")
    code, out = predict(tmp_path, text, "--machine", "xzc-pmac-pvt")
    assert (
        code == 1 and "line 11: a X velocity of -300 mm/s, over the 250 mm/s of machine 'xzc-pmac-pvt'" in out
    )


def test_a_block_whose_f_gives_no_lathes_spindle_is_refused_by_its_line():
    """One block of 1 µs turning C 1°: 166,667 rpm, refused at that block's line."""
    body = whole_revolutions()[:360]
    body[29] = "G93 F0.000001 " + body[29]
    text = published(body, passes=1)
    want = text.split("\n").index(body[29]) + 1
    with pytest.raises(
        dialects.DialectError, match=rf"^line {want}: a block of 1e-06 s turning C 1 deg gives"
    ):
        _read(text)


def test_a_block_turning_the_spindle_past_the_machines_limit_is_refused_by_line(tmp_path):
    """xzc-pmac-pvt declares C at most 100 rpm: 36° in 10 ms (600 rpm) is refused at its block's
    line, whatever velocity the block's words give."""
    code, out = predict(tmp_path, PMAC_MANUAL.replace("PVT100", "PVT10"), "--machine", "xzc-pmac-pvt")
    assert code == 1 and "line 9: the block turns the spindle at 600 rpm, over the 100 rpm" in out, out
