"""Timed path programs on a PVT controller (docs/controllers.md): the axes cubic in time
between points (stages.timed_path) in the one simulator, D paths ([5]) and Fresnel programs
([2]) planned, exported, read back and verified in PMAC PVT."""

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

from ftsweep.cli.main import main
from ftsweep.engine.case import Case, CaseError, program_request
from ftsweep.exports import dialects, nc
from ftsweep.inputs import catalogs
from ftsweep.inputs.programs.moves import DialectError
from ftsweep.simulate import run_case
from ftsweep.stages.interpolation import rays, timed_path


# ----------------------------------------------------------------------- closed forms
@settings(max_examples=50)
@given(st.lists(st.floats(-3, 3), min_size=5, max_size=5), st.integers(5, 60), st.integers(0, 2**16))
def test_local_slopes_are_exact_for_a_quartic_at_any_spacing(c, n, seed):
    """The velocity of a point is the slope of the quartic through five points of its piece:
    exact for any polynomial of degree ≤ 4, whatever the steps."""
    t = np.cumsum(np.random.default_rng(seed).uniform(0.1, 1.0, n))
    f = np.polynomial.Polynomial(c)
    np.testing.assert_allclose(
        timed_path.slopes(t, f(t)), f.deriv()(t), atol=1e-9 * (1.0 + np.abs(f(t)).max())
    )


def test_a_break_keeps_the_slope_of_the_piece_it_is_told():
    """|t − 5| has a corner at t = 5: each piece's slope is exact, the break's the chosen side's."""
    t = np.linspace(0.0, 10.0, 21)
    y = np.abs(t - 5.0)
    at = np.array([10])
    left = timed_path.slopes(t, y, at, np.array([True]))
    right = timed_path.slopes(t, y, at, np.array([False]))
    np.testing.assert_allclose(left[:10], -1.0, atol=1e-12)
    np.testing.assert_allclose(left[11:], 1.0, atol=1e-12)
    assert left[10] == pytest.approx(-1.0, abs=1e-12) and right[10] == pytest.approx(1.0, abs=1e-12)
    with pytest.raises(ValueError, match="strictly inside"):
        timed_path.slopes(t, y, np.array([0]))


@settings(max_examples=30)
@given(st.floats(0.5, 5.0), st.floats(-2.0, 2.0), st.integers(2, 50))
def test_tangents_from_velocities_and_back_are_the_same_segments(w, v, n):
    t = np.linspace(0.0, 1.0, n + 1)
    chan = np.column_stack([w * t, 3.0 + v * t**2, np.sin(t)])
    tan = timed_path.tangents(t, chan)
    again = timed_path.from_velocities(timed_path.velocities(tan, np.diff(t)), np.diff(t))
    np.testing.assert_allclose(again, tan, atol=1e-12)


def test_linear_tangents_cross_rays_where_the_linear_walk_does():
    """Segments with the chord as both tangents are the linear segments: the cubic crossing
    (a root in each segment) finds what the linear walk finds."""
    rng = np.random.default_rng(3)
    phi = np.cumsum(rng.uniform(0.01, 0.2, 400))
    rho = 1000.0 + 50.0 * np.sin(phi)
    z = 3.0 * np.cos(2.0 * phi)
    chan = np.column_stack([phi, rho, z])
    chord = np.diff(chan, axis=0)
    tan = np.empty((phi.size - 1, 6))
    tan[:, 0::2], tan[:, 1::2] = chord, chord
    theta = np.linspace(-math.pi, math.pi, 37)
    p1, w1, s1 = rays.crossings(phi, rho, z, theta)
    p2, w2, s2 = timed_path.crossings(phi, chan, tan, theta)
    np.testing.assert_array_equal(s1, s2)
    np.testing.assert_allclose(p2, p1, atol=1e-9, equal_nan=True)
    np.testing.assert_allclose(w2, w1, atol=1e-12, equal_nan=True)


def test_a_tool_held_still_on_a_turning_part_cuts_a_circle():
    """Turned frame ([2] eq. 9): X = r, Y = 0 while C turns at constant speed is the circle of
    radius r about the centre on the part, crossed on every ray at radius r, Z (linear in time)
    at the time C reaches the ray: exact, whatever the cubic."""
    t = np.linspace(0.0, 2.0, 81)
    c = 2.0 * math.pi * t + 0.3
    chan = np.column_stack([c, np.full(t.size, 500.0), np.zeros(t.size), 10.0 + 4.0 * t])
    tan = timed_path.tangents(t, chan)
    # the part turns under the tool: its angle on the part is −C
    angle = -np.unwrap(np.arctan2(-np.sin(c), np.cos(c)))
    theta = np.linspace(0.0, 2.0 * math.pi, 24, endpoint=False)
    pos, w, seg = timed_path.crossings(angle, chan, tan, theta, timed_path.TURNED, (0.0, 0.0), -1.0)
    ok = seg >= 0
    assert ok.sum() >= 2 * theta.size
    np.testing.assert_allclose(pos[ok], 500.0, atol=1e-9)
    # C reaches the ray's angle q (= −angle) at t = (q' − 0.3)/2π
    q = (theta[:, None] + 2.0 * math.pi * np.arange(pos.shape[1])[None, :]) + 2.0 * math.pi * math.floor(
        angle[0] / (2.0 * math.pi)
    )
    np.testing.assert_allclose(w[ok], (10.0 + 4.0 * (q - 0.3) / (2.0 * math.pi))[ok], atol=1e-9)


# ----------------------------------------------------------------------- the one simulator
def _dpath(machine: str) -> dict:
    case = Case(
        surface="concave_sphere",
        machine=machine,
        cutting="dpath-finish",
        layout=program_request(kind="dpath", spacing_um=100.0, points_per_cut=41),
    )
    return run_case(case)


def _fresnel(machine: str) -> dict:
    case = Case(
        surface="chebyshev_example",
        machine=machine,
        cutting="fresnel-finish",
        feed_um=8.0,
        layout=program_request(kind="fresnel", facet_height_um=10.0, points_per_turn=60),
    )
    return run_case(case)


@pytest.mark.parametrize(
    ("run", "linear", "pvt"),
    [(_dpath, "sts-xzc", "xzc-pmac-pvt"), (_fresnel, "xyzc-nanoform", "xyzc-pmac-pvt")],
)
def test_cubic_segments_cut_the_interpolation_error_of_the_same_points(run, linear, pvt):
    """The same points on a PVT controller: the interpolation-only error (commands against the
    exact ones at the crossings) falls by an order or more (h⁴ against h² per segment) and the
    form error does not grow; the points and the time stay those planned (within the time
    steps' rounding)."""
    a, b = run(linear), run(pvt)
    assert a["n_points"] == b["n_points"]
    assert b["pv_interp_nm"] < 0.1 * a["pv_interp_nm"]
    assert b["pv_nm"] <= a["pv_nm"] * 1.001
    assert b["machining_s"] == pytest.approx(a["machining_s"], rel=1e-6)


@pytest.mark.parametrize("run", [_dpath, _fresnel])
def test_a_spline1_machine_refuses_timed_programs_by_name(run):
    with pytest.raises(CaseError, match="spline1.*TA"):
        run("sts-pmac-spline")


def test_a_four_axis_pvt_program_reads_back_with_y():
    m = dialects.Moves(
        np.array([0.0, 10.0, 20.0]),
        np.array([1.0, 0.9, 0.8]),
        np.array([0.1, 0.2, 0.3]),
        np.array([0.01, 0.01]),
        np.array([0.05, 0.06, 0.07]),
        {a: np.array([1.0, 2.0, 3.0]) for a in "CXYZ"},
        "pvt",
    )
    from ftsweep.exports import nc
    from ftsweep.inputs import catalogs

    ctrl = nc.controller_of(catalogs.entry("machines", "xyzc-pmac-pvt"), "pmac-pvt")
    lines = dialects.render(m, "pmac-pvt", ["four axes"], ctrl)
    assert "C10.000000:2.000000 X0.900000:2.000000 Y0.060000:2.000000 Z0.200000:2.000000" in lines
    back = dialects.read(lines, "pmac-pvt")
    assert back.y_mm is not None
    np.testing.assert_allclose(back.y_mm, m.y_mm)
    np.testing.assert_allclose(back.velocity["Y"][1:], m.velocity["Y"][1:])
    # a Y first given during the cut: not a four-axis program from its start
    late = [("C0.000000 X1.000000" if ln == "C0.000000 X1.000000 Y0.050000" else ln) for ln in lines]
    assert late != lines
    with pytest.raises(DialectError, match="Y is given during the cut"):
        dialects.read(late, "pmac-pvt")


# ----------------------------------------------------------------------- export, verify, predict
def _cube(tmp: Path, name: str, text: str) -> Path:
    (tmp / f"{name}.yaml").write_text(text)
    cube = tmp / f"{name}.zarr"
    r = CliRunner().invoke(
        main, ["sweep", str(tmp / f"{name}.yaml"), "--out", str(cube), "--scheduler", "synchronous"]
    )
    assert r.exit_code == 0, r.output
    return cube


@pytest.mark.parametrize(
    ("name", "sweep", "axes"),
    [
        (
            "dpath",
            "surface: concave_sphere\nlayout: dpath\nmachine: xzc-pmac-pvt\ncutting: dpath-finish\n"
            "axes: {spacing_um: [500.0], points_per_cut: [41]}\n",
            "CXZ",
        ),
        (
            "fresnel",
            "surface: chebyshev_example\nlayout: fresnel\nmachine: xyzc-pmac-pvt\ncutting: fresnel-finish\n"
            "axes: {facet_height_um: [10.0], points_per_turn: [60], feed_um: [8.0]}\n",
            "CXYZ",
        ),
    ],
)
def test_a_timed_program_goes_out_in_pvt_and_verifies(tmp_path, name, sweep, axes):
    """Export writes every axis with its velocity on whole 0.25 µs steps; verify reads it as
    the controller does and re-simulates it within 1 % of the cube; a changed velocity digit
    is refused; predict reads it and names its axes' peaks."""
    import xarray as xr

    cube = _cube(tmp_path, name, sweep)
    out = tmp_path / f"{name}.pmc"
    r = CliRunner().invoke(main, ["export", str(cube), "--case", "0", "-o", str(out)])
    assert r.exit_code == 0, r.output
    lines = out.read_text().splitlines()
    blocks = [ln for ln in lines if ln.startswith("C") and ":" in ln]
    assert blocks and all([w[0] for w in b.split()] == list(axes) for b in blocks)
    for ln in lines:
        if ln.startswith("PVT"):
            steps = float(ln[3:]) * 1e-3 / 2.5e-7
            assert steps == pytest.approx(round(steps), abs=1e-6)
    # the program stops after its path within the machine's accelerations, every axis at once
    machine = "xzc-pmac-pvt" if axes == "CXZ" else "xyzc-pmac-pvt"
    moves = dialects.read(lines, "pmac-pvt", nc.profile_for(machine, "pmac-pvt"))
    limits = catalogs.entry("machines", machine).axes
    t_stop = moves.seconds[-1]
    assert moves.stopped and all(v[-1] == 0.0 for v in moves.velocity.values())
    assert abs(moves.velocity["X"][-2]) / t_stop <= limits.x_accel_m_s2 * 1e3 * (1 + 1e-6)
    assert abs(moves.velocity["Z"][-2]) / t_stop <= limits.z_accel_m_s2 * 1e3 * (1 + 1e-6)
    if limits.c_accel_rad_s2 is not None:
        assert abs(np.radians(moves.velocity["C"][-2])) / t_stop <= limits.c_accel_rad_s2 * (1 + 1e-6)
    r = CliRunner().invoke(
        main, ["verify", str(out), "--json", *(["--compiled"] if shutil.which("cc") else [])]
    )
    assert r.exit_code == 0, r.output
    record = json.loads(r.stdout)
    assert record["dialect"] == "pmac-pvt" and record["layout"] == name
    if "compiled_axes" in record:  # the C reference read every axis, Y included, as the file's segments
        assert set(record["compiled_axes"]) == set(axes)
        assert all(d <= b for d, b in record["compiled_axes"].values())
    cube_pv = float(xr.open_zarr(cube)["pv_nm"].values.ravel()[0])
    assert record["pv_nm"] == pytest.approx(cube_pv, rel=0.01)
    machine = "xzc-pmac-pvt" if axes == "CXZ" else "xyzc-pmac-pvt"
    r = CliRunner().invoke(main, ["predict", "--program", str(out), "--machine", machine, "--json"])
    assert r.exit_code == 0, r.output
    info = json.loads(r.stdout)
    assert info["n_points"] == record["n_points"] and info["interpolation"] == "pvt"
    named = {k.split("_")[0].upper() for k in info["axes"]}
    assert named == set(axes) - {"C"} and all(a["ok"] for a in info["axes"].values())
    # one velocity digit changed, the CRC left as it was: refused
    k = lines.index(blocks[len(blocks) // 2])
    pos, vel = lines[k].split()[1].split(":")
    lines[k] = lines[k].replace(f"{pos}:{vel}", f"{pos}:{vel[:-1]}{(int(vel[-1]) + 1) % 10}", 1)
    out.write_text("\n".join(lines) + "\n")
    r = CliRunner().invoke(main, ["verify", str(out)])
    assert r.exit_code == 1 and "CRC" in r.output
