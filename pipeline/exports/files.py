"""The file machinery every exported kind shares: sidecars (path, digest, the recorded case
and entries), the layer schedule a layered file carries, atomic writing with ``--force``, and
for plain-text programs their CRC over every line, reading, and the line-by-line comparison
with the program the recorded case plans again (:func:`check_document`). The formats
themselves live with their kinds (``ftsweep.kinds.<kind>``), above this layer;
:mod:`ftsweep.tools.export` dispatches between them.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ftsweep.engine.case import Case
from ftsweep.engine.planning import ResolvedCase, layer_plan
from ftsweep.errors import ExportError
from ftsweep.exports.fingerprint import exact_on_this_platform
from ftsweep.inputs.case_entries import Entries
from ftsweep.inputs.catalogs import CatalogError
from ftsweep.inputs.trust import specs_from_entries
from ftsweep.stages.interpolation.spiral_program import spiral_radius
from ftsweep.stages.numerics import decimals
from ftsweep.store.io import (
    MAX_PROGRAM_BYTES,
    check_sidecar_text,
    dumps_json,
    older_sidecar_path,
    read_regular,
    read_sidecar,
    sidecar_of,
    sidecar_path,
    write_texts_atomic,
)

# the export's time stamp and its place in the cube's ledger (:mod:`ftsweep.store.ledger`):
# provenance beside the file, not part of what the machine runs, so the same case exported
# twice gives the same file, byte for byte (a signature covers them)
STAMP_FIELDS = ("created", "ledger")


def sidecar_digest(sidecar: dict[str, Any], text_fields: tuple[str, ...] = ("crc32", "header_sha256")) -> str:
    """SHA-256 of a sidecar's content without the fields that depend on the exported text
    (``text_fields``: for a header ``crc32`` and ``header_sha256``) and without its time stamp
    (:data:`STAMP_FIELDS`): the header's ``SIDECAR_SHA256`` macro (a program's ``# sidecar:``
    line) holds it."""
    core = {k: v for k, v in sidecar.items() if k not in text_fields and k not in STAMP_FIELDS}
    text = dumps_json(core, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def recorded_entries(specs: Entries) -> dict[str, Any]:
    """The (surface, machine, cutting) entries as a sidecar records them."""
    keys = ("surface", "machine", "cutting")
    return {key: spec.model_dump(mode="json") for key, spec in zip(keys, specs, strict=True)}


def case_meta(
    layout: str,
    case: Case,
    specs: Entries,
    chosen: dict[str, Any],
    extra: dict[str, Any],
    stamp: tuple[str, str],
    n_points: int,
    own: dict[str, Any],
) -> dict[str, Any]:
    """The sidecar content of a path program exported from a cube case: generator and time
    (``stamp``), its kind, points, surface and compensation, its ``own`` fields, the predicted
    P-V, the export's ``extra``, the selection, the case and the catalog entries. Refuses a
    case that plans another number of points than the cube recorded."""
    if n_points != chosen["n_points"]:
        raise ProgramError(f"the cube says {chosen['n_points']} points but the spec plans {n_points}")
    return {
        "generator": stamp[1],
        "created": stamp[0],
        "layout": layout,
        "n_points": n_points,
        "surface": case.surface,
        "compensation": case.compensation,
        **own,
        "pv_nm": chosen["pv_nm"],
        **extra,
        "selection": {k: v for k, v in chosen.items() if not isinstance(v, (list, dict)) or k == "case"},
        "case": case.model_dump(mode="json"),
        "catalog_entries": recorded_entries(specs),
    }


def recorded_case_of(meta: dict[str, Any], side: Path, trust_plugins: bool = False) -> tuple[Case, Entries]:
    """The case and (surface, machine, cutting) specs a sidecar ``side`` recorded;
    :class:`ExportError` if they cannot be read. A plug-in the sidecar names must be one of
    the local catalog's unless ``trust_plugins`` (:func:`~ftsweep.inputs.trust.specs_from_entries`)."""
    try:
        entries = meta["catalog_entries"]
        parts = (entries["surface"], entries["machine"], entries["cutting"])
        case = Case.model_validate(meta["case"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ExportError(f"{side}: the recorded case cannot be read ({str(exc)[:200]})") from None
    try:
        specs = specs_from_entries(*parts, trust_plugins=trust_plugins)
    except CatalogError as exc:
        raise ExportError(f"{side}: {exc}") from None
    except (TypeError, ValueError) as exc:
        raise ExportError(f"{side}: the recorded catalog entries cannot be read ({str(exc)[:200]})") from None
    return case, specs


# a controller's layer schedule is a short list: beyond this the part is not one for layers
MAX_EXPORT_SEGMENTS = 100_000


def layer_schedule(rcase: ResolvedCase, values: Any) -> dict[str, Any] | None:
    """The layer schedule ([3]) of a case whose commands ``values`` [µm] (the table or
    program as exported) exceed the travel, as a controller runs it: per layer its Z offset
    [µm] and start radius [µm]; per segment its layer and the accumulated spindle angles
    [deg] where it starts and ends (C = φ mod 360, X = ρ0 − F·φ/360). None for one pass."""
    plan = layer_plan(rcase, np.asarray(values, dtype=np.float64))
    if plan is None:
        return None
    if plan.n_segments > MAX_EXPORT_SEGMENTS:
        raise ExportError(
            f"the layered plan has {plan.n_segments:,} segments, more than a controller's schedule "
            f"({MAX_EXPORT_SEGMENTS:,}); nothing exported: use a longer stroke"
        )
    return {
        "n_layers": plan.n_layers,
        "zone_um": plan.zone_um,
        "margin_um": plan.margin_um,
        "travel_um": plan.travel_um,
        "rho0_um": rcase.rho0_um,
        "offset_um": plan.offsets_um.tolist(),
        "start_radius_um": spiral_radius(plan.first_phi, rcase.rho0_um, rcase.feed_um).tolist(),
        "segment_layer": plan.seg_layer.tolist(),
        "segment_phi_deg": np.degrees(np.column_stack((plan.seg_start, plan.seg_end))).tolist(),
    }


class ProgramError(ExportError):
    """A program file cannot be trusted; the message says why."""


# the one CRC line of a program: it covers every other line of the file
CRC_LINE = "# CRC32: 0x{:08x} over every other line"

# How far a program line may lie from the re-planned one across platforms, per column unit:
# 1 µs, 1e-6°, 1e-6 mm = 1 nm (lines are printed to 1 ns, 1e-9° and 1 pm, so a last-bit
# difference of another platform lies far inside). On the platform a file was planned on
# every number must equal the re-planned one (ftsweep.exports.fingerprint).
LINE_TOLERANCE = {"s": 1e-6, "deg": 1e-6, "mm": 1e-6}


# the sidecar fields that depend on the program's text (left out of the sidecar's digest)
TEXT_FIELDS = ("program", "program_sha256", "crc32")


def crc_of(rows: list[str]) -> int:
    """CRC-32 of the file's lines but its CRC line, joined by newlines."""
    return zlib.crc32("\n".join(rows).encode("utf-8")) & 0xFFFFFFFF


# digits after the point of every number of a program's data lines: 1 ns, 1e-9 deg, 1e-9 mm
DECIMALS = 9


class DataLines:
    """A program's data lines: one row of numbers a line (planned values, shape (lines,
    columns)), each printed with :data:`DECIMALS` decimals as Python's ``format(v, ".9f")``
    would, single spaces between (:mod:`ftsweep.stages.numerics.decimals`, at compiled speed).
    ``printed``: the numbers as the machine reads them back from the text."""

    def __init__(self, values: np.ndarray) -> None:
        values = np.asarray(values, dtype=np.float64)
        if values.ndim != 2:
            raise ValueError(f"data lines need a (lines, columns) array, got shape {values.shape}")
        self.values = values
        self._fixed: decimals.Fixed | None = None
        self._encoded: bytes | None = None
        self._printed: np.ndarray | None = None

    @classmethod
    def of(cls, *columns: np.ndarray) -> DataLines:
        """The lines whose columns are ``columns`` (1-D arrays of one length)."""
        return cls(np.column_stack([np.asarray(c, dtype=np.float64) for c in columns]))

    def __len__(self) -> int:
        return int(self.values.shape[0])

    @property
    def fixed(self) -> decimals.Fixed:
        """The numbers as printed, in units of the last decimal (text and read-back share it)."""
        if self._fixed is None:
            self._fixed = decimals.fixed(self.values, DECIMALS)
        return self._fixed

    @property
    def encoded(self) -> bytes:
        """The lines joined by newlines (none after the last), ASCII: as written to the file."""
        if self._encoded is None:
            self._encoded = decimals.rows_bytes(self.fixed) if len(self) else b""
        return self._encoded

    @property
    def printed(self) -> np.ndarray:
        """The numbers as printed and read back, shape of ``values``."""
        if self._printed is None:
            self._printed = decimals.printed(self.fixed)
        return self._printed


def now() -> str:
    """The time an export's sidecar is stamped with (ISO 8601 with its UTC offset): the
    local time, or ``SOURCE_DATE_EPOCH`` [s since 1970, UTC] where set (the reproducible-builds
    convention), which makes the sidecar reproducible too. The exported file holds no time."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    if epoch is None:
        return time.strftime("%Y-%m-%dT%H:%M:%S%z")
    if not epoch.strip().isdigit():
        raise ExportError(f"SOURCE_DATE_EPOCH={epoch[:40]!r} is not a whole number of seconds since 1970")
    return time.strftime("%Y-%m-%dT%H:%M:%S+0000", time.gmtime(int(epoch)))


def closing_lines(side_name: str, meta: dict[str, Any]) -> list[str]:
    """The header line naming a program's sidecar and its digest (before the CRC line)."""
    return [f"# sidecar: {side_name} sha256 {sidecar_digest(meta, TEXT_FIELDS)}"]


def write_program(
    out: Path, side: Path, head: list[str], columns: str, lines: DataLines, meta: dict[str, Any]
) -> dict[str, Any]:
    """Close the header (the sidecar's digest, the CRC over every other line, the column
    line), name the program and its digest in the sidecar, and write both atomically."""
    check_sidecar_text({**meta, "program": out.name, "sidecar": side.name}, side, "nothing exported")
    rows = [*head, *closing_lines(side.name, meta)]
    # the data lines stay the kernel's bytes: encoded once, not again for the CRC, the digest
    # and the write
    body = b"\n" + lines.encoded if len(lines) else b""
    crc = zlib.crc32(body, crc_of([*rows, columns])) & 0xFFFFFFFF
    data = "\n".join([*rows, CRC_LINE.format(crc), columns]).encode("utf-8") + body + b"\n"
    meta.update(program=out.name, crc32=crc, program_sha256=hashlib.sha256(data).hexdigest())
    write_texts_atomic({side: dumps_json(meta, indent=2) + "\n", out: data})
    return meta


class ProgramFile:
    """A program file as read: its header rows (magic line to the sidecar line), header
    fields, data lines as numbers, its CRC-32 as written (``0x…``) and the SHA-256 of the
    bytes read (hex), so that the sidecar's digest is checked on the very bytes whose lines
    are checked, not on a second read of a file that may have changed in between."""

    def __init__(
        self, rows: list[str], fields: dict[str, str], data: np.ndarray, crc: str, sha256: str
    ) -> None:
        self.rows, self.fields, self.data, self.crc, self.sha256 = rows, fields, data, crc, sha256


def where_in(raw: bytes, pos: int) -> str:
    """'line L, column C' of byte ``pos`` of a file (both from 1; LF ends a line)."""
    line = raw.count(b"\n", 0, pos) + 1
    column = pos - raw.rfind(b"\n", 0, pos)
    return f"line {line}, column {column}"


def check_controller_text(path: Path, raw: bytes, blank_lines: bool = False) -> None:
    """Refuse bytes a controller would read differently from export's lines: anything but
    printable ASCII and LF (a CR, alone or before LF, ends a line on a controller that
    splits lines at CR; NUL, tabs and non-ASCII bytes are not written by export), a blank
    line (unless ``blank_lines``: a program from elsewhere), or a last line without its LF.
    Names the line and column."""
    buf = np.frombuffer(raw, dtype=np.uint8)
    bad = ((buf < 32) & (buf != 10)) | (buf > 126)
    if bad.any():
        pos = int(np.argmax(bad))
        what = (
            "a carriage return (CR): a controller ends a line there"
            if raw[pos] == 13
            else (f"byte 0x{raw[pos]:02x}, which export never writes")
        )
        raise ProgramError(f"{path}: {where_in(raw, pos)} holds {what}; do not run it")
    blank = -1 if blank_lines else raw.find(b"\n\n")
    if blank >= 0 or (raw.startswith(b"\n") and not blank_lines):
        raise ProgramError(f"{path}: {where_in(raw, blank + 1)} is blank; export writes no blank line")
    if not raw.endswith(b"\n"):
        raise ProgramError(f"{path}: the last line has no line end (LF); the file was cut short")


def read_program_file(path: Path, magic: str, columns: str) -> ProgramFile:
    """A program file read as a controller reads it: only a regular file, every line as
    export writes it in form (:func:`check_controller_text`; data lines byte for byte in
    :data:`DECIMALS`-decimal form, :func:`ftsweep.stages.numerics.decimals.fault`), its CRC (over
    every line but the CRC line) checked."""
    raw = read_regular(path, MAX_PROGRAM_BYTES, "program")
    if not raw.startswith(magic.encode("utf-8")):
        raise ProgramError(f"{path} is not an ftsweep program of this kind (no '{magic}' first line)")
    check_controller_text(path, raw)
    # only the header is split into rows: the data lines are read from the file's bytes
    mark = ("\n" + columns + "\n").encode("utf-8")
    at = raw.find(mark)
    if at < 0 and raw.endswith(mark[:-1]):
        at = len(raw) - len(mark) + 1
    if at < 0:
        raise ProgramError(f"{path}: the column line '{columns}' is missing")
    rows = raw[:at].decode("ascii").split("\n")
    crc_rows = [i for i, row in enumerate(rows) if row.startswith("# CRC32:")]
    if len(crc_rows) != 1:
        raise ProgramError(f"{path}: the header must hold exactly one CRC32 line; do not run it")
    stored = rows[crc_rows[0]][len("# CRC32: ") :].split(" ")[0]
    if stored != f"0x{_crc_without(raw, rows, crc_rows[0]):08x}":
        raise ProgramError(
            f"{path}: CRC32 mismatch (header {stored or 'missing'}): a line was changed; do not run it"
        )
    head: dict[str, str] = {}
    for row in rows[1:]:
        key, _, value = row[2:].partition(": ")
        head[key] = value
    n_cols = columns.count(" ") + 1
    start = min(at + len(mark), len(raw))
    data = _numbers(path, raw, start, n_cols)
    return ProgramFile(rows[: crc_rows[0]], head, data, stored, hashlib.sha256(raw).hexdigest())


def _crc_without(raw: bytes, rows: list[str], skip: int) -> int:
    """:func:`crc_of` the file's rows but row ``skip`` (a header row, so 0 < skip < the last
    row), taken from the file's bytes around it instead of a joined copy of every row."""
    head = "\n".join(rows[:skip]).encode("utf-8") + b"\n"
    start = len(head) + len(rows[skip].encode("utf-8")) + 1
    end = len(raw) - 1 if raw.endswith(b"\n") else len(raw)
    return zlib.crc32(memoryview(raw)[start:end], zlib.crc32(head)) & 0xFFFFFFFF


def _numbers(path: Path, raw: bytes, start: int, n_cols: int) -> np.ndarray:
    """The data lines (``raw[start:]``, after the column line) as an (lines, columns) array,
    refused unless byte for byte in export's form (:func:`ftsweep.stages.numerics.decimals.fault`,
    naming line and column); read at compiled speed (a million lines in ~0.08 s)."""
    body = memoryview(raw)[start : len(raw) - 1] if start < len(raw) else memoryview(b"")
    off = decimals.fault(body, n_cols, DECIMALS)
    if off >= 0:
        raise ProgramError(
            f"{path}: {where_in(raw, start + off)}: a data line is not {n_cols} numbers as export writes "
            f"them (-?digits.{DECIMALS} digits, one space between, LF at the end: no exponent, no '+', "
            "no leading zero, no blank line); do not run it"
        )
    data = decimals.parse_rows(body, n_cols, DECIMALS)
    if data is None:
        raise ProgramError(f"{path}: a data line holds a number beyond 2^53 units of its last decimal")
    return data


def recorded_extra(meta: dict[str, Any]) -> dict[str, Any]:
    """The provenance a program's sidecar records beside its case (the cube it came from,
    the platform it was planned on, its place in the cube's export ledger, the machine it was
    planned for where export --machine moved it)."""
    keys = ("cube", "cube_git_revision", "platform", "ledger", "planned_for")
    return {k: meta.get(k) for k in keys if k in meta}


def check_document(
    path: Path,
    doc: ProgramFile,
    planned: tuple[list[str], DataLines, dict[str, Any]],
    meta: dict[str, Any],
    columns: str,
) -> None:
    """Refuse a program whose header lines are not exactly the re-planned ones, whose data
    lines differ from the re-planned ones (by more than :data:`LINE_TOLERANCE` where the
    sidecar's platform is not this machine's:
    :func:`~ftsweep.exports.fingerprint.exact_on_this_platform`), or whose sidecar claims
    other than the re-derived ones; each message names the line or field."""
    head, lines, expected_meta = planned
    # the sidecar's name as export rendered it: from the program's recorded name, by the rule
    # of the sidecar found (an older export's FILE.json)
    named = sidecar_path if sidecar_of(path) == sidecar_path(path) else older_sidecar_path
    side_name = named(Path(str(meta.get("program", path.name)))).name
    want = [*head, *closing_lines(side_name, meta)]
    for number, (a, b) in enumerate(zip(doc.rows, want, strict=False), start=1):
        if a != b:
            raise ProgramError(
                f"{path}: line {number} reads {a[:120]!r} where the recorded case gives {b[:120]!r}; "
                "do not run it"
            )
    if len(doc.rows) != len(want):
        raise ProgramError(
            f"{path}: the header has {len(doc.rows)} lines where the recorded case gives {len(want)}; "
            "do not run it"
        )
    exact, _ = exact_on_this_platform(meta.get("platform"))
    check_lines(path, doc.data, lines.printed, columns, len(doc.rows) + 3, exact)
    _check_claims(path, meta, expected_meta)


def check_lines(
    path: Path, data: np.ndarray, planned: np.ndarray, columns: str, first_line: int, exact: bool
) -> None:
    """Every data line equal to the planned one (``planned``: its numbers as printed,
    :attr:`DataLines.printed`), column by column: exactly with ``exact``, else within
    :data:`LINE_TOLERANCE`."""
    if data.shape[0] != planned.shape[0]:
        raise ProgramError(
            f"{path}: {data.shape[0]:,} data lines, but the recorded case plans {planned.shape[0]:,}; "
            "do not run it"
        )
    names = columns.split()
    for col, name in enumerate(names):
        tol = 0.0 if exact else LINE_TOLERANCE[name.rsplit("_", 1)[1]]
        off = np.abs(data[:, col] - planned[:, col])
        if not off.max(initial=0.0) <= tol:
            k = int(np.argmax(~(off <= tol)))
            raise ProgramError(
                f"{path}: line {first_line + k} has {name} {data[k, col]:.9f}, the recorded case plans "
                f"{planned[k, col]:.9f} (tolerance {tol:g}; {int(np.sum(~(off <= tol))):,} line(s) off); "
                "do not run it"
            )


def _check_claims(path: Path, meta: dict[str, Any], expected: dict[str, Any]) -> None:
    """The sidecar's fields must be the re-derived ones (those depending on the text aside)."""
    got = json.loads(dumps_json({k: v for k, v in meta.items() if k not in TEXT_FIELDS}))
    want = json.loads(dumps_json({k: v for k, v in expected.items() if k not in TEXT_FIELDS}))
    differ = sorted(k for k in set(got) | set(want) if got.get(k) != want.get(k))
    if differ:
        raise ProgramError(
            f"{sidecar_of(path)}: {', '.join(differ[:5])} differ(s) from what the recorded case gives; "
            "do not run it"
        )


def checked_sidecar(path: Path, doc: ProgramFile) -> dict[str, Any]:
    """The sidecar of a program (``doc``, as read from ``path``), refused unless it and the
    program name each other."""
    return sidecar_naming(path, doc.sha256, doc.fields.get("sidecar", "").split(" sha256 ")[-1])


def sidecar_naming(path: Path, sha256: str, stated: str) -> dict[str, Any]:
    """The sidecar of the program file ``path`` whose bytes have SHA-256 ``sha256`` and whose
    header states the sidecar's digest ``stated``: refused unless the sidecar names those bytes
    and has that digest (:func:`sidecar_digest` over all but :data:`TEXT_FIELDS`)."""
    side = sidecar_of(path)
    try:
        meta = read_sidecar(path)
    except ExportError as exc:
        raise ProgramError(str(exc)) from None
    if meta.get("program_sha256") != sha256:
        raise ProgramError(f"{side} does not belong to {path} (SHA-256 of the program differs)")
    if stated != sidecar_digest(meta, TEXT_FIELDS):
        raise ProgramError(f"{path}: the sidecar was changed (its SHA-256 differs from the header's)")
    return dict(meta)


def checked_pv(
    path: Path, meta: dict[str, Any], record: dict[str, Any], pv_tolerance_nm: float | None
) -> dict[str, Any]:
    """``record`` (a re-simulation) with the predicted P-V and tolerance; refused when they
    disagree."""
    predicted = float(meta["pv_nm"])
    # Z is printed to 1 pm: the re-simulation agrees to far better than 0.01 nm + 0.1 %
    tol = 0.01 + 1e-3 * predicted if pv_tolerance_nm is None else pv_tolerance_nm
    record.update(predicted_pv_nm=predicted, pv_tolerance_nm=tol, checksum=f"0x{int(meta['crc32']):08x}")
    record["header"] = str(path)
    if not abs(record["pv_nm"] - predicted) <= tol or not math.isfinite(record["pv_nm"]):
        raise ProgramError(
            f"{path}: the program re-simulates to P-V {record['pv_nm']:.3f} nm, not the predicted "
            f"{predicted:.3f} nm (tolerance {tol:.3f} nm); do not run it"
        )
    return record


Progress = Callable[[int, int], None] | None


def pv_lines(record: dict[str, Any], source: str) -> list[str]:
    return [
        f"P-V          {record['pv_nm']:.2f} nm re-simulated from {source} "
        f"(predicted at export: {record['predicted_pv_nm']:.2f} nm, "
        f"tolerance {record['pv_tolerance_nm']:.2f} nm) ok"
    ]
