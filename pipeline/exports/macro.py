"""The macro language of ISO controllers (Fanuc Custom Macro B, as the Moore and most STS
controllers run it) as far as a path program needs it: arithmetic on numbers and variables
(+ − * /, [ ] grouping, SIN COS TAN ATAN SQRT ABS ROUND FIX FUP, angles in degrees) and the
conditions LT LE GT GE EQ NE of WHILE and IF (docs/controllers.md). An expression is parsed
once by a small recursive-descent parser into a tree of closures evaluated on the variables as
they are: never by Python's ``eval``."""

from __future__ import annotations

import math
import re
from collections.abc import Callable

# an expression parsed once: evaluated on the variables set so far (KeyError: one unset)
Expr = Callable[[dict[int, float]], float]


class MacroError(ValueError):
    """An expression or condition the macro language does not define (the reader adds the line)."""


_TOKEN = re.compile(r"#\d+|\d+\.?\d*|\.\d+|[A-Z]+|[-+*/\[\]()]|\S")
_NUMBER = re.compile(r"\d+\.?\d*|\.\d+")
_CONDITION = re.compile(r"^(.+?)\s*\b(LT|LE|GT|GE|EQ|NE)\b\s*(.+)$")
_COMPARE: dict[str, Callable[[float, float], bool]] = {
    "LT": lambda a, b: a < b,
    "LE": lambda a, b: a <= b,
    "GT": lambda a, b: a > b,
    "GE": lambda a, b: a >= b,
    "EQ": lambda a, b: a == b,
    "NE": lambda a, b: a != b,
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


def _binary(op: str, a: Expr, b: Expr) -> Expr:
    if op == "+":
        return lambda v: a(v) + b(v)
    if op == "-":
        return lambda v: a(v) - b(v)
    if op == "*":
        return lambda v: a(v) * b(v)
    return lambda v: a(v) / b(v)


def _apply(f: Callable[[float], float], a: Expr) -> Expr:
    return lambda v: f(a(v))


def parse(text: str) -> Expr:
    """The closure of an arithmetic expression; :class:`MacroError` names what is not one."""
    tokens = _TOKEN.findall(text.strip())
    value, rest = _sum(tokens)
    if rest:
        raise MacroError(f"cannot evaluate {' '.join(rest)[:40]!r} in {text.strip()[:40]!r}")
    return value


def _chain(
    t: list[str], ops: tuple[str, str], operand: Callable[[list[str]], tuple[Expr, list[str]]]
) -> tuple[Expr, list[str]]:
    """Operands joined by the left-associative operators ``ops`` (one precedence level)."""
    value, t = operand(t)
    while t and t[0] in ops:
        op, (rhs, t) = t[0], operand(t[1:])
        value = _binary(op, value, rhs)
    return value, t


def _sum(t: list[str]) -> tuple[Expr, list[str]]:
    return _chain(t, ("+", "-"), _product)


def _product(t: list[str]) -> tuple[Expr, list[str]]:
    return _chain(t, ("*", "/"), _atom)


def _atom(t: list[str]) -> tuple[Expr, list[str]]:
    if not t:
        raise MacroError("an expression ends early")
    head = t[0]
    if head in ("+", "-"):
        value, rest = _atom(t[1:])
        return (_apply(lambda x: -x, value) if head == "-" else value), rest
    if head in ("[", "("):
        value, rest = _sum(t[1:])
        if not rest or rest[0] not in ("]", ")"):
            raise MacroError("an expression's bracket does not close")
        return value, rest[1:]
    if head in FUNCTIONS:
        if len(t) < 2 or t[1] != "[":
            raise MacroError(f"{head} takes its argument in brackets: {head}[...]")
        arg, rest = _atom(t[1:])
        return _apply(FUNCTIONS[head], arg), rest
    if head.startswith("#"):
        k = int(head[1:])
        return (lambda v: v[k]), t[1:]
    if _NUMBER.fullmatch(head):
        c = float(head)
        return (lambda v: c), t[1:]
    raise MacroError(f"cannot evaluate {head!r}: not a number, a variable or a function the reader knows")


def condition(text: str) -> Callable[[dict[int, float]], bool]:
    """The closure of a condition ``a OP b`` (OP one of LT LE GT GE EQ NE)."""
    found = _CONDITION.match(text.strip())
    if not found:
        raise MacroError("a condition must be 'a LT|LE|GT|GE|EQ|NE b' (AND/OR are not evaluated)")
    a, op, b = parse(found.group(1)), _COMPARE[found.group(2)], parse(found.group(3))
    return lambda v: op(a(v), b(v))
