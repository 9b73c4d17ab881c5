"""Delta Tau PMAC motion programs (PVT and SPLINE1) read as the controller reads them
(docs/controllers.md)."""

from __future__ import annotations

import math
import re

import numpy as np

from ftsweep.exports.moves import DialectError, Moves

# a cut block giving all three axes (with their velocities in PVT): read without the tokenizer
_PMAC_PLAIN = re.compile(
    r"^C(-?\d+\.\d+)(?::(-?\d+\.\d+))? X(-?\d+\.\d+)(?::(-?\d+\.\d+))? Z(-?\d+\.\d+)(?::(-?\d+\.\d+))?$"
)
_PMAC_MOVE = re.compile(r"^([CXYZ])(-?\d+\.\d+)(?::(-?\d+\.\d+))?$")


def read_pmac(lines: list[str], dialect: str) -> Moves:
    """A PMAC motion program: RAPID to the start, then PVT moves (each ``AXISpos:vel``,
    ``PVTms`` setting the segment time) or SPLINE1 moves at one TA [ms]."""
    reader = _PmacReader(dialect)
    for n, line in enumerate(lines):
        reader.line(n, line)
    return reader.moves()


class _PmacReader:
    """The state of a PMAC program read line by line (:func:`read_pmac`)."""

    def __init__(self, dialect: str) -> None:
        self.dialect = dialect
        self.comments: list[str] = []
        self.pos: dict[str, float] = {"C": math.nan, "X": math.nan, "Y": math.nan, "Z": math.nan}
        self.mode, self.seconds = "", math.nan
        self.points: list[dict[str, float]] = []
        self.vel: list[dict[str, float]] = []
        self.times: list[float] = []

    def line(self, n: int, line: str) -> None:
        fast = _PMAC_PLAIN.match(line) if self.points and self.mode in ("PVT", "SPLINE1") else None
        speeds = (fast.group(2), fast.group(4), fast.group(6)) if fast else ()
        if fast and all((v is None) == (self.mode == "SPLINE1") for v in speeds):
            self._plain(fast)
            return
        text = line.split(";", 1)[0].strip().upper()
        if line.startswith("; "):
            self.comments.append(line[2:])
        if not text or text in ("CLOSE", "ABS", "OPEN PROG 1 CLEAR"):
            return
        if text in ("RAPID", "LINEAR"):
            if self.points:
                raise DialectError(f"line {n + 1}: {text} after the cut: the reader takes one cut")
            self.mode = text
            return
        found = re.fullmatch(r"PVT(\d+(?:\.\d+)?)", text) or re.fullmatch(r"SPLINE1\s*TA(\d+)", text)
        if found:
            self._segment_time(n, text, found.group(1))
            return
        self._move(n, line, text)

    def _plain(self, m: re.Match[str]) -> None:
        """A cut block of :data:`_PMAC_PLAIN`'s form: what :meth:`_move` makes of it."""
        self.pos = {**self.pos, "C": float(m.group(1)), "X": float(m.group(3)), "Z": float(m.group(5))}
        self.points.append(self.pos)
        if self.mode == "PVT":
            self.vel.append(
                {**self.vel[-1], "C": float(m.group(2)), "X": float(m.group(4)), "Z": float(m.group(6))}
            )
        self.times.append(self.seconds)

    def _segment_time(self, n: int, text: str, ms: str) -> None:
        self.mode = "PVT" if text.startswith("PVT") else "SPLINE1"
        self.seconds = float(ms) * 1e-3
        if not 0.0 < self.seconds <= 4.0959998 + 1e-12:
            raise DialectError(f"line {n + 1}: a segment time of {ms} ms is outside (0, 4095.9998]")

    def _move(self, n: int, line: str, text: str) -> None:
        words = text.split()
        parsed = [_PMAC_MOVE.match(w) for w in words]
        if not words or not all(parsed):
            raise DialectError(f"line {n + 1} ({line.strip()[:60]!r}): not a block the reader evaluates")
        move = {m.group(1): float(m.group(2)) for m in parsed if m}
        speeds = {m.group(1): float(m.group(3)) for m in parsed if m and m.group(3) is not None}
        if self.mode in ("RAPID", "LINEAR", ""):
            if speeds or not self.mode:
                raise DialectError(f"line {n + 1}: a move before PVT or SPLINE1, or a velocity outside PVT")
            self.pos.update(move)
            return
        if not self.points:
            self.points.append(dict(self.pos))
            self.vel.append({"C": 0.0, "X": 0.0, "Y": 0.0, "Z": 0.0})  # a RAPID ends at rest
        self.pos.update(move)
        self.points.append(dict(self.pos))
        if self.mode == "PVT":
            if set(speeds) != set(move):
                raise DialectError(f"line {n + 1}: every PVT axis word needs its velocity (pos:vel)")
            self.vel.append({**self.vel[-1], **speeds})
        self.times.append(self.seconds)

    def moves(self) -> Moves:
        if not self.points:
            raise DialectError("no PVT or SPLINE1 move: nothing to predict")
        cols = {a: np.array([p[a] for p in self.points]) for a in "CXYZ"}
        # Y is a four-axis program's: given at the start or never
        axes = "CXYZ" if np.isfinite(cols["Y"][0]) else "CXZ"
        for axis in "CXYZ":
            if axis in axes and not np.all(np.isfinite(cols[axis])):
                raise DialectError(f"the cut starts before {axis} is given a position")
            if axis not in axes and np.any(np.isfinite(cols[axis])):
                raise DialectError(f"{axis} is given during the cut but not at its start")
        velocity = None
        interp = "spline1" if self.mode == "SPLINE1" else "pvt"
        if interp == "pvt":
            velocity = {a: np.array([v[a] for v in self.vel]) for a in axes}
        times = np.array(self.times)
        y = cols["Y"] if "Y" in axes else None
        return Moves(cols["C"], cols["X"], cols["Z"], times, y, velocity, interp, self.dialect, self.comments)
