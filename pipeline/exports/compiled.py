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

from ftsweep.store.io import ExportError

BOUND_UM = 1e-9
MIN_POINTS = 100_000
FLAGS = ("-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Werror")


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


def check_program(path: Path, moves: Any, adapter: Any) -> dict[str, Any]:
    """A PMAC PVT or SPLINE1 program evaluated by the compiled reference (Hermite in time,
    B-spline basis) against the segments the simulator forms from the same moves (the kind's
    adapter's ``commands``) at the same places: ``M`` parameters per segment, at least
    ``MIN_POINTS`` in all."""
    if moves.interpolation == "linear" or adapter.commands is None:
        raise ExportError(
            "--compiled evaluates table headers and PMAC PVT and SPLINE1 programs; this one is linear G-code"
        )
    per = max(1, math.ceil(MIN_POINTS / (moves.n_points - 1)))
    want = adapter.commands(moves, per)
    with tempfile.TemporaryDirectory(prefix="ftsref-") as tmp:
        exe = _build(Path(tmp), [])
        done = subprocess.run([str(exe), str(path), str(per)], capture_output=True, timeout=600)
    if done.returncode != 0:
        raise ExportError(
            f"the reference interpolator refused {path}: {done.stderr.decode(errors='replace')[:300]}"
        )
    got = np.frombuffer(done.stdout, dtype=np.float64) * 1e3
    return _compared(got, want, f"points along the path ({per} per segment)")


def _compared(got: np.ndarray, want: np.ndarray, what: str) -> dict[str, Any]:
    if got.shape != want.shape:
        raise ExportError(f"the reference interpolator gave {got.size:,} values for {want.size:,} {what}")
    diff = float(np.max(np.abs(got - want))) if got.size else 0.0
    if not diff <= BOUND_UM:
        k = int(np.argmax(np.abs(got - want)))
        raise ExportError(
            f"the compiled reference and the simulator differ by {diff:.3g} µm at {what} #{k} "
            f"(bound {BOUND_UM:g} µm): the controller would not cut what was predicted"
        )
    return {
        "compiled_points": int(got.size),
        "compiled_max_diff_um": diff,
        "compiled_bound_um": BOUND_UM,
        "compiled_what": what,
    }
