"""Delta Tau PMAC motion programs (PVT and SPLINE1) read as the controller its machine's
profile describes reads them (docs/controllers.md): Turbo PMAC's syntax (``PVT<ms>``,
``SPLINE1`` timed by TM or TA) or Power PMAC's (``pvt<ms>``, ``spline<ms>``), words with or
without spaces, integer or decimal numbers, ABS and INC, TA/TS/TM; PVT velocities in units
per Isx90 ms (Ix90 on PMAC/PMAC2, ``Coord[x].FeedTime`` on Power PMAC).

Segment times follow the Turbo PMAC Software Reference's I42 entry: I42 = 0 makes TM, I42 = 1
makes TA the time of SPLINE and PVT moves, ``PVT<ms>`` sets it in either mode; the time is in
ms, from 0 to 4,095.9998 ms at a resolution of 1/4 µs in both modes. The other of TM and TA
inside SPLINE or PVT mode is refused naming I42. C written modulo 360 needs a C motor that
rolls over (Ixx27, the profile's ``c_wrap: revolution``: an ABS move takes the shorter way
round); without rollover a jump of C by most of a revolution is refused naming Ixx27."""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from ftsweep.inputs.programs.moves import DialectError, Moves, line_label, physical_line

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
# the Turbo PMAC's longest segment time and its resolution (Software Reference, I42) [ms]
MAX_SEGMENT_MS = 4095.9998
TIME_STEP_MS = 0.00025
# a PMAC's servo cycle at its factory settings (I10 = 3,713,707: 442.11 µs) [s], where the
# profile declares none: no segment is shorter than one servo cycle
DEFAULT_SERVO_S = 442.11e-6


def read_pmac(lines: list[str], dialect: str, ctrl: Any, preamble: int = 0) -> Moves:
    """A PMAC motion program: moves to the start (RAPID or LINEAR), then PVT moves (each
    ``AXISpos:vel``, ``PVT<ms>`` or the I42-selected TM/TA setting the segment time) or
    SPLINE1 moves at one time [ms]. The first ``preamble`` lines are a template's."""
    reader = _PmacReader(dialect, ctrl, preamble)
    for n, line in enumerate(lines):
        reader.line(n, line)
    return reader.moves()


class _PmacReader:
    """The state of a PMAC program read line by line (:func:`read_pmac`)."""

    def __init__(self, dialect: str, ctrl: Any, preamble: int = 0) -> None:
        self.dialect, self.ctrl, self.preamble = dialect, ctrl, preamble
        self.lines: list[int] = []  # each point's physical line (a preamble's negative)
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

    def line_no(self, n: int) -> int:
        return physical_line(n, self.preamble)

    def fail(self, n: int, line: str, why: str) -> DialectError:
        return DialectError(f"{line_label(self.line_no(n))} ({line.strip()[:60]!r}): {why}")

    def line(self, n: int, line: str) -> None:
        fast = (
            _PMAC_PLAIN.match(line)
            if self.points and self.absolute and self.mode in ("PVT", "SPLINE1")
            else None
        )
        speeds = (fast.group(2), fast.group(4), fast.group(6)) if fast else ()
        if fast and all((v is None) == (self.mode == "SPLINE1") for v in speeds):
            self._plain(n, line, fast)
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
        move[axis] = self._finite(n, line, m.group(7), f"{axis} position")
        if m.group(8) is not None:
            speeds[axis] = self._finite(n, line, m.group(8), f"{axis} velocity") * self.per_second

    def _finite(self, n: int, line: str, text: str, what: str) -> float:
        value = float(text)
        if not math.isfinite(value):
            raise self.fail(n, line, f"the {what} {text[:24]}… is not a finite number")
        return value

    def _statement(self, n: int, line: str, m: re.Match[str]) -> None:
        word, power = m.group(1), self.ctrl.pmac_syntax == "power"
        if word in ("ABS", "INC"):
            self.absolute = word == "ABS"
        elif word in ("RAPID", "LINEAR"):
            self.ended = bool(self.points)  # after the cut: the retract, never cut
            self.mode = word
        elif m.group(3) is not None:  # PVT<ms> sets the time whatever I42 says
            self.mode = "PVT"
            self.seconds = self.ta_s = self._time(n, line, m.group(3), "PVT")
        elif m.group(2) is not None:
            # Turbo PMAC: SPLINE1 the mode, its time TM or TA by I42; Power PMAC: spline<ms>
            if not power and m.group(2) != "1":
                raise self.fail(
                    n,
                    line,
                    f"a Turbo PMAC's uniform spline is SPLINE1, timed by {self.ctrl.pmac_timer} "
                    f"(I42={self.ctrl.i42})",
                )
            self.mode = "SPLINE1"
            if power:
                self.ta_s = self._time(n, line, m.group(2), "spline")
        elif m.group(4) in ("A", "M"):
            self._timer_word(n, line, "T" + m.group(4), m.group(5))
        # TS (S-curve time) shapes LINEAR moves only

    def _timer_word(self, n: int, line: str, word: str, ms: str) -> None:
        """TM or TA: the I42-selected one sets the SPLINE and PVT move time; the other, inside
        SPLINE or PVT mode, is refused naming I42 (outside, it shapes LINEAR moves only)."""
        if word == self.ctrl.pmac_timer:
            self.ta_s = self._time(n, line, ms, word)
            if self.mode == "PVT":
                self.seconds = self.ta_s
        elif self.mode in ("PVT", "SPLINE1"):
            raise self.fail(
                n,
                line,
                f"{word}{ms} in {self.mode} mode: under I42={self.ctrl.i42} the SPLINE and PVT move time "
                f"is {self.ctrl.pmac_timer} (the Turbo PMAC Software Reference's I42 entry: 0 selects TM, "
                "1 TA); see machine.controller.i42",
            )

    def _time(self, n: int, line: str, ms: str, what: str) -> float:
        """A segment time [s] from its word [ms], on the controller's 1/4 µs steps; refused
        outside (one servo cycle, 4,095.9998 ms]."""
        value = round(self._finite(n, line, ms, f"{what} time") / TIME_STEP_MS) * TIME_STEP_MS
        servo_ms = (self.ctrl.servo_period_s or DEFAULT_SERVO_S) * 1e3
        if not servo_ms * (1.0 - 1e-9) <= value <= MAX_SEGMENT_MS + 1e-9:
            declared = (
                ""
                if self.ctrl.servo_period_s
                else " (a PMAC's factory servo cycle; the profile declares none)"
            )
            raise self.fail(
                n,
                line,
                f"a segment time {what}{ms[:24]} ms is outside the controller's ({servo_ms:g} ms servo "
                f"cycle{declared}, {MAX_SEGMENT_MS} ms]",
            )
        return value * 1e-3

    def _plain(self, n: int, line: str, m: re.Match[str]) -> None:
        """A cut block of :data:`_PMAC_PLAIN`'s form: what :meth:`_move` makes of it."""
        self.pos = {**self.pos, "C": float(m.group(1)), "X": float(m.group(3)), "Z": float(m.group(5))}
        self.points.append(self.pos)
        self.lines.append(self.line_no(n))
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
            self.lines.append(self.line_no(n))
            self.vel.append({a: 0.0 for a in AXES})  # a RAPID ends at rest
        self.pos.update(target)
        self.points.append(dict(self.pos))
        self.lines.append(self.line_no(n))
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
        self._all_finite(cols, axes)
        cols["C"] = self._rolled_over(cols["C"])
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
            point_lines=np.array(self.lines, dtype=np.int64),
        )

    def _all_finite(self, cols: dict[str, np.ndarray], axes: str) -> None:
        """Every position and velocity a finite number (a 400-digit word is not), by line."""
        for name, values in [*cols.items(), *((f"{a} velocity", [v[a] for v in self.vel]) for a in axes)]:
            bad = np.flatnonzero(~np.isfinite(np.asarray(values, dtype=np.float64)))
            if name in axes or name.endswith("velocity"):
                if bad.size:
                    raise DialectError(
                        f"{line_label(self.lines[int(bad[0])])}: the {name} is not a finite number"
                    )

    def _rolled_over(self, c: np.ndarray) -> np.ndarray:
        """C as the motor turns: with rollover (Ixx27 one revolution, the profile's ``c_wrap:
        revolution``) every move the shorter way round; without, as written, a step of more
        than half a revolution refused naming Ixx27 (a program written modulo 360)."""
        step = np.diff(c)
        if self.ctrl.c_wrap == "revolution":
            step = np.mod(step, 360.0)
            return np.concatenate([c[:1], c[0] + np.cumsum(np.where(step > 180.0, step - 360.0, step))])
        # C as written; a step back by more than half a revolution against the way the spindle
        # turns is a program written modulo 360 (its C drops from near 360 to near 0)
        turning = np.sign(np.median(step)) if step.size else 0.0
        jumps = np.flatnonzero((np.abs(step) > 180.0) & (np.sign(step) == -turning))
        if jumps.size:
            k = int(jumps[0]) + 1
            raise DialectError(
                f"{line_label(self.lines[k])}: C goes from {c[k - 1]:g} to {c[k]:g}, turning the spindle "
                f"{step[k - 1]:+g} deg in one segment: the program is written modulo 360, and this C motor "
                "does not roll over (Ixx27 = 0, the profile's c_wrap: cumulative); set machine.controller."
                "c_wrap: revolution for a C motor whose Ixx27 is one revolution"
            )
        return c
