"""A controller header as the C compiler reads it (docs/architecture.md "Trust").

The header's text is preprocessed by a real C preprocessor (pcpp, a maintained pure-Python
implementation of C99 translation phases 1-4, so verify works where no compiler is
installed) and the resulting declarations are parsed by a C parser (pycparser). What comes
out is what a controller's firmware build would see: the object-like macros the file
defines (name and replacement text, comments removed) and the one table declaration (type,
name, dimensions, cells). Anything export does not write is refused, naming it: an
``#include`` other than ``<stdint.h>``, ``#undef``, a conditional other than the include
guard, a second definition, a function-like macro, a directive pcpp does not know, another
declaration.

The table's cells are not run through the preprocessor token by token (pcpp takes ~10 µs a
token: 10 s for a million cells). Instead the rows are first checked to be exactly what
export writes (``    {v, v, …},`` with decimal integers only), which contains no identifier,
comment, quote, backslash or directive, so C reads each row as the same tokens in any
context; the run of rows is replaced by one identifier (:data:`SENTINEL`) and the
preprocessed declaration must hold exactly that identifier as its initializer. If the rows
sat in a comment, a skipped conditional or a macro, the sentinel would too, and the
declaration would not hold it.
"""

from __future__ import annotations

import io
import re
from dataclasses import dataclass
from typing import Any

import numpy as np
from pcpp import Action, OutputDirective, Preprocessor

from ftsweep.errors import ExportError

# stands for the table's rows while the rest of the header is preprocessed
SENTINEL = "FTSWEEP_TABLE_ROWS_"
# a row as export writes it: four spaces, braces, decimal integers separated by ", " (no
# leading zero: C reads 012 as octal 10)
_INT = r"(?:0|-?[1-9][0-9]*)"
_ROW = re.compile(r"    \{" + _INT + r"(?:, " + _INT + r")*\},?")
# the typedefs <stdint.h> gives the two table types (the include itself is not followed)
_STDINT = "typedef short int16_t;\ntypedef int int32_t;\n"
# the table types export writes (their ranges: numpy's of the same width)
INT_TYPES = ("int16_t", "int32_t")
# the directives export writes, in this order: guard, its define, <stdint.h>, the macros, #endif
_GUARD, _DEFINE, _INCLUDE, _ENDIF = "ifndef", "define", "include", "endif"
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
# pcpp's tokens for a quote that starts no complete literal, and for character constants
# (export writes neither)
_STRAYS = frozenset({"CPP_DQUOTE", "CPP_SQUOTE", "CPP_CHAR"})


@dataclass(frozen=True)
class CView:
    """What C reads from a header: ``macros`` (name, replacement text) in definition order,
    the include guard's name, the table's element type (``int16_t``/``int32_t``), name and
    cells (an (rows, cols) int64 array, rows and cols the declared dimensions)."""

    macros: tuple[tuple[str, str], ...]
    guard: str
    int_type: str
    name: str
    cells: np.ndarray


def read_c(raw: bytes, where: str) -> CView:
    """The C view of a header's bytes; :class:`ExportError` naming the first thing export
    would not write. ``where`` names the file in messages."""
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError as exc:
        raise ExportError(
            f"{where} is not an ftsweep header: byte {exc.start} is not ASCII (export writes ASCII only)"
        ) from None
    lines = text.split("\n")
    first, last, cells = _rows(lines, where)
    stub = "\n".join([*lines[:first], SENTINEL, *lines[last:]])
    macros, guard, out = _preprocess(stub, where)
    int_type, name, dims = _declaration(out, where)
    if cells.shape != dims:
        raise ExportError(
            f"{where}: the table is declared [{dims[0]}][{dims[1]}] but its initializer holds "
            f"{cells.shape[0]} row(s) of {cells.shape[1]}; do not load it"
        )
    limits = np.iinfo(int_type[: -len("_t")])
    if cells.size and (cells.min() < limits.min or cells.max() > limits.max):
        raise ExportError(f"{where}: a table value does not fit {int_type}; do not load it")
    return CView(tuple(macros.items()), guard, int_type, name, cells)


def _rows(lines: list[str], where: str) -> tuple[int, int, np.ndarray]:
    """(first row's line index, index after the last, cells) of the one run of table rows."""
    rows = [i for i, line in enumerate(lines) if line.startswith("    {")]
    if not rows:
        raise ExportError(f"{where}: no table rows found (lines '    {{v, v, ...}},'); do not load it")
    first, last = rows[0], rows[-1] + 1
    if last - first != len(rows):
        raise ExportError(f"{where}: line {rows[-1] + 1}: a table row outside the table; do not load it")
    body = "\n".join(lines[first:last])
    for k, line in enumerate(lines[first:last]):
        if _ROW.fullmatch(line) is None or line.endswith(",") == (k == last - first - 1):
            raise ExportError(
                f"{where}: line {first + k + 1} is not a table row as export writes it "
                f"('    {{v, v, ...}},' with decimal integers; no comma after the last){_fault(line)}; "
                "do not load it"
            )
    width = lines[first].count(",") + 1 - (1 if lines[first].endswith(",") else 0)
    flat = np.array(body.translate(str.maketrans("{},", "   ")).split(), dtype=np.int64)
    if flat.size != width * (last - first):
        raise ExportError(f"{where}: the table's rows do not all hold {width} values; do not load it")
    return first, last, flat.reshape(last - first, width)


def _fault(row: str) -> str:
    """Where a table row first leaves export's form: the value that is not an integer."""
    at = 5
    for value in row[5:].rstrip(",}").split(", "):
        if re.fullmatch(_INT, value) is None:
            return f": column {at + 1} holds {value[:40]!r}, not an integer as export writes one"
        at += len(value) + 2
    return ""


class _Strict(Preprocessor):  # type: ignore[misc]
    """pcpp refusing, with :class:`ExportError`, every directive export does not write:
    anything but the guard, object-like ``#define``s of new names, ``#include <stdint.h>``
    (never looked up) and the last ``#endif``."""

    def __init__(self, where: str) -> None:
        super().__init__()
        self.line_directive = None
        self.where = where
        self.order: list[str] = []
        self.defined: dict[str, int] = {}
        self.guard = ""

    def refuse(self, line: int, what: str) -> ExportError:
        return ExportError(f"{self.where}: line {line}: {what}; do not load it")

    def on_error(self, file: str, line: int, msg: str) -> None:
        raise self.refuse(line, f"the C preprocessor refuses it ({msg})")

    def on_directive_unknown(self, directive, toks, ifpassthru, precedingtoks):  # type: ignore[no-untyped-def]
        raise self.refuse(directive.lineno, f"#{directive.value} is not written by export")

    def on_comment(self, tok):  # type: ignore[no-untyped-def]
        return False  # a comment is white space to C (translation phase 3)

    def on_directive_handle(self, directive, toks, ifpassthru, precedingtoks):  # type: ignore[no-untyped-def]
        line, kind = directive.lineno, directive.value
        self.order.append(kind)
        if any(t.type in _STRAYS for t in toks):
            raise self.refuse(line, "a quote that opens no string literal (compilers differ on the rest)")
        values = [t.value for t in toks]
        if "/*" in "".join(values):  # pcpp lexes an unterminated comment as '/' '*'; C refuses it
            raise self.refuse(line, "a comment that never ends")
        words = [t for t in values if t.strip()]
        check = {_INCLUDE: self._include, _DEFINE: self._define, _GUARD: self._guard, _ENDIF: self._endif}
        if kind not in check:
            raise self.refuse(line, f"#{kind} is not written by export")
        check[kind](line, values, words)
        if kind == _DEFINE:
            self._literal(line, words[0], [t for t in toks[1:] if t.type == "CPP_ID"])
        if kind == _INCLUDE:
            raise OutputDirective(Action.IgnoreAndRemove)  # <stdint.h> is never looked up
        return True

    def _include(self, line: int, values: list[str], words: list[str]) -> None:
        if "".join(words) != "<stdint.h>":
            raise self.refuse(line, f"#include {''.join(words)[:60]} is not written by export")

    def _define(self, line: int, values: list[str], words: list[str]) -> None:
        name = words[0] if words else ""
        after = values[1] if len(values) > 1 else " "
        if _IDENT.fullmatch(name) is None or values[0] != name or (after.strip() and after != "("):
            raise self.refuse(line, f"#define of {name[:60]!r}, not an identifier and a space")
        if name in self.defined or name in self.macros:
            raise self.refuse(line, f"a second definition of {name[:60]}")
        if after == "(":
            raise self.refuse(line, f"{name[:60]} is a function-like macro")
        self.defined[name] = line

    def _literal(self, line: int, name: str, identifiers: list[Any]) -> None:
        """Judged before anything is expanded: export's replacements are literals (numbers,
        strings, a brace list of numbers), so one holding an identifier is refused here, a
        macro defined before it or after it alike (a chain defined forwards expands only at its
        use, after the last definition); chained macros would double their expansion at every
        level, and without them what C expands is at most the file's own tokens once per use."""
        if not identifiers:
            return
        word = identifiers[0].value
        what = f"names the macro {word[:60]}" if word in self.macros else f"holds the identifier {word[:60]}"
        raise self.refuse(
            line,
            f"{name[:60]}'s replacement {what} (export's replacements are literals: numbers and "
            "strings); nothing expanded",
        )

    def _guard(self, line: int, values: list[str], words: list[str]) -> None:
        if len(self.order) != 1 or len(words) != 1 or _IDENT.fullmatch(words[0]) is None:
            raise self.refuse(line, "a conditional other than the include guard")
        self.guard = words[0]

    def _endif(self, line: int, values: list[str], words: list[str]) -> None:
        if words:
            raise self.refuse(line, "text after #endif")


def _preprocess(stub: str, where: str) -> tuple[dict[str, str], str, str]:
    """The macros the header defines (name → replacement text, in definition order, the
    guard left out), its include guard and the preprocessed text, refusing any directive
    export does not write (:class:`_Strict`) or not in export's order."""
    pp = _Strict(where)
    pp.parse(stub, "header.h")
    buffer = io.StringIO()
    pp.write(buffer)
    out = buffer.getvalue()
    if "/*" in out:
        raise ExportError(f"{where}: a comment that never ends; do not load it")
    if pp.order[:3] != [_GUARD, _DEFINE, _INCLUDE] or pp.order[-1] != _ENDIF or _ENDIF in pp.order[:-1]:
        raise ExportError(
            f"{where}: the directives are not export's (#ifndef guard, #define guard, #include <stdint.h>, "
            f"#define ..., #endif): found {', '.join('#' + d for d in pp.order[:8])}; do not load it"
        )
    guard = next(iter(pp.defined), "")
    if guard != pp.guard:
        raise ExportError(f"{where}: the include guard's #define is not the name its #ifndef tests")
    macros = {name: _replacement(pp.macros[name].value) for name in pp.defined if name != guard}
    return macros, guard, out


def _replacement(tokens: list) -> str:  # type: ignore[type-arg]
    """A macro's replacement list as text, each run of white space (comments included) one
    space, none at the ends: C99 6.10.3p1 holds such runs identical, as gcc's -dM prints them."""
    parts: list[str] = []
    for tok in tokens:
        if tok.type in ("CPP_WS", "CPP_COMMENT1", "CPP_COMMENT2") or not tok.value.strip():
            if parts and parts[-1] != " ":
                parts.append(" ")
        else:
            parts.append(tok.value)
    return "".join(parts).strip()


def _declaration(out: str, where: str) -> tuple[str, str, tuple[int, int]]:
    """(element type, name, (rows, cols)) of the one declaration of the preprocessed text,
    which must be ``static const T name[R][C] = {SENTINEL};``."""
    from pycparser import c_ast, c_parser

    try:
        ast = c_parser.CParser().parse(_STDINT + out, "header.h")
    except Exception as exc:  # pycparser raises its ParseError and plain AssertionErrors
        raise ExportError(
            f"{where}: C cannot parse what the preprocessor leaves ({str(exc)[:160]})"
        ) from None
    decls = ast.ext[2:]
    bad = ExportError(
        f"{where}: C reads other declarations than export's one table "
        "'static const intN_t NAME[ROWS][COLS] = {rows};': the rows sit in a comment, a conditional or "
        "a macro, or something was added; do not load it"
    )
    if len(decls) != 1 or not isinstance(decls[0], c_ast.Decl):
        raise bad
    d = decls[0]
    outer = d.type
    inner = getattr(outer, "type", None)
    leaf = getattr(inner, "type", None)
    init = d.init
    if not (
        d.storage == ["static"]
        and isinstance(outer, c_ast.ArrayDecl)
        and isinstance(inner, c_ast.ArrayDecl)
        and isinstance(leaf, c_ast.TypeDecl)
        and leaf.quals == ["const"]
        and isinstance(leaf.type, c_ast.IdentifierType)
        and len(leaf.type.names) == 1
        and leaf.type.names[0] in INT_TYPES
        and isinstance(init, c_ast.InitList)
        and len(init.exprs) == 1
        and isinstance(init.exprs[0], c_ast.ID)
        and init.exprs[0].name == SENTINEL
    ):
        raise bad
    dims = []
    for array in (outer, inner):
        dim = array.dim
        if not (isinstance(dim, c_ast.Constant) and dim.type == "int" and dim.value.isdigit()):
            raise bad
        dims.append(int(dim.value))
    return leaf.type.names[0], str(d.name), (dims[0], dims[1])
