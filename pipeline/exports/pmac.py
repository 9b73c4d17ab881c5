"""Delta Tau PMAC motion programs (PVT and SPLINE1) read as the controller its machine's
profile describes reads them (docs/controllers.md): Turbo PMAC's syntax (``PVT<ms>``,
``SPLINE1`` with ``TA<ms>``) or Power PMAC's (``pvt<ms>``, ``spline<ms>``), words with or
without spaces, integer or decimal numbers, ABS and INC, TA/TS/TM; PVT velocities in units
per Ix90 ms, segment times by I42."""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from ftsweep.exports.moves import DialectError, Moves

_NUM = r"-?(?:\d+\.?\d*|\.\d+)"
# a cut block giving all three axes (with their velocities in PVT): read without the tokenizer
_PMAC_PLAIN = re.compile(
    r"^C(-?\d+\.\d+)(?::(-?\d+\.\d+))? X(-?\d+\.\d+)(?::(-?\d+\.\d+))? Z(-?\d+\.\d+)(?::(-?\d+\.\d+))?$"
)
# one statement of a line whose spaces are removed: a mode, a time, or an axis word
_STATEMENT = re.compile(
    rf"(SPLINE({_NUM})|PVT({_NUM})|T([AMS])({_NUM})|ABS|INC|RAPID|LINEAR|([A-Z])({_NUM})(?::({_NUM}))?)"
)
_WHOLE_LINE = re.compile(r"^(OPEN\s+PROG\s*\d+(\s+CLEAR)?|CLOSE|CLEAR|END\s+GATHER|DWELL\s*0)$")
AXES = "CXYZ"


def read_pmac(lines: list[str], dialect: str, ctrl: Any) -> Moves:
    """A PMAC motion program: moves to the start (RAPID or LINEAR), then PVT moves (each
    ``AXISpos:vel``, ``PVT<ms>`` setting the segment time) or SPLINE1 moves at one TA [ms]."""
    reader = _PmacReader(dialect, ctrl)
    for n, line in enumerate(lines):
        reader.line(n, line)
    return reader.moves()


class _PmacReader:
    """The state of a PMAC program read line by line (:func:`read_pmac`)."""

    def __init__(self, dialect: str, ctrl: Any) -> None:
        self.dialect, self.ctrl = dialect, ctrl
        self.comments: list[str] = []
        self.pos: dict[str, float] = {a: math.nan for a in AXES}
        self.mode, self.seconds, self.ta_s = "", math.nan, math.nan
        self.absolute = True
        self.ended = False
        self.cut_mode = ""
        self.points: list[dict[str, float]] = []
        self.vel: list[dict[str, float]] = []
        self.times: list[float] = []
        # velocities in a file's units per Ix90 ms, made per second
        self.per_second = 1000.0 / float(ctrl.ix90_ms)

    def fail(self, n: int, line: str, why: str) -> DialectError:
        return DialectError(f"line {n + 1} ({line.strip()[:60]!r}): {why}")

    def line(self, n: int, line: str) -> None:
        fast = (
            _PMAC_PLAIN.match(line)
            if self.points and self.absolute and self.mode in ("PVT", "SPLINE1")
            else None
        )
        speeds = (fast.group(2), fast.group(4), fast.group(6)) if fast else ()
        if fast and all((v is None) == (self.mode == "SPLINE1") for v in speeds):
            self._plain(fast)
            return
        if line.startswith("; "):
            self.comments.append(line[2:])
        text = line.split(";", 1)[0].split("//", 1)[0].strip().upper()
        if not text or _WHOLE_LINE.match(text):
            return
        squeezed, at = re.sub(r"\s+", "", text), 0
        move: dict[str, float] = {}
        speeds_: dict[str, float] = {}
        for m in _STATEMENT.finditer(squeezed):
            if m.start() != at:
                raise self.fail(n, line, f"cannot read {squeezed[at : m.start()][:20]!r}")
            at = m.end()
            if m.group(6):
                self._word(n, line, m, move, speeds_)
            else:
                self._statement(n, line, m)
        if at != len(squeezed):
            raise self.fail(n, line, f"cannot read {squeezed[at:][:20]!r}")
        if move:
            self._move(n, line, move, speeds_)

    def _word(
        self, n: int, line: str, m: re.Match[str], move: dict[str, float], speeds: dict[str, float]
    ) -> None:
        axis = m.group(6)
        if axis not in AXES:
            raise self.fail(n, line, f"the axis {axis} is not one of a path program's (C, X, Y, Z)")
        move[axis] = float(m.group(7))
        if m.group(8) is not None:
            speeds[axis] = float(m.group(8)) * self.per_second

    def _statement(self, n: int, line: str, m: re.Match[str]) -> None:
        word, power = m.group(1), self.ctrl.pmac_syntax == "power"
        if word in ("ABS", "INC"):
            self.absolute = word == "ABS"
        elif word in ("RAPID", "LINEAR"):
            self.ended = bool(self.points)  # after the cut: the retract, never cut
            self.mode = word
        elif m.group(3) is not None:
            self.mode = "PVT"
            self.seconds = self._time(n, line, m.group(3), "PVT")
        elif m.group(2) is not None:
            # Turbo PMAC: SPLINE1 the mode, TA its time; Power PMAC: spline<ms>, the time in it
            if not power and m.group(2) != "1":
                raise self.fail(n, line, "a Turbo PMAC profile writes SPLINE1 with TA<ms>")
            self.mode = "SPLINE1"
            if power:
                self.ta_s = self._time(n, line, m.group(2), "spline")
        elif m.group(4) == "A":
            self.ta_s = self._time(n, line, m.group(5), "TA")
        # TS (S-curve time) and TM (move time) shape LINEAR moves only: the cut's segments
        # are PVT's or SPLINE1's, timed by PVT and TA

    def _time(self, n: int, line: str, ms: str, what: str) -> float:
        value = float(ms)
        if self.ctrl.i42 == 1 and value != round(value):
            raise self.fail(n, line, f"{what} time {ms} ms: this controller takes whole ms (I42=1)")
        if not 0.0 < value <= 4095.9998 + 1e-9:
            raise self.fail(n, line, f"a segment time of {ms} ms is outside (0, 4095.9998]")
        return value * 1e-3

    def _plain(self, m: re.Match[str]) -> None:
        """A cut block of :data:`_PMAC_PLAIN`'s form: what :meth:`_move` makes of it."""
        self.pos = {**self.pos, "C": float(m.group(1)), "X": float(m.group(3)), "Z": float(m.group(5))}
        self.points.append(self.pos)
        if self.mode == "PVT":
            k = self.per_second
            v = {"C": float(m.group(2)) * k, "X": float(m.group(4)) * k, "Z": float(m.group(6)) * k}
            self.vel.append({**self.vel[-1], **v})
        self.times.append(self.seconds if self.mode == "PVT" else self.ta_s)

    def _move(self, n: int, line: str, move: dict[str, float], speeds: dict[str, float]) -> None:
        target = move if self.absolute else {a: self.pos[a] + v for a, v in move.items()}
        if self.ended and self.mode in ("PVT", "SPLINE1"):
            raise self.fail(n, line, "a second cut after RAPID or LINEAR: the reader takes one cut")
        if self.mode in ("RAPID", "LINEAR", ""):
            if speeds or not self.mode:
                raise self.fail(
                    n,
                    line,
                    "a move before PVT or SPLINE1 that is not RAPID or LINEAR, or a velocity outside PVT",
                )
            self.pos = {**self.pos, **target}  # a new dict: the cut's last point keeps its own
            return
        if self.mode == "SPLINE1" and not self.ta_s > 0:
            raise self.fail(n, line, "a SPLINE1 move before its segment time TA is set")
        if not self.points:
            self.cut_mode = self.mode
            self.points.append(dict(self.pos))
            self.vel.append({a: 0.0 for a in AXES})  # a RAPID ends at rest
        self.pos.update(target)
        self.points.append(dict(self.pos))
        if self.mode == "PVT":
            if set(speeds) != set(move):
                raise self.fail(n, line, "every PVT axis word needs its velocity (pos:vel)")
            self.vel.append({**self.vel[-1], **speeds})
        self.times.append(self.seconds if self.mode == "PVT" else self.ta_s)

    def moves(self) -> Moves:
        if not self.points:
            raise DialectError("no PVT or SPLINE1 move: nothing to predict")
        cols = {a: np.array([p[a] for p in self.points]) for a in AXES}
        # Y is a four-axis program's: given at the start or never
        axes = "CXYZ" if np.isfinite(cols["Y"][0]) else "CXZ"
        for axis in AXES:
            if axis in axes and not np.all(np.isfinite(cols[axis])):
                raise DialectError(f"the cut starts before {axis} is given a position")
            if axis not in axes and np.any(np.isfinite(cols[axis])):
                raise DialectError(f"{axis} is given during the cut but not at its start")
        velocity = None
        interp = "spline1" if self.cut_mode == "SPLINE1" else "pvt"
        if interp == "pvt":
            velocity = {a: np.array([v[a] for v in self.vel]) for a in axes}
        times = np.array(self.times)
        y = cols["Y"] if "Y" in axes else None
        # a PVT cut that ends at rest: its last segment is the stop after its path
        stopped = (
            velocity is not None and len(self.points) > 2 and all(v[-1] == 0.0 for v in velocity.values())
        )
        return Moves(
            cols["C"],
            cols["X"],
            cols["Z"],
            times,
            y,
            velocity,
            interp,
            self.dialect,
            self.comments,
            stopped=stopped,
        )
