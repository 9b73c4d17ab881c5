"""Export and verification of path programs: spiral ([4]), D-path ([5]) and, through
:mod:`ftsweep.fstudy`, Fresnel ([2]) programs. One plain-text line per control point under a
``#`` header of units, surface, tool, budgets and predicted P-V, with a JSON sidecar holding
the full case; both written atomically.

A spiral line is ``C [deg]  X [mm]  Z [mm]``: C the *accumulated* spindle angle (0 at the
part's edge, increasing by 360 per revolution), X the radius of the tool on the spiral and Z
the compensated tool-tip height; the controller interpolates X and Z linearly in C between
consecutive lines. ``CRC32`` in the header covers every other line of the file (the header
lines, the layer offsets and segments included); the header names the sidecar's SHA-256 and
the sidecar the program's. :func:`verify_program` plans the program again from the recorded
case and compares it with every line the machine reads: the header lines exactly, every data
line within :data:`LINE_TOLERANCE` per column, the sidecar's claims with the re-derived ones.
"""

from __future__ import annotations

import hashlib
import json
import math
import time
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ftsweep import __version__
from ftsweep.case import Case, resolve_case, run_case
from ftsweep.export import (
    ExportError,
    layer_schedule,
    recorded_case_of,
    recorded_entries,
    sidecar_digest,
    sidecar_path,
)
from ftsweep.io import dumps_json, write_texts_atomic
from ftsweep.stages.spiral import SpiralPath

MAGIC = "# ftsweep spiral program"
COLUMNS = "C_deg X_mm Z_mm"
# printed digits: 1e-9 mm = 1 pm in X and Z, 1e-9 deg in C
LINE = "{:.9f} {:.9f} {:.9f}"
CRC_LINE = "# CRC32: 0x{:08x} over every other line"

# How far a program line may lie from the re-planned one, per column unit: 1 µs, 1e-6°,
# 1e-6 mm = 1 nm. Lines are printed to 1 ns, 1e-9° and 1 pm and re-planning is deterministic,
# so an exported program lies far inside; an edit of a nanometre or more is refused.
LINE_TOLERANCE = {"s": 1e-6, "deg": 1e-6, "mm": 1e-6}


class ProgramError(ExportError):
    """A program file cannot be trusted; the message says why."""


def is_program(path: Path) -> bool:
    """Whether ``path`` starts like an exported spiral, D-path or Fresnel program."""
    from ftsweep.fstudy import F_MAGIC

    with open(path, encoding="utf-8", errors="replace") as fh:
        return fh.readline().startswith((MAGIC, D_MAGIC, F_MAGIC))


def _data_lines(path: SpiralPath, values_um: np.ndarray) -> list[str]:
    c_deg = np.degrees(path.phi)
    x_mm = path.rho * 1e-3
    z_mm = np.asarray(values_um) * 1e-3
    return [LINE.format(c, x, z) for c, x, z in zip(c_deg, x_mm, z_mm, strict=True)]


def _crc(rows: list[str]) -> int:
    """CRC-32 of the file's lines but its CRC line, joined by newlines."""
    return zlib.crc32("\n".join(rows).encode("utf-8")) & 0xFFFFFFFF


# the sidecar fields that depend on the program's text (left out of the sidecar's digest)
TEXT_FIELDS = ("program", "program_sha256", "crc32")


def spiral_document(
    case: Case,
    specs: tuple[Any, Any, Any],
    chosen: dict[str, Any],
    extra: dict[str, Any],
    created: str,
    generator: str,
) -> tuple[list[str], list[str], dict[str, Any]]:
    """The header lines, data lines and sidecar content of a spiral case ([4]), planned from
    its spec and entries: export writes them and verify re-derives them."""
    rcase = resolve_case(case, specs=specs)
    assert isinstance(rcase.layout, SpiralPath) and rcase.values is not None
    path = rcase.layout
    if path.n_points != chosen["n_points"]:
        raise ProgramError(f"the cube says {chosen['n_points']} points but the spec plans {path.n_points}")
    lines = _data_lines(path, rcase.values)
    # planned from Z as printed, as the controller executes it
    schedule = layer_schedule(rcase, _values_of(lines))
    rule, value = case.layout.spiral_rule()
    residual = case.layout.residual_um
    meta = {
        "generator": generator,
        "created": created,
        "layout": "spiral",
        "n_points": path.n_points,
        "rule": rule,
        "rule_value": value,
        "residual_um": residual,
        "rho0_um": path.rho0_um,
        "surface": case.surface,
        "compensation": case.compensation,
        "feed_um": rcase.feed_um,
        "nose_radius_um": rcase.nose_radius_um,
        "spindle_rpm": specs[2].spindle_rpm,
        "pv_nm": chosen["pv_nm"],
        "layers": schedule,
        **extra,
        "selection": chosen,
        "case": case.model_dump(mode="json"),
        "catalog_entries": recorded_entries(specs),
    }
    unit = {"angle": "points/rev", "arc": "um of path", "chord": "um chord budget"}[rule]
    head = [
        f"{MAGIC} (linear interpolation of X and Z in C between consecutive lines)",
        f"# generator: {generator}; created {created}",
        f"# surface: {case.surface}; compensation: {case.compensation}",
        f"# tool: nose radius {rcase.nose_radius_um:.6g} um; feed {rcase.feed_um:.9g} um/rev; "
        f"spindle {specs[2].spindle_rpm:g} rpm",
        f"# rule: {rule} {value:g} {unit}; residual budget "
        + (f"{residual:g} um" if residual is not None else "none (feed given)"),
        f"# predicted P-V: {chosen['pv_nm']:.6f} nm",
        f"# points: {path.n_points}",
        *_layer_lines(schedule),
        "# units: C [deg] accumulated spindle angle from the edge, X [mm] radius, Z [mm] tool tip",
    ]
    return head, lines, meta


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S%z")


def export_program(
    out: Path,
    side: Path,
    case: Case,
    specs: tuple[Any, Any, Any],
    chosen: dict[str, Any],
    extra: dict[str, Any],
) -> dict[str, Any]:
    """Plan the chosen spiral case again from its recorded spec and entries (the same
    program the cube predicted), and write the program and its sidecar atomically."""
    head, lines, meta = spiral_document(case, specs, chosen, extra, _now(), f"ftsweep {__version__}")
    return write_program(out, side, head, COLUMNS, lines, meta)


def _closing_lines(side_name: str, meta: dict[str, Any]) -> list[str]:
    return [f"# sidecar: {side_name} sha256 {sidecar_digest(meta, TEXT_FIELDS)}"]


def write_program(
    out: Path, side: Path, head: list[str], columns: str, lines: list[str], meta: dict[str, Any]
) -> dict[str, Any]:
    """Close the header (the sidecar's digest, the CRC over every other line, the column
    line), name the program and its digest in the sidecar, and write both atomically."""
    rows = [*head, *_closing_lines(side.name, meta)]
    crc = _crc([*rows, columns, *lines])
    text = "\n".join([*rows, CRC_LINE.format(crc), columns, *lines]) + "\n"
    meta.update(program=out.name, crc32=crc, program_sha256=hashlib.sha256(text.encode()).hexdigest())
    write_texts_atomic({side: dumps_json(meta, indent=2) + "\n", out: text})
    return meta


def _values_of(lines: list[str]) -> np.ndarray:
    return np.array([float(line.split()[2]) for line in lines]) * 1e3


def _layer_lines(schedule: dict[str, Any] | None) -> list[str]:
    """Header lines of a layered program ([3]): the Z offset of each layer (Z to execute =
    the line's Z − the offset) and each segment: the C range a layer cuts."""
    if schedule is None:
        return []
    offsets = " ".join(f"{v:.9f}" for v in np.asarray(schedule["offset_um"]) * 1e-3)
    out = [
        f"# layers: {schedule['n_layers']} (Z zone {schedule['zone_um']:.6g} um); in layer k the Z axis "
        "offsets the part by offset_mm[k] and the servo executes Z - offset, on that layer's segments only",
        f"# offset_mm: {offsets}",
    ]
    for layer, (a, b) in zip(schedule["segment_layer"], schedule["segment_phi_deg"], strict=True):
        out.append(f"# segment: layer {layer} C {a:.9f} to {b:.9f}")
    return out


class ProgramFile:
    """A program file as read: its header rows (magic line to the sidecar line), header
    fields, data lines as written and as numbers, and its CRC-32 as written (``0x…``)."""

    def __init__(
        self, rows: list[str], fields: dict[str, str], lines: list[str], data: np.ndarray, crc: str
    ) -> None:
        self.rows, self.fields, self.lines, self.data, self.crc = rows, fields, lines, data, crc


def read_program(path: Path, magic: str = MAGIC, columns: str = COLUMNS) -> tuple[dict[str, str], np.ndarray]:
    """The header fields and the (N, columns) data of a program file, its CRC checked."""
    doc = read_program_file(path, magic, columns)
    return doc.fields, doc.data


def read_program_file(path: Path, magic: str, columns: str) -> ProgramFile:
    """A program file, its CRC (over every line but the CRC line) checked; every data line
    must hold the columns' count of plain numbers."""
    with open(path, encoding="utf-8") as fh:
        text = fh.read()
    rows = text.split("\n")
    if not rows or not rows[0].startswith(magic):
        raise ProgramError(f"{path} is not an ftsweep program of this kind (no '{magic}' first line)")
    if rows[-1] == "":
        rows = rows[:-1]
    try:
        start = rows.index(columns) + 1
    except ValueError:
        raise ProgramError(f"{path}: the column line '{columns}' is missing") from None
    crc_rows = [i for i, row in enumerate(rows[:start]) if row.startswith("# CRC32:")]
    if len(crc_rows) != 1:
        raise ProgramError(f"{path}: the header must hold exactly one CRC32 line; do not run it")
    others = rows[: crc_rows[0]] + rows[crc_rows[0] + 1 :]
    stored = rows[crc_rows[0]][len("# CRC32: ") :].split(" ")[0]
    if stored != f"0x{_crc(others):08x}":
        raise ProgramError(
            f"{path}: CRC32 mismatch (header {stored or 'missing'}): a line was changed; do not run it"
        )
    head: dict[str, str] = {}
    for row in rows[1 : start - 1]:
        key, _, value = row[2:].partition(": ")
        head[key] = value
    lines = rows[start:]
    n_cols = columns.count(" ") + 1
    try:
        data = np.array([[float(v) for v in line.split(" ")] for line in lines], dtype=np.float64)
    except ValueError as exc:
        raise ProgramError(f"{path}: a data line is not {n_cols} numbers ({exc})") from None
    if data.ndim != 2 or data.shape[1] != n_cols or not np.all(np.isfinite(data)):
        raise ProgramError(f"{path}: every data line must hold {columns} as {n_cols} finite numbers")
    return ProgramFile(rows[: crc_rows[0]], head, lines, data, stored)


def verify_program(
    path: Path,
    progress: Callable[[int, int], None] | None = None,
    pv_tolerance_nm: float | None = None,
    trust_plugins: bool = False,
) -> dict[str, Any]:
    """Check a program and its sidecar against the program its recorded case plans (every
    header line, every data line within :data:`LINE_TOLERANCE`), then re-simulate the part
    from the file's own lines. Raises :class:`ProgramError` (an ``ExportError``) naming the
    first mismatch; returns the re-simulated record with the predicted P-V and the tolerance
    applied. Spiral, D-path and Fresnel programs are told apart by their first line."""
    path = Path(path)
    with open(path, encoding="utf-8", errors="replace") as fh:
        first = fh.readline()
    if first.startswith(D_MAGIC):
        return verify_dpath(path, progress, pv_tolerance_nm, trust_plugins)
    if not first.startswith(MAGIC):
        from ftsweep import fstudy

        return fstudy.verify(path, trust_plugins)
    doc = read_program_file(path, MAGIC, COLUMNS)
    meta = checked_sidecar(path, doc.fields)
    case, specs = recorded_case_of(meta, sidecar_path(path), trust_plugins)
    planned = spiral_document(
        case, specs, meta["selection"], _extra_of(meta), meta["created"], meta["generator"]
    )
    check_document(path, doc, planned, meta, COLUMNS)
    data = doc.data
    phi = np.radians(data[:, 0])
    rule, value = case.layout.spiral_rule()
    spiral_path = SpiralPath("spiral", phi, float(meta["rho0_um"]), float(meta["feed_um"]), rule, value)
    record = run_case(case, specs=specs, progress=progress, program=(spiral_path, data[:, 2] * 1e3))
    return checked_pv(path, meta, record, pv_tolerance_nm)


def _extra_of(meta: dict[str, Any]) -> dict[str, Any]:
    return {k: meta.get(k) for k in ("cube", "cube_git_revision") if k in meta}


def check_document(
    path: Path,
    doc: ProgramFile,
    planned: tuple[list[str], list[str], dict[str, Any]],
    meta: dict[str, Any],
    columns: str,
) -> None:
    """Refuse a program whose header lines are not exactly the re-planned ones, whose data
    lines leave the re-planned ones by more than :data:`LINE_TOLERANCE`, or whose sidecar
    claims other than the re-derived ones; each message names the line or field."""
    head, lines, expected_meta = planned
    side_name = sidecar_path(Path(str(meta.get("program", path.name)))).name
    want = [*head, *_closing_lines(side_name, meta)]
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
    check_lines(path, doc.data, lines, columns, len(doc.rows) + 3)
    _check_claims(path, meta, expected_meta)


def check_lines(
    path: Path, data: np.ndarray, planned_lines: list[str], columns: str, first_line: int
) -> None:
    """Every data line within :data:`LINE_TOLERANCE` of the planned one, column by column."""
    if data.shape[0] != len(planned_lines):
        raise ProgramError(
            f"{path}: {data.shape[0]:,} data lines, but the recorded case plans {len(planned_lines):,}; "
            "do not run it"
        )
    planned = np.array([[float(v) for v in line.split()] for line in planned_lines], dtype=np.float64)
    names = columns.split()
    for col, name in enumerate(names):
        tol = LINE_TOLERANCE[name.rsplit("_", 1)[1]]
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
            f"{sidecar_path(path)}: {', '.join(differ[:5])} differ(s) from what the recorded case gives; "
            "do not run it"
        )


def checked_sidecar(path: Path, head: dict[str, str]) -> dict[str, Any]:
    """The sidecar of a program, refused unless it and the program name each other."""
    side = sidecar_path(path)
    try:
        meta = json.loads(side.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ProgramError(f"{side}: the sidecar cannot be read ({exc})") from None
    if not isinstance(meta, dict):
        raise ProgramError(f"{side} is not an ftsweep sidecar (a JSON object is expected)")
    if meta.get("program_sha256") != hashlib.sha256(path.read_bytes()).hexdigest():
        raise ProgramError(f"{side} does not belong to {path} (SHA-256 of the program differs)")
    if head.get("sidecar", "").split(" sha256 ")[-1] != sidecar_digest(meta, TEXT_FIELDS):
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


# --------------------------------------------------------------------------- D paths ([5])
D_MAGIC = "# ftsweep D-path program"
D_COLUMNS = "t_s C_deg X_mm Z_mm"
D_LINE = "{:.9f} {:.9f} {:.9f} {:.9f}"


def _limits_of_lines(machine: Any, data: np.ndarray) -> str:
    """The axis limits the lines (t [s], C [deg], X [mm], Z [mm]) exceed, checked on every
    line: positions directly, feeds and accelerations by differences between lines."""
    from ftsweep import dpath as dprog

    t, phi, x_um, z_um = data[:, 0], np.radians(data[:, 1]), data[:, 2] * 1e3, data[:, 3] * 1e3
    if not np.all(np.diff(t) > 0.0):
        return "time does not increase from line to line"
    peaks, _ = dprog.motion_peaks(t, phi, x_um, z_um)
    # the C speed from printed times and angles: allow their last digit
    return dprog.limits_reason(machine, peaks, z_um, peaks["c_speed_peak_rpm"] - 1e-6)


def dpath_document(
    case: Case,
    specs: tuple[Any, Any, Any],
    chosen: dict[str, Any],
    extra: dict[str, Any],
    created: str,
    generator: str,
) -> tuple[list[str], list[str], dict[str, Any]]:
    """The header lines, data lines and sidecar content of a D-path case ([5]), planned from
    its spec and entries: export writes them and verify re-derives them."""
    from ftsweep import dpath as dprog

    rcase = resolve_case(case, specs=specs)
    path, z = rcase.layout, rcase.values
    if path.n_points != chosen["n_points"]:
        raise ProgramError(
            f"the prediction says {chosen['n_points']} points but the spec plans {path.n_points}"
        )
    rpm = specs[2].spindle_rpm
    t = dprog.times(path, z, rpm)
    lines = [
        D_LINE.format(*row) for row in zip(t, np.degrees(path.phi), path.rho * 1e-3, z * 1e-3, strict=True)
    ]
    g = path.geometry
    meta = {
        "generator": generator,
        "created": created,
        "layout": "dpath",
        "n_points": path.n_points,
        "surface": case.surface,
        "compensation": case.compensation,
        "spacing_um": g.spacing_um,
        "points_per_cut": path.points_per_cut,
        "transition": g.transition,
        "zones": g.zones,
        "nose_radius_um": rcase.nose_radius_um,
        "spindle_rpm": rpm,
        "machining_s": float(t[-1]),
        "pv_nm": chosen["pv_nm"],
        **extra,
        "selection": {k: v for k, v in chosen.items() if not isinstance(v, (list, dict)) or k == "case"},
        "case": case.model_dump(mode="json"),
        "catalog_entries": recorded_entries(specs),
    }
    head = [
        f"{D_MAGIC} (X, Z and C move linearly in time between consecutive lines)",
        f"# generator: {generator}; created {created}",
        f"# surface: {case.surface}; compensation: {case.compensation}; machine: {case.machine}",
        f"# zone: {g.length_um / 1e3:.6g} x {g.width_um / 1e3:.6g} mm, centre {g.centre_um / 1e3:.6g} mm off-axis; "  # noqa: E501
        f"{g.zones} zone(s) per revolution",
        f"# cuts: {path.n_cuts} at spacing {g.spacing_um:.9g} um, {path.points_per_cut} points each; "
        f"transition {g.transition}",
        f"# tool: nose radius {rcase.nose_radius_um:.6g} um; spindle {rpm:g} rpm (constant)",
        f"# timing: {float(t[-1]):.3f} s in all",
        f"# predicted P-V: {chosen['pv_nm']:.6f} nm",
        f"# points: {path.n_points}",
        "# units: t [s] from the first line, C [deg] accumulated, X [mm] tool radius, Z [mm] tool tip",
    ]
    return head, lines, meta


def export_dpath(
    out: Path,
    side: Path,
    case: Case,
    specs: tuple[Any, Any, Any],
    chosen: dict[str, Any],
    extra: dict[str, Any],
) -> dict[str, Any]:
    """Plan the chosen D-path case again ([5]) and write it as position-time lines
    (t [s] at constant spindle speed, accumulated C [deg], X [mm], Z [mm]) with its sidecar,
    atomically; refused if any line leaves the machine's axis limits."""
    head, lines, meta = dpath_document(case, specs, chosen, extra, _now(), f"ftsweep {__version__}")
    data = np.array([[float(v) for v in line.split()] for line in lines])
    reason = _limits_of_lines(specs[1], data)
    if reason:
        raise ProgramError(
            f"the program leaves the axis limits of machine '{case.machine}': {reason}; nothing exported"
        )
    return write_program(out, side, head, D_COLUMNS, lines, meta)


def verify_dpath(
    path: Path,
    progress: Callable[[int, int], None] | None = None,
    pv_tolerance_nm: float | None = None,
    trust_plugins: bool = False,
) -> dict[str, Any]:
    """Check a D-path program: CRC and sidecar, every line within the machine's axis limits,
    every line (t, C, X, Z) and header line against the program its recorded case plans
    (:func:`check_document`), and the part re-simulated from the lines' C, X and Z."""
    doc = read_program_file(path, D_MAGIC, D_COLUMNS)
    meta = checked_sidecar(path, doc.fields)
    case, specs = recorded_case_of(meta, sidecar_path(path), trust_plugins)
    reason = _limits_of_lines(specs[1], doc.data)
    if reason:
        raise ProgramError(
            f"{path}: a line leaves the axis limits of machine '{case.machine}': {reason}; do not run it"
        )
    planned = dpath_document(
        case, specs, meta["selection"], _extra_of(meta), meta["created"], meta["generator"]
    )
    check_document(path, doc, planned, meta, D_COLUMNS)
    data = doc.data
    rcase = resolve_case(case, specs=specs)
    # the path as the file gives it: its C and X, on the planned cuts' geometry
    given = rcase.layout._replace(phi=np.radians(data[:, 1]), rho=data[:, 2] * 1e3)
    record = run_case(case, specs=specs, progress=progress, program=(given, data[:, 3] * 1e3))
    return checked_pv(path, meta, record, pv_tolerance_nm)
