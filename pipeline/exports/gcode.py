"""ISO STS and RS274 G-code read as a controller reads it (docs/controllers.md): modal
state, constant macro variables, WHILE loops of constant count and the G93 blocks' points;
anything else refused, naming the line."""

from __future__ import annotations

import math
import re
from collections.abc import Callable

import numpy as np

from ftsweep.exports.moves import DialectError, Moves

# lines a program's loops may execute beyond the file's own lines (about 3 s here at ~3.4 µs
# a line): a WHILE loop cannot make the reader run away, and a loop-made program of up to
# ~300,000 points is read; larger programs are written out, as CAM and ftsweep write them
MAX_READ_BLOCKS = 1_000_000


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
# the axes a block may move: C, X, Y, Z and a layered program's servo W
AXES = ("C", "X", "Y", "Z", "W")


# an expression parsed once: evaluated on the variables set so far (KeyError: one unset)
Expr = Callable[[dict[int, float]], float]


def _constant(c: float) -> Expr:
    return lambda v: c


def _variable(k: int) -> Expr:
    return lambda v: v[k]


def _negative(a: Expr) -> Expr:
    return lambda v: -a(v)


def _plus(a: Expr, b: Expr) -> Expr:
    return lambda v: a(v) + b(v)


def _minus(a: Expr, b: Expr) -> Expr:
    return lambda v: a(v) - b(v)


def _times(a: Expr, b: Expr) -> Expr:
    return lambda v: a(v) * b(v)


def _over(a: Expr, b: Expr) -> Expr:
    return lambda v: a(v) / b(v)


class IsoReader:
    """ISO STS / RS274 G-code as a controller reads it: modal state, macro variables set to
    constants, WHILE loops (their conditions on those constants) and the G93 blocks' points."""

    def __init__(self, lines: list[str], dialect: str, g93_f: str) -> None:
        self.lines, self.dialect, self.g93_f = lines, dialect, g93_f
        self.vars: dict[int, float] = {}
        self.pos = {a: math.nan for a in AXES}
        self.g93 = False
        self.in_cut = False
        self.feed = math.nan
        self.motion = 0.0
        # every cut's points; T the time of the block into a point, NaN at a cut's start
        self.out: dict[str, list[float]] = {a: [] for a in (*AXES, "T")}
        self.m_codes: set[str] = set()
        self.comments: dict[int, str] = {}
        self.blocks = 0
        # a loop's lines are read and its expressions parsed once, then evaluated each pass
        self._cleaned: dict[int, str] = {}
        self._parsed: dict[int, list[tuple[str, str]]] = {}
        self._compiled: dict[str, Callable[[dict[int, float]], float]] = {}

    def fail(self, n: int, why: str) -> DialectError:
        text = self.lines[n].strip()[:80] if n < len(self.lines) else ""
        return DialectError(f"line {n + 1} ({text!r}): {why}")

    def run(self) -> Moves:
        self.budget = len(self.lines) + MAX_READ_BLOCKS
        self._execute(0, len(self.lines))
        if not self.out["C"]:
            raise DialectError("no cutting block under G93 (inverse time): nothing to predict")
        return self._moves()

    def _execute(self, first: int, stop: int) -> None:
        n = first
        while n < stop:
            # every line executed counts (assignments and loop tests too): no loop runs away
            self.blocks += 1
            if self.blocks > self.budget:
                raise self.fail(n, self._over_budget())
            text = self._clean(n)
            loop = _WHILE.match(text)
            if loop:
                end = self._loop_end(n, loop.group(2), stop)
                while self._condition(n, loop.group(1)):
                    self._execute(n + 1, end)
                    self.blocks += 1
                    if self.blocks > self.budget:
                        raise self.fail(n, self._over_budget())
                n = end + 1
                continue
            if _END.match(text):
                raise self.fail(n, "END without its WHILE")
            self._block(n, text)
            n += 1

    def _over_budget(self) -> str:
        return (
            f"its loops executed more than {MAX_READ_BLOCKS:,} lines beyond the file's own (a loop "
            "that does not end, or a program to write out block by block)"
        )

    def _clean(self, n: int) -> str:
        text = self._cleaned.get(n)
        if text is None:
            text = self._cleaned[n] = self._clean_line(n)
        return text

    def _clean_line(self, n: int) -> str:
        raw = self.lines[n].strip()
        if raw.startswith("(") and raw.endswith(")") and raw.count(")") == 1:
            self.comments[n] = raw[1:-1]  # by line: a loop's comment read again is one comment
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
        parsed once by a small parser into a tree of closures and evaluated on the variables
        as they are: never by Python's ``eval``."""
        compiled = self._compiled.get(text)
        if compiled is None:
            tokens = re.findall(r"#\d+|\d+\.?\d*|\.\d+|[-+*/\[\]()]|\S", text)
            compiled, rest = self._sum(n, tokens)
            if rest:
                raise self.fail(n, f"cannot evaluate {text.strip()[:40]!r}")
            self._compiled[text] = compiled
        try:
            return compiled(self.vars)
        except KeyError as exc:
            raise self.fail(n, f"#{exc.args[0]} is used before it is set to a constant") from None
        except ZeroDivisionError:
            raise self.fail(n, "division by zero") from None

    def _sum(self, n: int, t: list[str]) -> tuple[Expr, list[str]]:
        value, t = self._product(n, t)
        while t and t[0] in "+-":
            op, (rhs, t) = t[0], self._product(n, t[1:])
            value = _plus(value, rhs) if op == "+" else _minus(value, rhs)
        return value, t

    def _product(self, n: int, t: list[str]) -> tuple[Expr, list[str]]:
        value, t = self._atom(n, t)
        while t and t[0] in "*/":
            op, (rhs, t) = t[0], self._atom(n, t[1:])
            value = _times(value, rhs) if op == "*" else _over(value, rhs)
        return value, t

    def _atom(self, n: int, t: list[str]) -> tuple[Expr, list[str]]:
        if not t:
            raise self.fail(n, "an expression ends early")
        head = t[0]
        if head in "+-":
            value, rest = self._atom(n, t[1:])
            return (_negative(value) if head == "-" else value), rest
        if head in "[(":
            value, rest = self._sum(n, t[1:])
            if not rest or rest[0] not in "])":
                raise self.fail(n, "an expression's bracket does not close")
            return value, rest[1:]
        if head.startswith("#"):
            return _variable(int(head[1:])), t[1:]
        if _NUMBER.fullmatch(head):
            return _constant(float(head)), t[1:]
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
        words = self._words(n, text)
        self._modes(n, words)
        axes = {k: v for k, v in words if k in AXES}
        if axes:
            self._move(n, axes)

    def _plain(self, n: int, m: re.Match[str]) -> None:
        """A block of :data:`_PLAIN`'s form: what :meth:`_words`, :meth:`_modes` and
        :meth:`_move` make of it, without the tokenizer."""
        if m.group(1):
            self.motion = 1.0
        if m.group(6):
            self.feed = float(m.group(6))
        axes = {"C": float(m.group(2)), "X": float(m.group(3)), "Z": float(m.group(5))}
        if m.group(4):
            axes["Y"] = float(m.group(4))
        self._move(n, axes)

    def _words(self, n: int, text: str) -> list[tuple[str, float]]:
        parsed = self._parsed.get(n)
        if parsed is None:
            parsed = self._parsed[n] = self._split_words(n, text)
        return [(letter, self._expr(n, raw) if raw[0] in "[#" else float(raw)) for letter, raw in parsed]

    def _split_words(self, n: int, text: str) -> list[tuple[str, str]]:
        """A block's words as written (letter, number or expression), checked once."""
        found, at = [], 0
        for match in _WORD.finditer(text):
            if text[at : match.start()].strip():
                raise self.fail(n, f"cannot read {text[at : match.start()].strip()[:20]!r}")
            letter, raw = match.group(1), match.group(2)
            if not raw.startswith(("[", "#")) and letter in AXES and "." not in raw:
                raise self.fail(
                    n,
                    f"{letter}{raw} has no decimal point: controllers read it as mm or as µm by a parameter",
                )
            found.append((letter, raw))
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
            elif letter not in "CXYZWNTS":
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
            self.in_cut = self.in_cut and self.g93
            self.feed = math.nan
        elif value in (0.0, 1.0):
            self.motion = value

    def _move(self, n: int, axes: dict[str, float]) -> None:
        if self.g93 and self.motion == 1.0:
            if not self.in_cut:
                # a cut starts where the tool stands: a layered program has one per segment
                self.in_cut = True
                self._point(math.nan)
            if not self.feed > 0.0:
                raise self.fail(n, "a G93 block without a positive F: its time is unknown")
            minutes = 1.0 / self.feed if self.g93_f == "inverse_minutes" else self.feed / 60.0
            self.pos.update(axes)
            self._point(minutes * 60.0)
            return
        self.in_cut = False  # a move outside G93 (an approach, the retract) ends a cut
        self.pos.update(axes)

    def _point(self, seconds: float) -> None:
        for axis in AXES:
            self.out[axis].append(self.pos[axis])
        self.out["T"].append(seconds)

    def _moves(self) -> Moves:
        cols = {a: np.array(self.out[a]) for a in AXES}
        t = np.array(self.out["T"])
        starts = np.flatnonzero(np.isnan(t))
        for axis in "CXZ":
            if not np.all(np.isfinite(cols[axis])):
                raise DialectError(f"the cut starts before {axis} is given a position")
        c = cols["C"]
        if self.dialect != "linuxcnc":
            # C read modulo 360 is made accumulated within each cut
            c = np.concatenate(
                [_unwrap(c[lo:hi]) for lo, hi in zip(starts, [*starts[1:], c.size], strict=True)]
            )
        y = None if not np.all(np.isfinite(cols["Y"])) else cols["Y"]
        w = None
        if np.any(np.isfinite(cols["W"])):
            if not np.all(np.isfinite(cols["W"])):
                raise DialectError("a cut starts before W (the servo) is given a position")
            w = cols["W"]
        notes = [f"machine functions passed over: {', '.join(sorted(self.m_codes))}"] if self.m_codes else []
        return Moves(
            c,
            cols["X"],
            cols["Z"],
            t[1:],
            y,
            None,
            "linear",
            self.dialect,
            [self.comments[k] for k in sorted(self.comments)],
            notes,
            w,
            starts[1:] if starts.size > 1 else None,
        )


def _unwrap(c_deg: np.ndarray) -> np.ndarray:
    """C read modulo 360 made accumulated: every block turns the spindle forward by less
    than a revolution (C of a block equal to the last one's is no turn)."""
    step = np.mod(np.diff(c_deg), 360.0)
    return np.concatenate([[c_deg[0]], c_deg[0] + np.cumsum(step)])
