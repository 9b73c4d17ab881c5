"""Path programs in the dialects machine controllers read (docs/controllers.md): ISO STS
G-code as a Moore Nanotech reads it, LinuxCNC's RS274/NGC, Delta Tau PMAC PVT and SPLINE1;
written from a program's points and read back by one strict reader.

A :class:`Moves` is what a program commands: the points' accumulated C [deg], X [mm],
Z [mm] (optionally Y [mm]) and the segments' times [s]; a PVT program adds each point's
velocities, a SPLINE1 program's positions are its B-spline's control points. The reader
evaluates what a controller would (modal G-code state, constant macro variables, WHILE loops
of constant count) and refuses anything else, naming the line: a file is data, never run
or re-rendered.
"""

from __future__ import annotations

from typing import Any, Optional

import numpy as np

from ftsweep.exports.moves import (
    Adapter,
    aligned,
    stop_seconds,
    summary,
    with_stop,
    without_stop,
)
from ftsweep.inputs.controllers import DIALECT_INTERPOLATION, Controller
from ftsweep.inputs.programs.gcode import IsoReader
from ftsweep.inputs.programs.moves import DialectError, Moves
from ftsweep.inputs.programs.pmac import read_pmac

# the interpolation each controller dialect commands (the catalog's table, ftsweep's text aside)
INTERPOLATION = {d: i for d, i in DIALECT_INTERPOLATION.items() if d != "text"}
# the header every ISO STS program of a Moore Nanotech starts with (metric, XZ plane,
# absolute; G52 cancels local offsets, G63/G103 the controller's tapping and look-ahead
# modes), then the work offset, the tool, M78 and M26.1 (C axis to position mode)
ISO_HEADER = ("G52 G63 G71 G103 G40 G18 G90", "G54", "T0101", "M78", "M26.1")
LINUXCNC_HEADER = ("G21 G18 G90 G40 G49 G61",)
# how far above the first and last point's Z the tool approaches and leaves [mm]
CLEARANCE_MM = 1.0


# --------------------------------------------------------------------------- writing
def _num(values: np.ndarray, decimals: int) -> list[str]:
    """Numbers with ``decimals`` digits after the point, no negative zero."""
    rounded = np.round(np.asarray(values, dtype=np.float64), decimals) + 0.0
    return [f"{v:.{decimals}f}" for v in rounded.tolist()]


def comment(dialect: str, text: str) -> str:
    """A whole-line comment of ``dialect``, refused if its text would end or open one early."""
    if "(" in text or ")" in text or ";" in text:
        raise DialectError(f"a comment cannot hold '(', ')' or ';': {text[:80]!r}")
    return f"; {text}" if dialect.startswith("pmac") else f"({text})"


def comment_text(dialect: str, line: str) -> Optional[str]:
    """The text of a whole-line comment of ``dialect`` (None if the line is not one)."""
    if dialect.startswith("pmac"):
        return line[2:] if line.startswith("; ") else None
    return line[1:-1] if line.startswith("(") and line.endswith(")") and line.count(")") == 1 else None


def render(moves: Moves, dialect: str, comments: list[str], ctrl: Any) -> list[str]:
    """The program's lines in ``dialect`` (its comment header first), numbers as the
    controller entry ``ctrl`` says (decimals, G93's F, C wrapped or accumulated)."""
    head = [comment(dialect, c) for c in comments]
    body = {"iso-sts": _iso, "linuxcnc": _iso, "pmac-pvt": _pvt, "pmac-spline": _spline}[dialect]
    return head + body(moves, dialect, ctrl)


def wrapped(c_deg: np.ndarray, decimals: int) -> np.ndarray:
    """C printed modulo 360 (a value that rounds to 360 prints as 0)."""
    c = np.mod(np.round(np.asarray(c_deg, dtype=np.float64), decimals), 360.0)
    return np.where(np.round(c, decimals) >= 360.0, 0.0, c)


def _iso(m: Moves, dialect: str, ctrl: Any) -> list[str]:
    d, g93_f = ctrl.decimals, ctrl.g93_f
    c = m.c_deg if dialect == "linuxcnc" or ctrl.c_wrap == "cumulative" else wrapped(m.c_deg, d)
    cs, xs, zs = _num(c, d), _num(m.x_mm, d), _num(m.z_mm, d)
    ys = _num(m.y_mm, d) if m.y_mm is not None else None
    ws = _num(m.w_mm, d) if m.w_mm is not None else None
    minutes = np.asarray(m.seconds) / 60.0
    with np.errstate(invalid="ignore"):  # a layered program's approach moves have no block time
        f_values = 1.0 / minutes if g93_f == "inverse_minutes" else np.asarray(m.seconds)
    fs = [f"{v:.6f}" for v in f_values.tolist()]
    ends = np.array([[lo, hi - 1] for lo, hi in m.cuts()]).ravel()
    lift = dict(zip(ends.tolist(), _num(m.z_mm[ends] + CLEARANCE_MM, d), strict=True))
    out = list(ISO_HEADER if dialect == "iso-sts" else LINUXCNC_HEADER)
    for lo, hi in m.cuts():
        # a layered program's cut: Z (the slide) holds its layer's offset, W (the servo) cuts
        first_y = f" Y{ys[lo]}" if ys is not None else ""
        first_w = f" W{ws[lo]}" if ws is not None else ""
        out += [
            f"G94 G01 Z{lift[lo]} F100.0",
            f"G01 X{xs[lo]}{first_y} C{cs[lo]}{first_w} F100.0",
            f"G01 Z{zs[lo]} F10.0",
            "G93",
        ]
        for k in range(lo + 1, hi):
            y = f" Y{ys[k]}" if ys is not None else ""
            axes = f"X{xs[k]}{y} W{ws[k]}" if ws is not None else f"X{xs[k]}{y} Z{zs[k]}"
            out.append(f"G01 C{cs[k]} {axes} F{fs[k - 1]}")
        out += ["G94", f"G01 Z{lift[hi - 1]} F100.0"]
    out += ["M29", "M30"] if dialect == "iso-sts" else ["M2"]
    return out


def _one_cut(m: Moves, dialect: str) -> None:
    if m.cut_starts is not None or m.w_mm is not None:
        raise DialectError(
            f"a layered program (cuts of the servo W at the slide's offsets, [3]) is written in G-code "
            f"(iso-sts, linuxcnc), not {dialect}"
        )


def _axes(m: Moves) -> dict[str, np.ndarray]:
    """The axes a program commands, in block order (Y only for a four-axis program)."""
    out = {"C": m.c_deg, "X": m.x_mm}
    if m.y_mm is not None:
        out["Y"] = m.y_mm
    out["Z"] = m.z_mm
    return out


def _pmac_head(m: Moves, d: int) -> list[str]:
    lift = _num(np.array([m.z_mm[0] + CLEARANCE_MM]), d)[0]
    start = " ".join(f"{a}{_num(v[:1], d)[0]}" for a, v in _axes(m).items() if a != "Z")
    return ["CLOSE", "OPEN PROG 1 CLEAR", "ABS", "RAPID", f"Z{lift}", start, f"Z{_num(m.z_mm[:1], d)[0]}"]


def _retract(m: Moves, d: int) -> list[str]:
    """Leaving the part after a PMAC cut: RAPID, Z up by the clearance."""
    return ["RAPID", f"Z{_num(np.array([m.z_mm[-1] + CLEARANCE_MM]), d)[0]}"]


def _pvt(m: Moves, dialect: str, ctrl: Any) -> list[str]:
    _one_cut(m, dialect)
    assert m.velocity is not None
    d = ctrl.decimals
    pos = {a: _num(v, d) for a, v in _axes(m).items()}
    v = {a: _num(m.velocity[a], d) for a in pos}
    out = _pmac_head(m, d)
    last = ""
    for k in range(1, m.n_points):
        ms = f"{m.seconds[k - 1] * 1e3:.5f}"  # 0.01 µs: whole 0.25 µs steps print exactly
        if ms != last:
            out.append(f"PVT{ms}")
            last = ms
        out.append(" ".join(f"{a}{pos[a][k]}:{v[a][k]}" for a in pos))
    return out + _retract(m, d) + ["CLOSE"]


def _spline(m: Moves, dialect: str, ctrl: Any) -> list[str]:
    _one_cut(m, dialect)
    d = ctrl.decimals
    pos = {a: _num(v, d) for a, v in _axes(m).items()}
    out = _pmac_head(m, d)
    ta = f"{float(m.seconds[0]) * 1e3:.5f}".rstrip("0").rstrip(".")  # ms on whole 1/4 µs steps
    out.append(f"spline{ta}" if ctrl.pmac_syntax == "power" else f"SPLINE1 {ctrl.pmac_timer}{ta}")
    out += [" ".join(f"{a}{pos[a][k]}" for a in pos) for k in range(1, m.n_points)]
    return out + _retract(m, d) + ["CLOSE"]


# --------------------------------------------------------------------------- reading
def detect(lines: list[str]) -> str:
    """The dialect of a program's lines: PMAC if it holds PVT or SPLINE1 blocks, else G-code
    (LinuxCNC if it ends with M2 and has no ISO STS header, else ISO STS)."""
    upper = [ln.strip().upper() for ln in lines]
    if any(u.startswith(("PVT", "SPLINE1")) for u in upper):
        return "pmac-spline" if any(u.startswith("SPLINE1") for u in upper) else "pmac-pvt"
    if any(u.startswith(("G21",)) for u in upper) and not any("G71" in u for u in upper):
        return "linuxcnc"
    return "iso-sts"


def read(lines: list[str], dialect: str, ctrl: Any = None, preamble: int = 0) -> Moves:
    """The moves a program's lines command, read as the controller of profile ``ctrl``
    (:class:`ftsweep.inputs.controllers.Controller`, or its recorded dict; None: the dialect's
    defaults) reads ``dialect`` (:func:`detect`); :class:`DialectError` names the first line
    it cannot evaluate, as the file's physical line. The first ``preamble`` lines are a
    template's, read before the program's own (refusals name them as preamble lines)."""
    if ctrl is None:
        ctrl = Controller(dialect=dialect, interpolation=INTERPOLATION[dialect])
    elif isinstance(ctrl, dict):
        ctrl = Controller.model_validate(
            {**ctrl, "dialect": dialect, "interpolation": INTERPOLATION[dialect]}
        )
    if dialect.startswith("pmac"):
        return read_pmac(lines, dialect, ctrl, preamble)
    return IsoReader(lines, dialect, ctrl, preamble).run()


__all__ = [
    "Adapter",
    "DialectError",
    "Moves",
    "aligned",
    "stop_seconds",
    "with_stop",
    "without_stop",
    "summary",
    "render",
    "read",
    "detect",
    "wrapped",
    "comment",
    "comment_text",
]


def check_limits(moves: Moves, ctrl: Controller) -> None:
    """Refuse, naming the limit, a program the controller cannot run (its blocks, C's soft
    limit where C accumulates, and the segment times it runs: :meth:`Controller.segment_refusal`)."""
    from ftsweep.exports.files import ProgramError

    blocks = moves.n_points - 1
    if blocks > ctrl.max_blocks:
        raise ProgramError(
            f"the program has {blocks:,} blocks, more than the controller's {ctrl.max_blocks:,}"
        )
    cumulative = ctrl.c_wrap == "cumulative" or ctrl.dialect == "linuxcnc"
    turned = float(np.max(np.abs(moves.c_deg)))
    if cumulative and ctrl.c_limit_deg is not None and turned > ctrl.c_limit_deg:
        raise ProgramError(
            f"C reaches {turned:,.0f}° accumulated, past the controller's soft limit of "
            f"{ctrl.c_limit_deg:,.0f}° (machine.controller.c_limit_deg): raise the limit or make C a "
            "wrapped rotary"
        )
    why = ctrl.segment_refusal(moves.seconds)
    if why:
        raise ProgramError(why)


def machines_reading(dialect: str) -> list[str]:
    """The catalog's machines whose controller reads ``dialect``, by name."""
    from ftsweep.inputs import catalogs

    machines = catalogs.entries("machines").items()
    return sorted(m for m, e in machines if e.controller is not None and e.controller.dialect == dialect)
