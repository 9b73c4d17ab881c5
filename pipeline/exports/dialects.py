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

import math
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from typing import Any, Optional

import numpy as np

from ftsweep.store.io import ExportError

DIALECTS = ("text", "iso-sts", "linuxcnc", "pmac-pvt", "pmac-spline")
INTERPOLATION = {"iso-sts": "linear", "linuxcnc": "linear", "pmac-pvt": "pvt", "pmac-spline": "spline1"}
# blocks a program may hold when read: a WHILE loop cannot make the reader run away
MAX_READ_BLOCKS = 50_000_000
# the header every ISO STS program of a Moore Nanotech starts with (metric, XZ plane,
# absolute; G52 cancels local offsets, G63/G103 the controller's tapping and look-ahead
# modes), then the work offset, the tool, M78 and M26.1 (C axis to position mode)
ISO_HEADER = ("G52 G63 G71 G103 G40 G18 G90", "G54", "T0101", "M78", "M26.1")
LINUXCNC_HEADER = ("G21 G18 G90 G40 G49 G61",)
# how far above the first and last point's Z the tool approaches and leaves [mm]
CLEARANCE_MM = 1.0


class DialectError(ExportError):
    """A program cannot be read or written in its dialect; the message names the line."""


@dataclass
class Moves:
    """What a path program commands (units in the names; ``seconds`` per segment)."""

    c_deg: np.ndarray
    x_mm: np.ndarray
    z_mm: np.ndarray
    seconds: np.ndarray
    y_mm: Optional[np.ndarray] = None
    velocity: Optional[dict[str, np.ndarray]] = None  # PVT: per axis [deg/s or mm/s]
    interpolation: str = "linear"
    dialect: str = "text"
    comments: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # what the reader passed over (M codes, approach)

    @property
    def n_points(self) -> int:
        return int(self.c_deg.size)


@dataclass(frozen=True)
class Adapter:
    """How a path kind's programs go into controllers' dialects and come back (each kind
    declares its own beside its file format; :mod:`ftsweep.exports.nc` is the generic part).

    planned : ``(case, specs) -> (moves, lines)``: the program its case plans, as moves, and
        the kind's comment-header lines (tool, spindle, points per revolution …).
    simulate : ``(case, specs, moves, progress) -> record``: the one simulator on the case
        with its program as ``moves`` command it.
    check : ``(case, specs, moves) -> reason``: the machine limits the moves leave ('' none).
    commands : ``(moves, per) -> values``: the commands [µm] the simulator forms at ``per``
        parameters u = (j + 0.5)/per of every segment (the compiled reference's check); None:
        the kind's segments are not checked against the reference.
    stand_in : ``(surface, machine, cutting) -> case``: the case a program from elsewhere is
        simulated as (None: only ftsweep's own programs of this kind are read).
    """

    planned: Callable[..., tuple[Moves, list[str]]]
    simulate: Callable[..., dict[str, Any]]
    check: Callable[..., str]
    commands: Optional[Callable[[Moves, int], np.ndarray]] = None
    stand_in: Optional[Callable[[str, str, str], Any]] = None


# --------------------------------------------------------------------------- writing
def _num(values: np.ndarray, decimals: int) -> list[str]:
    """Numbers with ``decimals`` digits after the point, no negative zero."""
    rounded = np.round(np.asarray(values, dtype=np.float64), decimals) + 0.0
    return [f"{v:.{decimals}f}" for v in rounded.tolist()]


def _comment(dialect: str, text: str) -> str:
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
    head = [_comment(dialect, c) for c in comments]
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
    minutes = np.asarray(m.seconds) / 60.0
    f_values = 1.0 / minutes if g93_f == "inverse_minutes" else np.asarray(m.seconds)
    fs = [f"{v:.6f}" for v in f_values.tolist()]
    first_y = f" Y{ys[0]}" if ys is not None else ""
    out = list(ISO_HEADER if dialect == "iso-sts" else LINUXCNC_HEADER)
    lift = _num(np.array([m.z_mm[0] + CLEARANCE_MM, m.z_mm[-1] + CLEARANCE_MM]), d)
    out += [
        f"G94 G01 Z{lift[0]} F100.0",
        f"G01 X{xs[0]}{first_y} C{cs[0]} F100.0",
        f"G01 Z{zs[0]} F10.0",
        "G93",
    ]
    for k in range(1, len(cs)):
        y = f" Y{ys[k]}" if ys is not None else ""
        out.append(f"G01 C{cs[k]} X{xs[k]}{y} Z{zs[k]} F{fs[k - 1]}")
    out += ["G94", f"G01 Z{lift[1]} F100.0"]
    out += ["M29", "M30"] if dialect == "iso-sts" else ["M2"]
    return out


def _pmac_head(m: Moves, d: int) -> list[str]:
    lift = _num(np.array([m.z_mm[0] + CLEARANCE_MM]), d)[0]
    c0, x0, z0 = _num(m.c_deg[:1], d)[0], _num(m.x_mm[:1], d)[0], _num(m.z_mm[:1], d)[0]
    return ["CLOSE", "OPEN PROG 1 CLEAR", "ABS", "RAPID", f"Z{lift}", f"C{c0} X{x0}", f"Z{z0}"]


def _pvt(m: Moves, dialect: str, ctrl: Any) -> list[str]:
    assert m.velocity is not None
    d = ctrl.decimals
    cs, xs, zs = _num(m.c_deg, d), _num(m.x_mm, d), _num(m.z_mm, d)
    v = {axis: _num(m.velocity[axis], d) for axis in ("C", "X", "Z")}
    out = _pmac_head(m, d)
    last = ""
    for k in range(1, len(cs)):
        ms = f"{m.seconds[k - 1] * 1e3:.4f}"
        if ms != last:
            out.append(f"PVT{ms}")
            last = ms
        out.append(f"C{cs[k]}:{v['C'][k]} X{xs[k]}:{v['X'][k]} Z{zs[k]}:{v['Z'][k]}")
    return out + ["CLOSE"]


def _spline(m: Moves, dialect: str, ctrl: Any) -> list[str]:
    d = ctrl.decimals
    cs, xs, zs = _num(m.c_deg, d), _num(m.x_mm, d), _num(m.z_mm, d)
    out = _pmac_head(m, d)
    out.append(f"SPLINE1 TA{int(round(float(m.seconds[0]) * 1e3))}")
    out += [f"C{cs[k]} X{xs[k]} Z{zs[k]}" for k in range(1, len(cs))]
    return out + ["CLOSE"]


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


def read(lines: list[str], dialect: str, g93_f: str = "inverse_minutes") -> Moves:
    """The moves a program's lines command, read as the controller reads ``dialect``
    (:func:`detect`); :class:`DialectError` names the first line it cannot evaluate."""
    if dialect.startswith("pmac"):
        return _read_pmac(lines, dialect)
    return _IsoReader(lines, dialect, g93_f).run()


# a cutting block of numbers only (each with its decimal point): read without the tokenizer
_PLAIN = re.compile(
    r"^(G0?1 )?C(-?\d+\.\d*) X(-?\d+\.\d*) (?:Y(-?\d+\.\d*) )?Z(-?\d+\.\d*)(?: F(\d+\.\d*))?$"
)
_WORD = re.compile(r"([A-Z])\s*(\[[^\]]*\]|#\d+|[-+]?(?:\d+\.?\d*|\.\d+))")
_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)")
_COMMENT = re.compile(r"\([^()]*\)")
_ASSIGN = re.compile(r"^#(\d+)\s*=\s*(.+)$")
_WHILE = re.compile(r"^WHILE\s*\[(.+)\]\s*DO\s*(\d)$")
_END = re.compile(r"^END\s*(\d)$")
_CONDITION = re.compile(r"^(.+?)\s+(LT|LE|GT|GE|EQ|NE)\s+(.+)$")
# G codes the reader knows: motion, units, planes, offsets, compensation cancels, modes
KNOWN_G = {0.0, 1.0, 4.0, 17.0, 18.0, 19.0, 21.0, 40.0, 49.0, 52.0, 54.0, 55.0, 56.0, 57.0, 58.0, 59.0}
KNOWN_G |= {61.0, 63.0, 64.0, 71.0, 90.0, 93.0, 94.0, 103.0}
FLOW_M = {97.0, 98.0, 99.0}  # subprogram calls and returns: not evaluated


class _IsoReader:
    """ISO STS / RS274 G-code as a controller reads it: modal state, macro variables set to
    constants, WHILE loops (their conditions on those constants) and the G93 blocks' points."""

    def __init__(self, lines: list[str], dialect: str, g93_f: str) -> None:
        self.lines, self.dialect, self.g93_f = lines, dialect, g93_f
        self.vars: dict[int, float] = {}
        self.pos = {"C": math.nan, "X": math.nan, "Y": math.nan, "Z": math.nan}
        self.g93 = False
        self.feed = math.nan
        self.motion = 0.0
        self.out: dict[str, list[float]] = {"C": [], "X": [], "Y": [], "Z": [], "T": []}
        self.start: Optional[dict[str, float]] = None
        self.m_codes: set[str] = set()
        self.comments: list[str] = []
        self.blocks = 0

    def fail(self, n: int, why: str) -> DialectError:
        text = self.lines[n].strip()[:80] if n < len(self.lines) else ""
        return DialectError(f"line {n + 1} ({text!r}): {why}")

    def run(self) -> Moves:
        self._execute(0, len(self.lines))
        if not self.out["C"]:
            raise DialectError("no cutting block under G93 (inverse time): nothing to predict")
        return self._moves()

    def _execute(self, first: int, stop: int) -> None:
        n = first
        while n < stop:
            text = self._clean(n)
            loop = _WHILE.match(text)
            if loop:
                end = self._loop_end(n, loop.group(2), stop)
                while self._condition(n, loop.group(1)):
                    self._execute(n + 1, end)
                n = end + 1
                continue
            if _END.match(text):
                raise self.fail(n, "END without its WHILE")
            self._block(n, text)
            n += 1

    def _clean(self, n: int) -> str:
        raw = self.lines[n].strip()
        if raw.startswith("(") and raw.endswith(")") and raw.count(")") == 1:
            self.comments.append(raw[1:-1])
        if ";" in raw:
            raw = raw.split(";", 1)[0]
        if "(" in raw or ")" in raw:
            raw = _COMMENT.sub(" ", raw)
            if "(" in raw or ")" in raw:
                raise self.fail(n, "a comment's parentheses do not close on its line")
        text = raw.strip().upper()
        if text.startswith("/"):
            raise self.fail(n, "a block-delete '/' block: whether it runs depends on a switch")
        return text

    def _loop_end(self, n: int, tag: str, stop: int) -> int:
        depth = 0
        for k in range(n + 1, stop):
            text = self._clean_quiet(k)
            if _WHILE.match(text):
                depth += 1
            end = _END.match(text)
            if end:
                if depth == 0 and end.group(1) == tag:
                    return k
                depth -= 1
        raise self.fail(n, f"WHILE … DO{tag} has no END{tag}")

    def _clean_quiet(self, n: int) -> str:
        return _COMMENT.sub(" ", self.lines[n].split(";", 1)[0]).strip().upper()

    def _condition(self, n: int, text: str) -> bool:
        found = _CONDITION.match(text.strip())
        if not found:
            raise self.fail(n, "a WHILE condition must be 'a LT|LE|GT|GE|EQ|NE b'")
        a, op, b = self._expr(n, found.group(1)), found.group(2), self._expr(n, found.group(3))
        return bool({"LT": a < b, "LE": a <= b, "GT": a > b, "GE": a >= b, "EQ": a == b, "NE": a != b}[op])

    def _expr(self, n: int, text: str) -> float:
        """An arithmetic expression of numbers and set variables (+ − * /, [ ] grouping),
        evaluated by a small parser: never by Python's ``eval``."""
        tokens = re.findall(r"#\d+|\d+\.?\d*|\.\d+|[-+*/\[\]()]|\S", text)
        value, rest = self._sum(n, tokens)
        if rest:
            raise self.fail(n, f"cannot evaluate {text.strip()[:40]!r}")
        return value

    def _sum(self, n: int, t: list[str]) -> tuple[float, list[str]]:
        value, t = self._product(n, t)
        while t and t[0] in "+-":
            op, (rhs, t) = t[0], self._product(n, t[1:])
            value = value + rhs if op == "+" else value - rhs
        return value, t

    def _product(self, n: int, t: list[str]) -> tuple[float, list[str]]:
        value, t = self._atom(n, t)
        while t and t[0] in "*/":
            op, (rhs, t) = t[0], self._atom(n, t[1:])
            if op == "/" and rhs == 0.0:
                raise self.fail(n, "division by zero")
            value = value * rhs if op == "*" else value / rhs
        return value, t

    def _atom(self, n: int, t: list[str]) -> tuple[float, list[str]]:
        if not t:
            raise self.fail(n, "an expression ends early")
        head = t[0]
        if head in "+-":
            value, rest = self._atom(n, t[1:])
            return (-value if head == "-" else value), rest
        if head in "[(":
            value, rest = self._sum(n, t[1:])
            if not rest or rest[0] not in "])":
                raise self.fail(n, "an expression's bracket does not close")
            return value, rest[1:]
        if head.startswith("#"):
            var = int(head[1:])
            if var not in self.vars:
                raise self.fail(n, f"#{var} is used before it is set to a constant")
            return self.vars[var], t[1:]
        if _NUMBER.fullmatch(head):
            return float(head), t[1:]
        raise self.fail(n, f"cannot evaluate {head!r}")

    def _block(self, n: int, text: str) -> None:
        plain = _PLAIN.match(text)
        if plain:  # the common cutting block: numbers only, no word the modal state needs parsed
            self._plain(n, plain)
            return
        if not text or text == "%" or re.fullmatch(r"O\d+", text):
            return
        assign = _ASSIGN.match(text)
        if assign:
            self.vars[int(assign.group(1))] = self._expr(n, assign.group(2))
            return
        if re.search(r"\b(IF|GOTO|THEN)\b", text):
            raise self.fail(n, "IF/GOTO jumps are not evaluated: unroll them")
        self.blocks += 1
        if self.blocks > MAX_READ_BLOCKS:
            raise self.fail(n, f"more than {MAX_READ_BLOCKS:,} blocks")
        words = self._words(n, text)
        self._modes(n, words)
        axes = {k: v for k, v in words if k in "CXYZ"}
        if axes:
            self._move(n, axes)

    def _plain(self, n: int, m: re.Match[str]) -> None:
        """A block of :data:`_PLAIN`'s form: what :meth:`_words`, :meth:`_modes` and
        :meth:`_move` make of it, without the tokenizer."""
        self.blocks += 1
        if self.blocks > MAX_READ_BLOCKS:
            raise self.fail(n, f"more than {MAX_READ_BLOCKS:,} blocks")
        if m.group(1):
            self.motion = 1.0
        if m.group(6):
            self.feed = float(m.group(6))
        axes = {"C": float(m.group(2)), "X": float(m.group(3)), "Z": float(m.group(5))}
        if m.group(4):
            axes["Y"] = float(m.group(4))
        self._move(n, axes)

    def _words(self, n: int, text: str) -> list[tuple[str, float]]:
        found, at = [], 0
        for match in _WORD.finditer(text):
            if text[at : match.start()].strip():
                raise self.fail(n, f"cannot read {text[at : match.start()].strip()[:20]!r}")
            letter, raw = match.group(1), match.group(2)
            if raw.startswith(("[", "#")):
                value = self._expr(n, raw)
            else:
                if letter in "CXYZ" and "." not in raw:
                    raise self.fail(
                        n,
                        f"{letter}{raw} has no decimal point: controllers read it as mm or as µm "
                        "by a parameter",
                    )
                value = float(raw)
            found.append((letter, value))
            at = match.end()
        if text[at:].strip():
            raise self.fail(n, f"cannot read {text[at:].strip()[:20]!r}")
        return found

    def _modes(self, n: int, words: list[tuple[str, float]]) -> None:
        for letter, value in words:
            if letter == "G":
                self._g(n, value)
            elif letter == "M":
                if value in FLOW_M:
                    raise self.fail(n, f"M{value:g} calls or returns from a subprogram: not evaluated")
                self.m_codes.add(f"M{value:g}")
            elif letter == "F":
                self.feed = value
            elif letter not in "CXYZNTS":
                raise self.fail(n, f"the word {letter} is not one the reader evaluates")

    def _g(self, n: int, value: float) -> None:
        if value in (2.0, 3.0):
            raise self.fail(n, "circular interpolation (G2/G3) is not a path program's block")
        if value == 91.0:
            raise self.fail(n, "incremental positions (G91): the reader takes absolute (G90) programs")
        if value == 20.0:
            raise self.fail(n, "inch units (G20): the reader takes metric (G21/G71) programs")
        if value not in KNOWN_G:
            raise self.fail(n, f"G{value:g} is not a code the reader evaluates")
        if value in (93.0, 94.0):
            self.g93 = value == 93.0
            self.feed = math.nan
        elif value in (0.0, 1.0):
            self.motion = value

    def _move(self, n: int, axes: dict[str, float]) -> None:
        if self.g93 and self.motion == 1.0:
            if self.start is None:
                self.start = dict(self.pos)
            if not self.feed > 0.0:
                raise self.fail(n, "a G93 block without a positive F: its time is unknown")
            minutes = 1.0 / self.feed if self.g93_f == "inverse_minutes" else self.feed / 60.0
            self.pos.update(axes)
            for axis in "CXYZ":
                self.out[axis].append(self.pos[axis])
            self.out["T"].append(minutes * 60.0)
            return
        if self.out["C"]:
            self.pos.update(axes)  # a move after the cut (the retract) ends it
            return
        self.pos.update(axes)

    def _moves(self) -> Moves:
        assert self.start is not None
        cols = {a: np.array([self.start[a], *self.out[a]]) for a in "CXYZ"}
        for axis in "CXZ":
            if not np.all(np.isfinite(cols[axis])):
                raise DialectError(f"the cut starts before {axis} is given a position")
        c = cols["C"]
        if self.dialect != "linuxcnc":
            c = _unwrap(c)
        y = None if not np.all(np.isfinite(cols["Y"])) else cols["Y"]
        notes = [f"machine functions passed over: {', '.join(sorted(self.m_codes))}"] if self.m_codes else []
        return Moves(
            c,
            cols["X"],
            cols["Z"],
            np.array(self.out["T"]),
            y,
            None,
            "linear",
            self.dialect,
            self.comments,
            notes,
        )


def _unwrap(c_deg: np.ndarray) -> np.ndarray:
    """C read modulo 360 made accumulated: every block turns the spindle forward by less
    than a revolution (C of a block equal to the last one's is no turn)."""
    step = np.mod(np.diff(c_deg), 360.0)
    return np.concatenate([[c_deg[0]], c_deg[0] + np.cumsum(step)])


# a cut block giving all three axes (with their velocities in PVT): read without the tokenizer
_PMAC_PLAIN = re.compile(
    r"^C(-?\d+\.\d+)(?::(-?\d+\.\d+))? X(-?\d+\.\d+)(?::(-?\d+\.\d+))? Z(-?\d+\.\d+)(?::(-?\d+\.\d+))?$"
)
_PMAC_MOVE = re.compile(r"^([CXZ])(-?\d+\.\d+)(?::(-?\d+\.\d+))?$")


def _read_pmac(lines: list[str], dialect: str) -> Moves:
    """A PMAC motion program: RAPID to the start, then PVT moves (each ``AXISpos:vel``,
    ``PVTms`` setting the segment time) or SPLINE1 moves at one TA [ms]."""
    reader = _PmacReader(dialect)
    for n, line in enumerate(lines):
        reader.line(n, line)
    return reader.moves()


class _PmacReader:
    """The state of a PMAC program read line by line (:func:`_read_pmac`)."""

    def __init__(self, dialect: str) -> None:
        self.dialect = dialect
        self.comments: list[str] = []
        self.pos: dict[str, float] = {"C": math.nan, "X": math.nan, "Z": math.nan}
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
        self.pos = {"C": float(m.group(1)), "X": float(m.group(3)), "Z": float(m.group(5))}
        self.points.append(self.pos)
        if self.mode == "PVT":
            self.vel.append({"C": float(m.group(2)), "X": float(m.group(4)), "Z": float(m.group(6))})
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
            self.vel.append({"C": 0.0, "X": 0.0, "Z": 0.0})  # a RAPID ends at rest
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
        cols = {a: np.array([p[a] for p in self.points]) for a in "CXZ"}
        for axis in "CXZ":
            if not np.all(np.isfinite(cols[axis])):
                raise DialectError(f"the cut starts before {axis} is given a position")
        velocity = None
        interp = "spline1" if self.mode == "SPLINE1" else "pvt"
        if interp == "pvt":
            velocity = {a: np.array([v[a] for v in self.vel]) for a in "CXZ"}
        times = np.array(self.times)
        return Moves(
            cols["C"], cols["X"], cols["Z"], times, None, velocity, interp, self.dialect, self.comments
        )


def aligned(moves: Moves, c0_deg: float) -> Moves:
    """``moves`` with C shifted by whole revolutions so that it starts nearest ``c0_deg``: a C
    printed modulo 360 gives the angle, not the revolutions turned before the program starts."""
    turns = round((c0_deg - float(moves.c_deg[0])) / 360.0)
    return replace(moves, c_deg=moves.c_deg + 360.0 * turns)


def blocks(lines: list[str]) -> Iterator[str]:
    """The lines that are not whole-line comments (what the controller executes)."""
    for line in lines:
        if not (line.startswith(("(", "; "))):
            yield line


def summary(m: Moves) -> dict[str, Any]:
    """Points, revolutions, points per revolution and the feed per revolution [µm] (from X's
    drop per revolution of C) of a spiral program's moves."""
    turn = (m.c_deg - m.c_deg[0]) / 360.0
    revs = float(turn[-1])
    dx = -np.diff(m.x_mm) * 1e3
    dturn = np.diff(turn)
    feed = np.divide(dx, dturn, out=np.full(dx.shape, np.nan), where=dturn > 0)
    feed = feed[np.isfinite(feed)]
    return {
        "n_points": m.n_points,
        "revolutions": revs,
        "points_per_rev": (m.n_points - 1) / revs if revs > 0 else math.nan,
        "feed_um_per_rev": {
            "min": float(feed.min()) if feed.size else math.nan,
            "median": float(np.median(feed)) if feed.size else math.nan,
            "max": float(feed.max()) if feed.size else math.nan,
        },
        "machining_s": float(np.sum(m.seconds)),
    }
