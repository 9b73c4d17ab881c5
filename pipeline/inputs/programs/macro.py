"""The macro language of ISO controllers (Fanuc Custom Macro B, as the Moore and most STS
controllers run it) as far as a path program needs it: arithmetic on numbers and variables
(+ − * /, [ ] grouping, SIN COS TAN ATAN SQRT ABS ROUND FIX FUP, angles in degrees) and the
conditions LT LE GT GE EQ NE of WHILE and IF (docs/controllers.md).

An expression is parsed once, iteratively (operator precedence by a shunting yard: linear in
its tokens, no recursion, so brackets nested any depth cost their tokens only) into postfix
code that a stack machine evaluates in as many steps as the code has nodes; never by
Python's ``eval``. Each expression counts its nodes (:attr:`Expr.nodes`): the reader charges
them to its work budget every time it evaluates one. An expression of more than
:data:`MAX_TOKENS` tokens is refused before it is parsed whole.
"""

from __future__ import annotations

import math
import operator
import re
from collections.abc import Callable
from dataclasses import dataclass

# the longest expression a line may hold, in tokens (a CAM's longest is a few dozen)
MAX_TOKENS = 100_000
# the largest variable number: Fanuc's common and system variables end below it
MAX_VARIABLE = 99_999


class MacroError(ValueError):
    """An expression or condition the macro language does not define (the reader adds the line)."""


_TOKEN = re.compile(r"#\d+|\d+\.?\d*|\.\d+|[A-Z]+|[-+*/\[\]()]|\S")
_NUMBER = re.compile(r"\d+\.?\d*|\.\d+")
_CONDITION = re.compile(r"^(.+?)\s*\b(LT|LE|GT|GE|EQ|NE)\b\s*(.+)$")
_COMPARE: dict[str, Callable[[float, float], bool]] = {
    "LT": operator.lt,
    "LE": operator.le,
    "GT": operator.gt,
    "GE": operator.ge,
    "EQ": operator.eq,
    "NE": operator.ne,
}


def _fix(x: float) -> float:
    return float(math.floor(x)) if x >= 0 else float(math.ceil(x))


def _fup(x: float) -> float:
    return float(math.ceil(x)) if x >= 0 else float(math.floor(x))


def _round(x: float) -> float:
    """Fanuc ROUND: half away from zero (Python's round is half to even)."""
    return math.copysign(math.floor(abs(x) + 0.5), x)


FUNCTIONS: dict[str, Callable[[float], float]] = {
    "SIN": lambda x: math.sin(math.radians(x)),
    "COS": lambda x: math.cos(math.radians(x)),
    "TAN": lambda x: math.tan(math.radians(x)),
    "ATAN": lambda x: math.degrees(math.atan(x)),
    "SQRT": math.sqrt,
    "ABS": abs,
    "ROUND": _round,
    "FIX": _fix,
    "FUP": _fup,
}

# postfix opcodes: a constant, a variable, a function of one operand, an operator of two
_CONST, _VAR, _UNARY, _BINARY = range(4)
_OPERATORS: dict[str, tuple[int, Callable[[float, float], float]]] = {
    "+": (1, operator.add),
    "-": (1, operator.sub),
    "*": (2, operator.mul),
    "/": (2, operator.truediv),
}
_NEGATE = "neg"  # a unary minus on the operator stack: binds tighter than * and /
_OPEN = ("[", "(")
_CLOSE = ("]", ")")


def variable(digits: str) -> int:
    """The number of variable ``#digits``; :class:`MacroError` past :data:`MAX_VARIABLE`."""
    if len(digits) > 5 or int(digits) > MAX_VARIABLE:
        raise MacroError(f"variable #{digits[:12]}{'…' if len(digits) > 12 else ''} does not exist")
    return int(digits)


@dataclass(frozen=True)
class Expr:
    """An arithmetic expression as postfix code (opcode, argument): called on the variables
    set so far (KeyError: one unset), it returns its value; :class:`MacroError` when an
    operation has no finite value (SQRT of a negative number, ROUND of an infinite one)."""

    code: tuple[tuple[int, object], ...]

    @property
    def nodes(self) -> int:
        """The evaluation's steps: one per node of the code."""
        return len(self.code)

    def __call__(self, variables: dict[int, float]) -> float:
        stack: list[float] = []
        try:
            for op, arg in self.code:
                if op == _CONST:
                    stack.append(arg)  # type: ignore[arg-type]
                elif op == _VAR:
                    stack.append(variables[arg])  # type: ignore[index]
                elif op == _UNARY:
                    stack.append(arg(stack.pop()))  # type: ignore[operator]
                else:
                    b = stack.pop()
                    stack.append(arg(stack.pop(), b))  # type: ignore[operator]
        except (OverflowError, ValueError) as exc:
            raise MacroError(f"an operation has no finite value ({exc})") from None
        value = stack[0]
        if not math.isfinite(value):
            raise MacroError(f"the expression's value is {value}, not a finite number")
        return value


@dataclass(frozen=True)
class Condition:
    """``a OP b`` of WHILE and IF: called on the variables, True or False."""

    left: Expr
    compare: Callable[[float, float], bool]
    right: Expr

    @property
    def nodes(self) -> int:
        return self.left.nodes + self.right.nodes + 1

    def __call__(self, variables: dict[int, float]) -> bool:
        return self.compare(self.left(variables), self.right(variables))


def _tokens(text: str) -> list[str]:
    """The expression's tokens, refused past :data:`MAX_TOKENS` before the rest is scanned."""
    found = []
    for k, match in enumerate(_TOKEN.finditer(text)):
        if k >= MAX_TOKENS:
            raise MacroError(
                f"an expression of more than {MAX_TOKENS:,} tokens: not one a lathe program needs"
            )
        found.append(match.group())
    return found


def parse(text: str) -> Expr:
    """The postfix code of an arithmetic expression (module docstring); :class:`MacroError`
    names what is not one."""
    tokens = _tokens(text.strip())
    if not tokens:
        raise MacroError("an expression ends early")
    code: list[tuple[int, object]] = []
    ops: list[str] = []  # operators, negations, functions and open brackets
    operand = True  # whether an operand (or a unary sign) is due next
    for k, tok in enumerate(tokens):
        if operand:
            operand = _operand(tok, tokens, k, code, ops)
        elif tok in _OPERATORS:
            _pop_operators(ops, code, _OPERATORS[tok][0])
            ops.append(tok)
            operand = True
        elif tok in _CLOSE:
            _close(ops, code)
        else:
            raise MacroError(f"cannot evaluate {' '.join(tokens[k : k + 4])[:40]!r} in {text.strip()[:40]!r}")
    if operand:
        raise MacroError("an expression ends early")
    _pop_operators(ops, code, 0)
    if ops:
        raise MacroError("an expression's bracket does not close")
    return Expr(tuple(code))


def _operand(tok: str, tokens: list[str], k: int, code: list[tuple[int, object]], ops: list[str]) -> bool:
    """Take ``tok`` where an operand is due; whether one is still due after it."""
    if tok == "-":
        ops.append(_NEGATE)
        return True
    if tok == "+" or tok in _OPEN:
        if tok in _OPEN:
            ops.append("[")
        return True
    if tok in FUNCTIONS:
        if k + 1 >= len(tokens) or tokens[k + 1] != "[":
            raise MacroError(f"{tok} takes its argument in brackets: {tok}[...]")
        ops.append(tok)
        return True
    if tok == "#":
        raise MacroError("an indirect variable (##i or #[...]) is not evaluated: name the variable")
    if tok.startswith("#"):
        code.append((_VAR, variable(tok[1:])))
        return False
    if _NUMBER.fullmatch(tok):
        code.append((_CONST, float(tok)))
        return False
    raise MacroError(f"cannot evaluate {tok[:20]!r}: not a number, a variable or a function the reader knows")


def _emit(op: str, code: list[tuple[int, object]]) -> None:
    if op == _NEGATE:
        code.append((_UNARY, operator.neg))
    elif op in FUNCTIONS:
        code.append((_UNARY, FUNCTIONS[op]))
    else:
        code.append((_BINARY, _OPERATORS[op][1]))


def _pop_operators(ops: list[str], code: list[tuple[int, object]], least: int) -> None:
    """Emit the stacked operators binding at least as tight as ``least`` (left-associative)."""
    while ops and ops[-1] != "[" and ops[-1] not in FUNCTIONS:
        top = ops[-1]
        if top != _NEGATE and _OPERATORS[top][0] < least:
            return
        _emit(ops.pop(), code)


def _close(ops: list[str], code: list[tuple[int, object]]) -> None:
    """A closing bracket: its group's operators, then the function it is the argument of."""
    _pop_operators(ops, code, 0)
    if not ops or ops[-1] != "[":
        raise MacroError("a closing bracket without its opening one")
    ops.pop()
    while ops and (ops[-1] in FUNCTIONS or ops[-1] == _NEGATE):
        _emit(ops.pop(), code)


def condition(text: str) -> Condition:
    """A condition ``a OP b`` (OP one of LT LE GT GE EQ NE)."""
    found = _CONDITION.match(text.strip())
    if not found:
        raise MacroError("a condition must be 'a LT|LE|GT|GE|EQ|NE b' (AND/OR are not evaluated)")
    return Condition(parse(found.group(1)), _COMPARE[found.group(2)], parse(found.group(3)))
