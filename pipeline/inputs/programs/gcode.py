"""ISO STS and RS274 G-code read as the controller its machine's profile describes reads it
(docs/controllers.md): the profile's power-on modal state, modal blocks without a G word, the
macro language (:mod:`ftsweep.inputs.programs.macro`: variables, expressions, WHILE, IF, GOTO), G52
offsets applied, G90/G91, dwells as time, the spindle either way, several passes; anything the
profile does not define is refused naming the line, and values that cannot be a lathe program
under the profile are refused naming the convention that is the likely cause."""

from __future__ import annotations

import math
import re
from typing import Any, Optional

import numpy as np

from ftsweep.inputs.programs import macro
from ftsweep.inputs.programs.feedrate import check_timing
from ftsweep.inputs.programs.moves import DialectError, Moves, line_label, physical_line

# the work a program may make its reader do, in units of one expression node parsed or
# evaluated (a line executed: LINE_UNITS): WORK_PER_BYTE a byte of the file, at least
# WORK_FLOOR (a small file's loops: well under a second here) and at most MAX_WORK. A file
# written out block by block costs about LINE_UNITS a line; a loop that does not end, or an
# expression that would take long, is refused as soon as its work passes the budget.
WORK_PER_BYTE = 40
WORK_FLOOR = 1_000_000
MAX_WORK = 50_000_000
# a line executed costs as much as about ten expression nodes (its cleaning, matching and
# modal state: ~1.4 µs against ~0.1 µs a node here), so it counts LINE_UNITS units
LINE_UNITS = 10

# a cutting block of numbers only (each with its decimal point): read without the tokenizer
_PLAIN = re.compile(
    r"^(G0?1 )?C(-?\d+\.\d*) X(-?\d+\.\d*) (?:Y(-?\d+\.\d*) )?Z(-?\d+\.\d*)(?: F(\d+\.\d*))?$"
)
_WORD = re.compile(r"([A-Z])\s*(\[[^\]]*\]|#\d+|[-+]?(?:\d+\.?\d*|\.\d+))")
_COMMENT = re.compile(r"\([^()]*\)")
_LABEL = re.compile(r"^N(\d+)\s*")
_ASSIGN = re.compile(r"^#(\d+)\s*=\s*(.+)$")
_WHILE = re.compile(r"^WHILE\s*\[(.+)\]\s*DO\s*(\d)$")
_END = re.compile(r"^END\s*(\d)$")
_GOTO = re.compile(r"^GOTO\s*(.+)$")
_IF = re.compile(r"^IF\s*\[(.+)\]\s*(GOTO\s*(.+)|THEN\s*(.+))$")
# G codes of modes the path does not depend on: planes, metric, compensation cancels, exact
# stop and cutting modes, polar cancel, work coordinate systems (their offsets zero: the
# program's coordinates are the part's)
PASSIVE_G = {17.0, 18.0, 19.0, 21.0, 40.0, 49.0, 54.0, 55.0, 56.0, 57.0, 58.0, 59.0, 61.0, 63.0, 64.0, 71.0}
PASSIVE_G |= {103.0}
FLOW_M = {97.0, 98.0, 99.0}  # subprogram calls and returns: not evaluated
END_M = {2.0, 30.0}
# the axes a block may move: C, X, Y, Z and a layered program's servo W
AXES = ("C", "X", "Y", "Z", "W")
# a G94 feed move turning C among this many in a row is a cut, not an approach
G94_CUT_RUN = 3
# the longest cutting block read without the tokenizer: its numbers then have at most ~80
# digits, all finite as floats
MAX_PLAIN_CHARS = 300
# moves that are not cuts listed in a summary (the rest counted by the cuts' rule alone)
MAX_LISTED = 50


class IsoReader:
    """ISO STS / RS274 G-code as the controller of profile ``ctrl``
    (:class:`ftsweep.inputs.controllers.Controller`) reads it (module docstring)."""

    def __init__(self, lines: list[str], dialect: str, ctrl: Any, preamble: int = 0) -> None:
        # ``preamble``: how many of ``lines`` are a template's, read before the program's own
        # (a bare point list takes their modal state); refusals name those as preamble lines
        self.lines, self.dialect, self.ctrl = lines, dialect, ctrl
        self.preamble = preamble
        self.started_from = ""
        self.still_s = 0.0
        self.not_cut: list[tuple[int, str]] = []
        self.vars: dict[int, float] = {}
        self.pos = {a: math.nan for a in AXES}
        self.offset = {a: 0.0 for a in AXES}
        self.g93 = ctrl.power_on_feed == "G93"
        self.absolute = ctrl.power_on_distance == "G90"
        self.motion: Optional[float] = {"G00": 0.0, "G01": 1.0, "none": None}[ctrl.power_on_motion]
        self.in_cut = False
        self.feed, self.feed_line = math.nan, -1
        self.first_f: Optional[tuple[int, float]] = None
        self.g94_c_run = 0
        # every cut's points; T the time of the block into a point, NaN at a cut's start
        self.out: dict[str, list[float]] = {a: [] for a in (*AXES, "T")}
        self.point_line: list[int] = []
        self.m_codes: set[str] = set()
        self.comments: dict[int, str] = {}
        self.dwell_s = 0.0
        self.offset_used = False
        self.work = 0  # lines executed and expression nodes parsed or evaluated
        size = sum(len(line) + 1 for line in lines)
        self.budget = min(max(WORK_FLOOR, WORK_PER_BYTE * size), MAX_WORK)
        self.ended = False
        # a loop's lines are read and its expressions parsed once, then evaluated each pass
        self._cleaned: dict[int, str] = {}
        self._parsed: dict[int, list[tuple[str, str]]] = {}
        self._exprs: dict[str, macro.Expr] = {}
        self._conds: dict[str, macro.Condition] = {}
        self._labels: dict[int, int] = {}
        self._col = 0  # the column of the word being evaluated, for messages (0: the line)
        self._loops: dict[int, int] = {}

    def line_no(self, n: int) -> int:
        """The physical line of ``lines[n]`` in its file (1-based; a preamble's negative)."""
        return physical_line(n, self.preamble)

    def fail(self, n: int, why: str) -> DialectError:
        text = self.lines[n].strip()[:80] if 0 <= n < len(self.lines) else ""
        col = f", column {self._col}" if self._col else ""
        return DialectError(f"{line_label(self.line_no(n))}{col} ({text!r}): {why}")

    def _column(self, n: int, token: str) -> int:
        """Where ``token`` (a word as cleaned) stands in line ``n`` as written (1-based; 0
        when comments or a macro expression's spacing hide it)."""
        return self.lines[n].upper().find(token) + 1

    def run(self) -> Moves:
        self._scan()
        n = 0
        while n < len(self.lines) and not self.ended:
            self.work += LINE_UNITS  # every line executed counts (loop tests too): no loop runs away
            if self.work > self.budget:
                raise self.fail(n, self._over_budget())
            if self.preamble and n >= self.preamble and not self.started_from:
                self.started_from = self._state()
            n = self._step(n)
        if self.preamble and not self.started_from:
            raise DialectError(
                "the preamble ends the program (M2/M30) or never reaches its end: the program's own "
                "lines are not read"
            )
        if not self.out["C"]:
            raise DialectError(self._no_cut())
        moves = self._moves()
        check_timing(moves, self.ctrl, self._f_hint())
        return moves

    def _state(self) -> str:
        """The modal state and position the program's own lines start from."""
        feed = f"G93 F{self.feed:g}" if self.g93 and self.feed > 0 else ("G93" if self.g93 else "G94")
        motion = {None: "no motion mode", 0.0: "G00", 1.0: "G01"}[self.motion]
        at = " ".join(f"{a}{self.pos[a]:g}" for a in AXES if math.isfinite(self.pos[a]))
        offsets = " ".join(f"{a}{v:g}" for a, v in self.offset.items() if v)
        return f"{motion} {feed} {'G90' if self.absolute else 'G91'}, at {at or 'no position'}" + (
            f", G52 {offsets}" if offsets else ""
        )

    def _no_cut(self) -> str:
        feed = "G93" if self.ctrl.power_on_feed == "G93" else "G94 (feed per minute)"
        return (
            "no cutting block under G93 (inverse time): nothing to predict (the profile's power-on feed "
            f"mode is {feed}; a program of point blocks needs G93 before them)"
        )

    def _scan(self) -> None:
        """Sequence numbers (GOTO's targets) and every WHILE's END, found before running."""
        open_loops: list[tuple[str, int]] = []
        for n, raw in enumerate(self.lines):
            upper = raw.upper()
            if "N" in upper:
                label = _LABEL.match(raw.strip().upper())
                if label:
                    self._labels.setdefault(int(label.group(1)), n)
            if "WHILE" not in upper and "END" not in upper:
                continue
            text = self._clean(n)
            loop, end = _WHILE.match(text), _END.match(text)
            if loop:
                open_loops.append((loop.group(2), n))
            elif end:
                if not open_loops or open_loops[-1][0] != end.group(1):
                    raise self.fail(n, f"END{end.group(1)} without its WHILE … DO{end.group(1)}")
                start = open_loops.pop()[1]
                self._loops[start], self._loops[n] = n, start
        if open_loops:
            tag, n = open_loops[-1]
            raise self.fail(n, f"WHILE … DO{tag} has no END{tag}")

    def _step(self, n: int) -> int:
        """Execute line ``n``; the line to execute next."""
        text = self._clean(n)
        loop = _WHILE.match(text)
        if loop:
            return n + 1 if self._condition(n, loop.group(1)) else self._loops[n] + 1
        if _END.match(text):  # the WHILE's condition tested again: into its body or past the END
            start = self._loops[n]
            again = self._condition(n, _WHILE.match(self._clean(start)).group(1))  # type: ignore[union-attr]
            return start + 1 if again else n + 1
        jump = _IF.match(text)
        if jump:
            if not self._condition(n, jump.group(1)):
                return n + 1
            if jump.group(3) is not None:
                return self._goto(n, jump.group(3))
            text = jump.group(4).strip()
            if not _ASSIGN.match(text):
                raise self.fail(n, "IF … THEN takes an assignment #i = expression only")
        goto = _GOTO.match(text)
        if goto:
            return self._goto(n, goto.group(1))
        self._block(n, text)
        return n + 1

    def _goto(self, n: int, target: str) -> int:
        label = self._expr(n, target)
        if label != round(label) or int(label) not in self._labels:
            raise self.fail(n, f"GOTO {label:g}: no block N{label:g} in the program")
        return self._labels[int(label)]

    def _over_budget(self) -> str:
        return (
            f"the program's work passed {self.budget:,} units ({LINE_UNITS} a line executed, 1 an expression "
            f"node parsed or evaluated; {WORK_PER_BYTE} a byte of the file, at least {WORK_FLOOR:,}, at most "
            f"{MAX_WORK:,}): a loop that does not end, or a program to write out block by block"
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
        return _LABEL.sub("", text, count=1)

    def _condition(self, n: int, text: str) -> bool:
        return bool(self._evaluated(n, self._once(n, text, self._conds, macro.condition)))

    def _expr(self, n: int, text: str) -> float:
        return float(self._evaluated(n, self._once(n, text, self._exprs, macro.parse)))

    def _once(self, n: int, text: str, cache: dict[str, Any], parse: Any) -> Any:
        """``text`` parsed by ``parse`` once (a loop's lines are evaluated again and again),
        its nodes charged to the work budget."""
        found = cache.get(text)
        if found is None:
            try:
                found = cache[text] = parse(text)
            except macro.MacroError as exc:
                raise self.fail(n, str(exc)) from None
            self._charge(n, found.nodes)
        return found

    def _charge(self, n: int, units: int) -> None:
        self.work += units
        if self.work > self.budget:
            raise self.fail(n, self._over_budget())

    def _evaluated(self, n: int, f: Any) -> Any:
        self._charge(n, f.nodes)
        try:
            return f(self.vars)
        except KeyError as exc:
            why = f"#{exc.args[0]} is used before it is set (the reader knows no system variable)"
            raise self.fail(n, why) from None
        except ZeroDivisionError:
            raise self.fail(n, "division by zero") from None
        except ValueError as exc:  # SQRT of a negative number
            raise self.fail(n, f"an expression has no value: {exc}") from None

    def _block(self, n: int, text: str) -> None:
        plain = _PLAIN.match(text) if len(text) < MAX_PLAIN_CHARS else None
        if plain and self.absolute and self.g93 and not any(self.offset.values()):
            self._plain(n, plain)  # the common cutting block: no word the modal state needs parsed
            return
        if not text or text == "%" or re.fullmatch(r"O\d+", text):
            return
        assign = _ASSIGN.match(text)
        if assign:
            try:
                target = macro.variable(assign.group(1))
            except macro.MacroError as exc:
                raise self.fail(n, str(exc)) from None
            self.vars[target] = self._expr(n, assign.group(2))
            return
        if re.search(r"\b(IF|GOTO|THEN|WHILE|DO|END)\b", text):
            raise self.fail(n, "a macro statement the reader does not evaluate in this form")
        words = self._words(n, text)
        gs = [v for k, v in words if k == "G"]
        if 4.0 in gs:
            self._dwell(n, words)
            return
        axes = self._modes(n, words)
        if 52.0 in gs:
            self._local_offset(axes)
            return
        if axes:
            self._move(n, axes)

    def _plain(self, n: int, m: re.Match[str]) -> None:
        """A block of :data:`_PLAIN`'s form: what :meth:`_words`, :meth:`_modes` and
        :meth:`_move` make of it, without the tokenizer (its numbers finite: a literal of
        hundreds of digits is not, and goes to the tokenizer's refusal)."""
        if m.group(1):
            self.motion = 1.0
        if m.group(6):
            self._set_feed(n, float(m.group(6)))
        axes = {"C": float(m.group(2)), "X": float(m.group(3)), "Z": float(m.group(5))}
        if m.group(4):
            axes["Y"] = float(m.group(4))
        self._move(n, axes)

    def _words(self, n: int, text: str) -> list[tuple[str, float]]:
        parsed = self._parsed.get(n)
        if parsed is None:
            parsed = self._parsed[n] = self._split_words(n, text)
        words = [(letter, self._value(n, letter, raw)) for letter, raw in parsed]
        for (letter, raw), (_, value) in zip(parsed, words, strict=True):
            if not math.isfinite(value):
                self._col = self._column(n, f"{letter}{raw}")
                raise self.fail(n, f"{letter}{raw[:24]} is not a finite number")
        return words

    def _value(self, n: int, letter: str, raw: str) -> float:
        if raw[0] in "[#":
            return self._expr(n, raw)
        if letter in AXES and "." not in raw:
            return self._whole_number(n, letter, raw)
        return float(raw)

    def _whole_number(self, n: int, letter: str, raw: str) -> float:
        how = self.ctrl.whole_number_words
        if how == "mm":
            return float(raw)
        if how == "increments":
            return float(raw) * self.ctrl.input_increment_um * 1e-3
        self._col = self._column(n, f"{letter}{raw}")
        raise self.fail(
            n,
            f"{letter}{raw} has no decimal point: a controller reads it as mm or in least input increments "
            "by a parameter; the machine's profile does not say which "
            "(machine.controller.whole_number_words)",
        )

    def _split_words(self, n: int, text: str) -> list[tuple[str, str]]:
        """A block's words as written (letter, number or expression), checked once."""
        found, at = [], 0
        for match in _WORD.finditer(text):
            if text[at : match.start()].strip():
                self._col = self._column(n, text[at : match.start()].strip())
                raise self.fail(n, f"cannot read {text[at : match.start()].strip()[:20]!r}")
            found.append((match.group(1), match.group(2)))
            at = match.end()
        if text[at:].strip():
            self._col = self._column(n, text[at:].strip())
            raise self.fail(n, f"cannot read {text[at:].strip()[:20]!r}")
        return found

    def _modes(self, n: int, words: list[tuple[str, float]]) -> dict[str, float]:
        """The block's modal words applied; its axis words returned."""
        axes: dict[str, float] = {}
        for k, (letter, value) in enumerate(words):
            self._col = self._column(n, "".join(self._parsed[n][k]))
            if letter == "G":
                self._g(n, value)
            elif letter == "M":
                self._m(n, value)
            elif letter == "F":
                self._set_feed(n, value)
            elif letter in AXES:
                axes[letter] = value
            elif letter not in "NTS":
                raise self.fail(n, f"the word {letter} is not one the reader evaluates in this block")
        self._col = 0
        return axes

    def _m(self, n: int, value: float) -> None:
        if value in FLOW_M:
            raise self.fail(n, f"M{value:g} calls or returns from a subprogram: not evaluated")
        if value in END_M:
            self.ended = True
        self.m_codes.add(f"M{value:g}")

    def _g(self, n: int, value: float) -> None:
        if value in (2.0, 3.0):
            raise self.fail(n, "circular interpolation (G2/G3) is not a path program's block")
        if value == 20.0:
            raise self.fail(n, "inch units (G20): the reader takes metric (G21/G71) programs")
        if value in (93.0, 94.0):
            self.g93 = value == 93.0
            self.in_cut = self.in_cut and self.g93
            self.feed = math.nan
        elif value in (0.0, 1.0):
            self.motion = value
        elif value in (90.0, 91.0):
            self.absolute = value == 90.0
        elif value not in PASSIVE_G and value != 52.0:
            why = {
                10.0: "G10 sets offsets in the controller's memory",
                28.0: "G28 returns to a reference point",
            }
            raise self.fail(n, f"{why.get(value, f'G{value:g}')}: not a code the reader evaluates")

    def _set_feed(self, n: int, value: float) -> None:
        ctrl = self.ctrl
        if ctrl.f_min is not None and value < ctrl.f_min or ctrl.f_max is not None and value > ctrl.f_max:
            raise self.fail(n, f"F{value:g} is outside the controller's F range [{ctrl.f_min}, {ctrl.f_max}]")
        self.feed, self.feed_line = value, n

    def _dwell(self, n: int, words: list[tuple[str, float]]) -> None:
        """G04: the tool stands for X seconds (or P, in the profile's units)."""
        given = {k: v for k, v in words if k in "XPU"}
        if len(given) != 1 or any(k in "CYZW" for k, _ in words):
            raise self.fail(n, "G04 (dwell) takes one time word, X or U [s] or P, and moves no axis")
        letter, value = next(iter(given.items()))
        if value < 0:
            raise self.fail(n, "a dwell of negative time")
        self.dwell_s += value * 1e-3 if letter == "P" and self.ctrl.dwell_p == "ms" else value

    def _local_offset(self, axes: dict[str, float]) -> None:
        """G52: a local coordinate offset, added to every position programmed after it (G52
        without axes cancels every offset)."""
        if not axes:
            self.offset = {a: 0.0 for a in AXES}
        self.offset.update(axes)
        self.offset_used = self.offset_used or any(self.offset.values())

    def _target(self, axes: dict[str, float]) -> dict[str, float]:
        if self.absolute:
            return {a: v + self.offset[a] for a, v in axes.items()}
        return {a: self.pos[a] + v for a, v in axes.items()}

    def _move(self, n: int, axes: dict[str, float]) -> None:
        if self.motion is None:
            raise self.fail(
                n,
                "axis words before any motion mode (G0/G1): this controller refuses them "
                "(machine.controller.power_on_motion: none)",
            )
        target = self._target(axes)
        if self.g93 and self.motion == 1.0:
            self._inverse_time(n, target)
            return
        turns = "C" in target and target["C"] != self.pos["C"] and math.isfinite(self.pos["C"])
        self.g94_c_run = self.g94_c_run + 1 if turns and self.motion == 1.0 else 0
        if self.g94_c_run >= G94_CUT_RUN:
            raise self.fail(
                n,
                f"{G94_CUT_RUN} feed moves in a row turn C under G94 (feed per minute): a cut whose time "
                "depends on how this controller mixes degrees and mm; the reader times cuts written under "
                "G93" + (" (the profile's power-on feed mode is G94)" if not self.first_f else ""),
            )
        self.in_cut = False  # a move outside G93 (an approach, the retract) ends a cut
        what = "rapid" if self.motion == 0.0 else "G94 feed"
        self._passed(n, f"{what} move of {''.join(sorted(target))}")
        self.pos.update(target)

    def _passed(self, n: int, what: str) -> None:
        """A move that is not a cut, listed (the first ones: a loop repeats its approaches)."""
        if len(self.not_cut) < MAX_LISTED:
            self.not_cut.append((self.line_no(n), what))

    def _moved(self, target: dict[str, float]) -> list[str]:
        """The axes ``target`` moves from where the tool stands (an unknown position counts as
        moved); C read modulo 360 by a profile that wraps it (C360 is C0)."""
        wraps = self.ctrl.c_wrap == "revolution" and self.dialect != "linuxcnc"
        out = []
        for axis, value in target.items():
            here = self.pos[axis]
            step = value - here
            if axis == "C" and wraps and math.isfinite(step):
                step = math.remainder(step, 360.0)
            if not math.isfinite(here) or abs(step) > 1e-12 * max(1.0, abs(value)):
                out.append(axis)
        return out

    def _inverse_time(self, n: int, target: dict[str, float]) -> None:
        """A G93 feed block: a cut's block if it turns C; a standstill for its time if it moves no
        axis (a zero-length block, C360 -> C0 read modulo 360); else an air move that is not
        cut (an approach or a return with C still), which ends a cut."""
        moved = self._moved(target)
        if not moved:
            seconds = self._seconds(n)
            self.still_s += seconds
            self._passed(n, f"G93 block moving no axis: {seconds:g} s standing still")
        elif "C" not in moved:
            self._seconds(n)
            self.in_cut = False
            self._passed(n, f"G93 move of {''.join(sorted(moved))} without turning C")
        else:
            self._cut(n, target)
            return
        self.pos.update(target)

    def _cut(self, n: int, target: dict[str, float]) -> None:
        if not self.in_cut:
            # a cut starts where the tool stands (a layered program has one per segment); a
            # program that gives no position before its first block starts at that block
            self.in_cut = True
            if all(math.isfinite(self.pos[a]) for a in "CXZ"):
                self._point(math.nan, n)
                self.pos.update(target)
                self._point(self._seconds(n), n)
                return
            self.pos.update(target)
            self._point(math.nan, n)
            return
        seconds = self._seconds(n)
        self.pos.update(target)
        self._point(seconds, n)

    def _seconds(self, n: int) -> float:
        if not self.feed > 0.0:
            raise self.fail(n, "a G93 block without a positive F: its time is unknown")
        if self.ctrl.g93_f_every_block and self.feed_line != n:
            raise self.fail(
                n, "a G93 block without its own F: this controller needs F on every inverse-time block"
            )
        if self.first_f is None:
            self.first_f = (n, self.feed)
        return 60.0 / self.feed if self.ctrl.g93_f == "inverse_minutes" else self.feed

    def _point(self, seconds: float, n: int) -> None:
        for axis in AXES:
            self.out[axis].append(self.pos[axis])
        self.out["T"].append(seconds)
        self.point_line.append(n)

    def _moves(self) -> Moves:
        cols = {a: np.array(self.out[a]) for a in AXES}
        t = np.array(self.out["T"])
        starts = np.flatnonzero(np.isnan(t))
        for axis in "CXZ":
            if not np.all(np.isfinite(cols[axis])):
                k = int(np.flatnonzero(~np.isfinite(cols[axis]))[0])
                raise self.fail(self.point_line[k], f"the cut starts before {axis} is given a position")
        c = cols["C"]
        bounds = list(zip(starts, [*starts[1:], c.size], strict=True))
        if self.ctrl.c_wrap == "revolution" and self.dialect != "linuxcnc":
            c = np.concatenate([_unwrap(c[lo:hi]) for lo, hi in bounds])
        for lo, hi in bounds:
            self._one_way(c, int(lo), int(hi))
        y = None if not np.all(np.isfinite(cols["Y"])) else cols["Y"]
        w = None
        if np.any(np.isfinite(cols["W"])):
            if not np.all(np.isfinite(cols["W"])):
                raise DialectError("a cut starts before W (the servo) is given a position")
            w = cols["W"]
        notes = [f"machine functions passed over: {', '.join(sorted(self.m_codes))}"] if self.m_codes else []
        if self.offset_used:
            notes.append("G52 local offsets applied to the positions programmed after them")
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
            dwell_s=self.dwell_s,
            still_s=self.still_s,
            point_lines=np.array([self.line_no(k) for k in self.point_line], dtype=np.int64),
            not_cut=self.not_cut,
            started_from=self.started_from,
        )

    def _one_way(self, c: np.ndarray, lo: int, hi: int) -> None:
        """A cut's spindle turns one way (a block may hold C still)."""
        step = np.diff(c[lo:hi])
        if np.any(step > 0) and np.any(step < 0):
            turn = np.sign(step[np.flatnonzero(step)[0]])
            back = int(np.flatnonzero(np.sign(step) == -turn)[0])
            raise self.fail(
                self.point_line[lo + back + 1], "C turns back: a spindle program's C turns one way"
            )

    def _f_hint(self) -> Optional[str]:
        """Where the first G93 F stands and how it was read (the likely cause of a reading no
        lathe could run)."""
        if self.first_f is None:
            return None
        n, f = self.first_f
        how = "inverse minutes" if self.ctrl.g93_f == "inverse_minutes" else "seconds per block"
        return f"{line_label(self.line_no(n))}: G93 F{f:g} as {how}"


def _unwrap(c_deg: np.ndarray) -> np.ndarray:
    """C read modulo 360 made accumulated: every block turns the spindle by less than half a
    revolution, either way (the shorter way round)."""
    step = np.mod(np.diff(c_deg), 360.0)
    step = np.where(step > 180.0, step - 360.0, step)  # forward steps keep their exact value
    return np.concatenate([[c_deg[0]], c_deg[0] + np.cumsum(step)])
