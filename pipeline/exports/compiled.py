"""``verify --compiled``: what the controller computes from an exported file, by the C99
reference interpolator shipped with ftsweep (``ftsweep/exports/controller/ftsref.c``) built
with the system's C compiler, compared with the one simulator at 10⁵ points or more.

Both sides evaluate the same formulas on the same doubles (the C side with no fused
multiply-add, ``-ffp-contract=off``); they differ by rounding only: a few units in the last
place of commands of at most a few mm, about 1e-12 µm. The bound, 1e-9 µm, is a thousand
times that and a million times below the smallest quantity a file holds (1 pm): any
difference in what is computed (an index off by one cell, a swapped tangent, another end
rule) shows as nanometres.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
import tempfile
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from ftsweep.errors import ExportError

BOUND_UM = 1e-9
MIN_POINTS = 100_000
FLAGS = ("-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-pedantic", "-Wconversion", "-Werror")


def compiler() -> str:
    """The system's C compiler ($CC, cc, gcc or clang); ExportError when there is none."""
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and shutil.which(name):
            return str(shutil.which(name))
    raise ExportError("--compiled needs a C compiler (cc, gcc or clang on PATH, or $CC): none found")


def _build(work: Path, defines: list[str]) -> Path:
    source = resources.files("ftsweep.exports.controller").joinpath("ftsref.c")
    src = work / "ftsref.c"
    src.write_text(source.read_text(encoding="ascii"), encoding="ascii")
    exe = work / "ftsref"
    done = subprocess.run(
        [compiler(), *FLAGS, *defines, str(src), "-o", str(exe), "-lm"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    if done.returncode != 0:
        raise ExportError(f"the reference interpolator did not compile: {done.stderr.strip()[:600]}")
    return exe


def check_header(path: Path, layout: Any, table_um: np.ndarray, seed: int = 0) -> dict[str, Any]:
    """The header's table looked up by the compiled reference (the header's own macros and
    table) against the simulator's bilinear lookup (:func:`ftsweep.stages.interpolation.tables.interpolate`)
    at ``MIN_POINTS`` tool positions spread over the table (and past its edges)."""
    from ftsweep.stages.interpolation import tables as interpolation

    text = Path(path).read_text(encoding="ascii")
    found = re.search(r"^#define ([A-Z0-9_]+)_LAYOUT_IS_RING ", text, re.M)
    table = re.search(r"^static const \w+ ([a-z0-9_]+)_table\[", text, re.M)
    if not found or not table:
        raise ExportError(f"{path}: no LAYOUT_IS_RING macro or table declaration for the reference to use")
    rng = np.random.default_rng(seed)
    n = MIN_POINTS
    ring = bool(layout.periodic)
    outer = (layout.shape[0] - 1) * layout.pitch[0] + layout.origin[0]
    if ring:
        rho = rng.uniform(0.0, outer * 1.02, n)
        theta_deg = rng.uniform(0.0, 360.0, n)
        query = np.column_stack([rho, theta_deg])
        want = interpolation.interpolate(layout, table_um, rho, np.radians(theta_deg))
    else:
        x = rng.uniform(layout.origin[0] * 1.02, -layout.origin[0] * 1.02, n)
        y = rng.uniform(layout.origin[1] * 1.02, -layout.origin[1] * 1.02, n)
        query = np.column_stack([x, y])
        u = (x - layout.origin[0]) / layout.pitch[0]
        v = (y - layout.origin[1]) / layout.pitch[1]
        want = interpolation.bilinear(table_um, u, v, False)
    with tempfile.TemporaryDirectory(prefix="ftsref-") as tmp:
        work = Path(tmp)
        shutil.copyfile(path, work / "table.h")
        exe = _build(
            work,
            [
                '-DFTS_HEADER="table.h"',
                f"-DFTS_PREFIX={found.group(1)}",
                f"-DFTS_TABLE={table.group(1)}_table",
            ],
        )
        done = subprocess.run(
            [str(exe)], input=np.ascontiguousarray(query).tobytes(), capture_output=True, timeout=600
        )
    got = np.frombuffer(done.stdout, dtype=np.float64)
    return _compared(got, want, "table lookups")


# the axes a program moves, in the order and bits the reference writes them
AXIS_BITS = {"C": 1, "X": 2, "Y": 4, "Z": 8, "W": 16}


def check_program(path: Path, moves: Any, adapter: Any, ctrl: Any) -> dict[str, Any]:
    """A path program read and evaluated by the compiled reference, written from the
    controllers' manuals (PMAC PVT as the cubic in time through its positions and velocities
    in units per Ix90, SPLINE1 by the B-spline's basis functions, G93 G-code linear in time;
    every axis the program moves, ABS or INC) against the segment forms the one simulator
    takes from the same file (:func:`file_segments`) at ``M`` fractions of every segment of
    every cut, at least ``MIN_POINTS`` in all; a spiral's Z also against the simulator's own
    commands (its adapter's ``commands``). ``ctrl``: the profile the file was written for."""
    per, got, out = _reference_axes(path, moves, ctrl)
    if adapter.commands is not None and moves.cut_starts is None:
        z, planned = got[:, list(out).index("Z")] * 1e3, adapter.commands(moves, per)
        if moves.interpolation == "spline1":
            # the planner takes natural ends (P_-1 = 2P_0 - P_1) where the controller adds a
            # piece from and to rest: the segments agree but for two at each end (and the
            # two added ones), which lie in the part's unjudged edge and centre bands
            z = z.reshape(-1, per)[2:-2].ravel()
            planned = planned.reshape(-1, per)[1:-1].ravel()
        out["Z_simulated"] = _compared(z, planned, "Z as simulated")
    return _worst(out)


def compare_reading(path: Path, moves: Any, ctrl: Any) -> dict[str, Any]:
    """Any program (ftsweep's or another CAM's) read by the compiled reference and by the
    strict reader (``moves``, read with the profile ``ctrl``): every axis at ``M`` fractions
    of every segment of every cut, as :func:`check_program` compares them. The reference's
    limits (macro statements, block delete) are refused naming the line."""
    return _worst(_reference_axes(path, moves, ctrl)[2])


def _worst(out: dict[str, Any]) -> dict[str, Any]:
    worst = max(out.values(), key=lambda r: r["compiled_max_diff_um"] / r["compiled_bound_um"])
    axes = {k: [v["compiled_max_diff_um"], v["compiled_bound_um"]] for k, v in out.items()}
    return {**worst, "compiled_axes": axes}


def _reference_axes(path: Path, moves: Any, ctrl: Any) -> tuple[int, np.ndarray, dict[str, Any]]:
    """The reference run on ``path``: samples per segment, its values (points, axes) and each
    axis compared with the reader's segments."""
    per = max(1, math.ceil(MIN_POINTS / max(moves.n_points - len(moves.cuts()), 1)))
    args = [
        f"{float(ctrl.ix90_ms):g}",
        "1" if ctrl.g93_f == "seconds" else "0",
        "1" if ctrl.c_wrap == "revolution" and ctrl.dialect != "linuxcnc" else "0",
        "1" if ctrl.pmac_syntax == "power" else "0",
        str(int(ctrl.i42)),
        power_on(ctrl),
    ]
    with tempfile.TemporaryDirectory(prefix="ftsref-") as tmp:
        exe = _build(Path(tmp), [])
        done = subprocess.run([str(exe), str(path), str(per), *args], capture_output=True, timeout=600)
    if done.returncode != 0:
        raise ExportError(
            f"the reference interpolator refused {path}: {done.stderr.decode(errors='replace')[:300]}"
        )
    raw = np.frombuffer(done.stdout, dtype=np.float64)
    want = file_segments(moves, per)
    mask = sum(AXIS_BITS[a] for a in want)
    if not raw.size or int(raw[0]) != mask:
        raise ExportError(f"the reference interpolator read other axes than {', '.join(want)} from {path}")
    got = raw[1:].reshape(-1, len(want)) if raw.size > 1 else np.empty((0, len(want)))
    out: dict[str, Any] = {}
    for k, (axis, values) in enumerate(want.items()):
        out[axis] = _compared(got[:, k], values, f"{axis} at points along the path ({per} per segment)", 1e-3)
    return per, got, out


def power_on(ctrl: Any) -> str:
    """The profile's power-on modes as the block of G words the reference runs first."""
    motion = "" if ctrl.power_on_motion == "none" else ctrl.power_on_motion
    return f"{motion} {ctrl.power_on_feed} {ctrl.power_on_distance}".strip()


def file_segments(moves: Any, per: int) -> dict[str, np.ndarray]:
    """Every axis a program moves [mm, deg] at u = (j + 0.5)/``per`` of every segment of every
    cut, as the one simulator forms the segments from the file's numbers (linear; PVT cubic
    Hermite through the positions and the velocities V·T; SPLINE1's B-spline way-points and
    tangents of the control points with the manual's added pieces, from and to rest)."""
    from ftsweep.stages.interpolation import segments

    axes = {"C": moves.c_deg, "X": moves.x_mm, "Y": moves.y_mm, "Z": moves.z_mm, "W": moves.w_mm}
    u = (np.arange(per) + 0.5) / per
    out: dict[str, np.ndarray] = {}
    for axis, y in axes.items():
        if y is None:
            continue
        parts = []
        for lo, hi in moves.cuts():
            p = np.asarray(y[lo:hi], dtype=np.float64)
            if moves.interpolation == "spline1":  # the controller's sequence, from and to rest
                p, d0, d1 = segments.added_pieces_segments(p)
            elif moves.interpolation == "pvt":
                t = np.asarray(moves.seconds[lo : hi - 1], dtype=np.float64)
                v = np.asarray(moves.velocity[axis][lo:hi], dtype=np.float64)
                d0, d1 = v[:-1] * t, v[1:] * t
            else:
                d0 = d1 = np.diff(p)
            parts.append(_hermite(p, d0, d1, u))
        out[axis] = np.concatenate(parts)
    return out


def _hermite(p: np.ndarray, d0: np.ndarray, d1: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Cubic Hermite segments (docs/controllers.md) at fractions ``u`` of each, row-major."""
    a, b = p[:-1, None], p[1:, None]
    h00, h10 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u
    h01, h11 = -2 * u**3 + 3 * u**2, u**3 - u**2
    return (h00 * a + h10 * d0[:, None] + h01 * b + h11 * d1[:, None]).ravel()


def _compared(got: np.ndarray, want: np.ndarray, what: str, scale: float = 1.0) -> dict[str, Any]:
    """The largest difference [µm: ``scale`` µm a unit of the values] of the reference's
    values from the simulator's, refused over the bound: ``BOUND_UM`` plus 1e-15 of the
    values' size (a C of 10⁵ degrees rounds at ~1e-11: the two sides' formulas differ)."""
    if got.shape != want.shape:
        raise ExportError(f"the reference interpolator gave {got.size:,} values for {want.size:,} {what}")
    diff = float(np.max(np.abs(got - want))) / scale if got.size else 0.0
    bound = BOUND_UM + 1e-14 * float(np.max(np.abs(want))) / scale if got.size else BOUND_UM
    if not diff <= bound:
        k = int(np.argmax(np.abs(got - want)))
        raise ExportError(
            f"the compiled reference and the simulator differ by {diff:.3g} µm at {what} #{k} "
            f"(bound {bound:.3g} µm): the controller would not cut what was predicted"
        )
    return {
        "compiled_points": int(got.size),
        "compiled_max_diff_um": diff,
        "compiled_bound_um": bound,
        "compiled_what": what,
    }
