"""A controller header read back as the controller reads it (:mod:`ftsweep.kinds.table.header`
writes it): through a real C preprocessor and parser (:mod:`ftsweep.kinds.table.c_view`), its
CRC checked, every line compared with what export would write for the recorded case, its table
with the re-planned one, and the machined surface re-simulated from the stored integers; the
header's file format (:func:`header_format`) and its compiled C reference check.
"""

from __future__ import annotations

import functools
import hashlib
import json
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ftsweep.engine.contract import FileFormat
from ftsweep.errors import ExportError
from ftsweep.exports.files import layer_schedule, pv_lines, recorded_case_of, sidecar_digest
from ftsweep.exports.fingerprint import exact_on_this_platform
from ftsweep.kinds.table.c_view import read_c
from ftsweep.kinds.table.header import (
    CHECKSUM_MACRO,
    LE_DTYPE,
    c_string,
    checksum,
    export_header,
    header_macros,
    header_meta,
    planned_ints,
    render_header,
)
from ftsweep.kinds.table.layout import build_layout
from ftsweep.simulate import resolve_case, run_case
from ftsweep.store.io import read_regular, read_sidecar, sidecar_of

# a header holds at most a controller's table: this bounds what verify reads
MAX_HEADER_BYTES = 200 * 2**20


def read_header(path: Path, raw: bytes | None = None) -> tuple[list[tuple[str, str]], np.ndarray]:
    """:func:`read_c_header` without the prefix."""
    macros, ints, _ = read_c_header(path, raw)
    return macros, ints


def read_c_header(path: Path, raw: bytes | None = None) -> tuple[list[tuple[str, str]], np.ndarray, str]:
    """The macros (name without prefix, replacement text as C reads it, in header order) and
    the integer table of a header, read as C reads it (:func:`ftsweep.kinds.table.c_view.read_c`:
    a real preprocessor and parser), and the identifiers' prefix; :class:`ExportError` if it
    is not what export writes in form. ``raw``: the file's bytes, read already."""
    path = Path(path)
    raw = read_regular(path, MAX_HEADER_BYTES, "header") if raw is None else raw
    view = read_c(raw, str(path))
    prefix = view.guard[:-2]
    if not view.guard.endswith("_H") or view.name != prefix.lower() + "_table":
        raise ExportError(
            f"{path}: the include guard {view.guard[:60]} and the table {view.name[:60]} do not share "
            "export's prefix (PREFIX_H, prefix_table); do not load it"
        )
    strays = [k for k, _ in view.macros if not k.startswith(prefix + "_")]
    if strays:
        raise ExportError(
            f"{path}: macro {strays[0][:60]} does not carry the prefix {prefix}_; do not load it"
        )
    macros = [(k[len(prefix) + 1 :], v) for k, v in view.macros]
    found = dict(macros)
    missing = [k for k in ("ROWS", "COLS", "INT_TYPE", "UNIT_NM", CHECKSUM_MACRO) if k not in found]
    if missing:
        raise ExportError(f"{path} is not a complete ftsweep header (missing {', '.join(missing)})")
    if found["INT_TYPE"] != c_string(view.int_type[:-2]):
        raise ExportError(
            f"{path}: the table is declared {view.int_type} but INT_TYPE says {found['INT_TYPE'][:40]}"
        )
    if (found["ROWS"], found["COLS"]) != tuple(str(n) for n in view.cells.shape):
        raise ExportError(
            f"{path}: the table holds {view.cells.shape[0]} × {view.cells.shape[1]} values, the macros say "
            f"{found['ROWS'][:20]} × {found['COLS'][:20]}; do not load it"
        )
    return macros, view.cells, prefix


def _macro_value(macros: dict[str, str], name: str, kind: Callable[[str], Any], path: Path) -> Any:
    try:
        return kind(macros[name])
    except (KeyError, ValueError) as exc:
        raise ExportError(f"{path}: macro {name} is missing or malformed ({exc})") from None


def default_pv_tolerance_nm(unit_nm: float, pv_nm: float) -> float:
    """Allowed |re-simulated − predicted| P-V [nm]. Quantisation moves each table value by at
    most half a unit; interpolation is a convex combination and the envelope of arcs shifted
    by at most δ moves by at most δ, so the error's extremes each move by at most half a unit
    and the P-V by at most one unit. 0.1 % of the P-V is added for floating-point noise."""
    return unit_nm + 1e-3 * pv_nm


def check_integrity(path: Path) -> tuple[dict[str, str], np.ndarray, dict[str, Any], str, bytes]:
    """The macros (as C reads them), table, sidecar, identifiers' prefix and bytes of a
    header whose CRC-32 (over every macro and the table), sidecar CRC, header SHA-256 (in
    the sidecar) and sidecar SHA-256 (in the header) all match; :class:`ExportError`
    naming the first that does not."""
    raw = read_regular(path, MAX_HEADER_BYTES, "header")
    macro_list, ints, prefix = read_c_header(path, raw)
    macros = dict(macro_list)
    stored = _stored_checksum(macros, macro_list, ints, path)
    meta = read_sidecar(path)
    side = sidecar_of(path)
    try:
        header_sha = meta["header_sha256"]
        recorded_crc = int(meta["crc32"])
    except (ValueError, KeyError, TypeError) as exc:
        raise ExportError(
            f"{side} is not an ftsweep sidecar ({type(exc).__name__}: {str(exc)[:100]})"
        ) from None
    if recorded_crc != stored:
        raise ExportError(f"{side} belongs to another table (checksum 0x{recorded_crc:08x})")
    if hashlib.sha256(raw).hexdigest() != header_sha:
        raise ExportError(
            f"{path} differs from the header the sidecar was written with (SHA-256 mismatch): the header "
            "was edited, or header and sidecar come from different exports; do not load it"
        )
    side_sha = _macro_value(macros, "SIDECAR_SHA256", json.loads, path)
    if sidecar_digest(meta) != side_sha:
        raise ExportError(
            f"{side} was changed after export (its SHA-256 does not match the header's SIDECAR_SHA256); "
            "re-export instead of editing it"
        )
    return macros, ints, meta, prefix, raw


def _stored_checksum(
    macros: dict[str, str], macro_list: list[tuple[str, str]], ints: np.ndarray, path: Path
) -> int:
    """The header's CRC-32, checked against its macros and table."""
    try:
        int_type = json.loads(macros["INT_TYPE"])
        stored = int(macros[CHECKSUM_MACRO].rstrip("UuLl"), 16)
    except ValueError:
        raise ExportError(f"{path}: macro INT_TYPE or {CHECKSUM_MACRO} is malformed") from None
    if int_type not in LE_DTYPE:
        raise ExportError(f"{path}: INT_TYPE {int_type!r} is not one of {', '.join(LE_DTYPE)}")
    actual = checksum(macro_list, ints, int_type)
    if stored != actual:
        raise ExportError(
            f"{path}: checksum mismatch (header says 0x{stored:08x}, macros and table give 0x{actual:08x}): "
            "a macro or the table was changed or damaged; do not load it"
        )
    return stored


def verify_header(
    path: Path,
    progress: Callable[[int, int], None] | None = None,
    pv_tolerance_nm: float | None = None,
    trust_plugins: bool = False,
) -> dict[str, Any]:
    """Check a header as the controller will read it, then re-simulate the part.

    A header passes only if: its CRC-32 (over every macro and the table), the sidecar's
    SHA-256 of the header and the header's SHA-256 of the sidecar match; the whole text is
    exactly what export writes for the recorded case (every macro value, the layer schedule,
    no comment or expression inside a value, no other line), so what C reads is what was
    checked; every table cell lies within one unit of the table the recorded case plans; and
    the P-V re-simulated from the stored integers is within ``pv_tolerance_nm`` (default
    :func:`default_pv_tolerance_nm`) of the predicted one. Raises :class:`ExportError` naming
    the first difference.
    """
    path = Path(path)
    macros, ints, meta, prefix, raw = check_integrity(path)
    case, specs = recorded_case_of(meta, sidecar_of(path), trust_plugins)
    surface, machine, _ = specs
    try:
        layout = build_layout(surface, case.layout)
    except ValueError as exc:
        raise ExportError(f"{path}: the recorded case plans no table ({exc})") from None
    exact, _ = exact_on_this_platform(meta.get("platform"))
    check_table(ints, planned_ints(case, specs, layout), path, 0 if exact else TABLE_UNITS_TOLERANCE)
    unit_nm = machine.table_unit_nm
    table = ints * unit_nm * 1e-3
    expected = header_meta(
        case, specs, layout, float(meta["pv_nm"]), str(meta["created"]), str(meta["generator"])
    )
    expected["layers"] = layer_schedule(resolve_case(case, specs=specs), table)
    expected["sidecar_sha256"] = sidecar_digest(meta)
    check_macros(macros, expected, ints, machine.table_int_type, path)
    check_canonical(
        raw.decode("ascii"), render_header(prefix, expected, ints, machine.table_int_type)[0], path, prefix
    )
    predicted = float(meta["pv_nm"])
    record = run_case(case, table=table, specs=specs, progress=progress)
    tol = default_pv_tolerance_nm(unit_nm, predicted) if pv_tolerance_nm is None else pv_tolerance_nm
    record["predicted_pv_nm"] = predicted
    record["pv_tolerance_nm"] = tol
    record["checksum"] = f"0x{int(meta['crc32']):08x}"
    record["header"] = str(path)
    if not abs(record["pv_nm"] - predicted) <= tol:
        raise ExportError(
            f"{path}: the table re-simulates to P-V {record['pv_nm']:.3f} nm, not the predicted "
            f"{predicted:.3f} nm (difference {record['pv_nm'] - predicted:+.3f} nm, tolerance {tol:.3f} nm); "
            "the header does not machine what was selected: do not load it"
        )
    return record


# across platforms cells may differ from a re-planned table by one unit: the planned values
# are rounded to the unit, so a last-bit difference at a half-unit boundary can flip one
TABLE_UNITS_TOLERANCE = 1


def check_table(ints: np.ndarray, planned: np.ndarray, path: Path, tolerance: int) -> None:
    """Refuse a table whose shape differs from the re-planned one or any of whose cells lies
    more than ``tolerance`` units from it (0 on the platform the file was planned on,
    :data:`TABLE_UNITS_TOLERANCE` across platforms:
    :func:`~ftsweep.exports.fingerprint.exact_on_this_platform`), naming the first such cell."""
    if ints.shape != planned.shape:
        raise ExportError(
            f"{path}: the table is {ints.shape[0]} × {ints.shape[1]}, the recorded case plans "
            f"{planned.shape[0]} × {planned.shape[1]}; do not load it"
        )
    diff = np.abs(ints.astype(np.int64) - planned.astype(np.int64))
    if diff.max(initial=0) > tolerance:
        off = diff > tolerance
        i, j = (int(v) for v in np.argwhere(off)[0])
        raise ExportError(
            f"{path}: table cell [{i}][{j}] holds {int(ints[i, j])}, the recorded case plans "
            f"{int(planned[i, j])} ({int(off.sum()):,} cell(s) differ by more than "
            f"{tolerance} unit); do not load it"
        )


def check_macros(
    macros: dict[str, str], expected: dict[str, Any], ints: np.ndarray, int_type: str, path: Path
) -> None:
    """Refuse a header whose macros, as C reads them (name, replacement text, order), are
    not the ones export writes for the recorded case (``expected``: :func:`header_meta` of
    it); names the first macro that differs."""
    want = [(n, v) for n, v, _ in header_macros(expected, ints.shape, int_type)]
    want.append((CHECKSUM_MACRO, f"0x{checksum(want, ints, int_type):08x}UL"))
    wanted = dict(want)
    for name in [*macros, *wanted]:
        if macros.get(name) != wanted.get(name):
            got, value = macros.get(name), wanted.get(name)
            raise ExportError(
                f"{path}: C reads macro {name[:60]} as {str(got)[:120]!r}, but the recorded case gives "
                f"{str(value)[:120]!r}; do not load it"
            )
    if list(macros) != list(wanted):
        raise ExportError(f"{path}: the macros are not in export's order; do not load it")


def check_canonical(text: str, expected: str, path: Path, prefix: str) -> None:
    """Refuse a header whose text is not exactly the one export writes for the recorded case
    (table excepted, which :func:`check_table` judges): a macro's value, a comment or an
    expression inside a value, or any other line that C would read differently from the
    values checked. Names the macro, or the line, that differs."""
    got, want = text.split("\n"), expected.split("\n")
    for number, (a, b) in enumerate(zip(got, want, strict=False), start=1):
        if a != b:
            raise ExportError(_difference(path, number, a, b, prefix))
    if len(got) != len(want):
        raise ExportError(
            f"{path}: the header has {len(got)} lines where export writes {len(want)}: it was edited; "
            "do not load it"
        )


def _difference(path: Path, number: int, got: str, want: str, prefix: str) -> str:
    m = re.match(rf"#define {re.escape(prefix)}_(\w+)\s", want)
    if m:
        value = want.split(None, 2)[2]
        return (
            f"{path}: macro {m.group(1)} reads {got.split(None, 2)[-1][:120]!r} on line {number}, but the "
            f"recorded case gives {value[:120]!r} (a value must be written exactly as export writes it: no "
            "other value, expression or comment); do not load it"
        )
    return (
        f"{path}: line {number} reads {got[:120]!r} where export writes {want[:120]!r}: the header was "
        "edited; do not load it"
    )


@functools.cache
def header_format() -> FileFormat:
    """The controller header's file format (ring and mesh tables)."""

    def exported(out: Path, meta: dict[str, Any]) -> list[str]:
        return [
            f"header       {out} ({meta['shape'][0]} × {meta['shape'][1]} {meta['int_type']}, "
            f"unit {meta['unit_nm']} nm, CRC-32 0x{meta['crc32']:08x})"
        ]

    def verified(record: dict[str, Any]) -> list[str]:
        return [
            f"checksum     {record['checksum']} (macros and table) ok; sidecar and file hashes ok",
            f"table        {record['layout']}: {record['n_points']:,} points, "
            "every macro and cell as re-planned",
            *pv_lines(record, "the stored integers"),
        ]

    return FileFormat(
        "controller header",
        None,
        export_header,
        verify_header,
        exported,
        verified,
        compiled=compiled_check,
    )


def compiled_check(path: Path, trust_plugins: bool = False) -> dict[str, Any]:
    """The compiled C reference's commands from a header verify has read already, against the
    simulator's (:func:`ftsweep.exports.compiled.check_header`)."""
    from ftsweep.exports.compiled import check_header
    from ftsweep.exports.files import recorded_case_of
    from ftsweep.store.io import sidecar_of

    _, ints, meta, _, _ = check_integrity(Path(path))
    case, specs = recorded_case_of(meta, sidecar_of(Path(path)), trust_plugins)
    layout = build_layout(specs.surface, case.layout)
    return check_header(path, layout, ints * specs.machine.table_unit_nm * 1e-3)
