"""Export and verification of spiral path programs ([4]): one plain-text line per control
point, ``C [deg]  X [mm]  Z [mm]``, under a ``#`` header of units, surface, tool, budgets
and predicted P-V, with a JSON sidecar holding the full case; both written atomically.

C is the *accumulated* spindle angle (0 at the part's edge, increasing by 360 per
revolution), X the radius of the tool on the spiral and Z the compensated tool-tip height;
the controller interpolates X and Z linearly in C between consecutive lines. ``CRC32`` in
the header covers every data line; the header names the sidecar's SHA-256 and the sidecar
the program's, so an edit to either is caught by :func:`verify_program`.
"""

from __future__ import annotations

import hashlib
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
    check_schedule,
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


class ProgramError(ExportError):
    """A program file cannot be trusted; the message says why."""


def is_program(path: Path) -> bool:
    """Whether ``path`` starts like an exported spiral or D-path program."""
    with open(path, encoding="utf-8", errors="replace") as fh:
        return fh.readline().startswith((MAGIC, D_MAGIC))


def _data_lines(path: SpiralPath, values_um: np.ndarray) -> list[str]:
    c_deg = np.degrees(path.phi)
    x_mm = path.rho * 1e-3
    z_mm = np.asarray(values_um) * 1e-3
    return [LINE.format(c, x, z) for c, x, z in zip(c_deg, x_mm, z_mm, strict=True)]


def _crc(lines: list[str]) -> int:
    return zlib.crc32("\n".join(lines).encode("ascii")) & 0xFFFFFFFF


# the sidecar fields that depend on the program's text (left out of the sidecar's digest)
TEXT_FIELDS = ("program", "program_sha256", "crc32")


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
    rcase = resolve_case(case, specs=specs)
    assert isinstance(rcase.layout, SpiralPath) and rcase.values is not None
    path = rcase.layout
    if path.n_points != chosen["n_points"]:
        raise ProgramError(f"the cube says {chosen['n_points']} points but the spec plans {path.n_points}")
    lines = _data_lines(path, rcase.values)
    # planned from Z as printed, as verify plans it
    schedule = layer_schedule(rcase, _values_of(lines))
    rule, value = case.layout.spiral_rule()
    residual = case.layout.residual_um
    meta = {
        "generator": f"ftsweep {__version__}",
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
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
        f"# generator: ftsweep {__version__}; created {meta['created']}",
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
    return _write_program(out, side, head, COLUMNS, lines, meta)


def _write_program(
    out: Path, side: Path, head: list[str], columns: str, lines: list[str], meta: dict[str, Any]
) -> dict[str, Any]:
    """Close the header (the sidecar's digest, the CRC over the data lines, the column line),
    name the program and its digest in the sidecar, and write both atomically."""
    crc = _crc(lines)
    head = [
        *head,
        f"# sidecar: {side.name} sha256 {sidecar_digest(meta, TEXT_FIELDS)}",
        f"# CRC32: 0x{crc:08x} over the data lines",
        columns,
    ]
    text = "\n".join(head + lines) + "\n"
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


def read_program(path: Path, magic: str = MAGIC, columns: str = COLUMNS) -> tuple[dict[str, str], np.ndarray]:
    """The header fields and the (N, columns) data of a program file, its CRC checked."""
    head: dict[str, str] = {}
    with open(path, encoding="utf-8") as fh:
        text = fh.read()
    rows = text.splitlines()
    if not rows or not rows[0].startswith(magic):
        raise ProgramError(f"{path} is not an ftsweep program of this kind (no '{magic}' first line)")
    try:
        start = rows.index(columns) + 1
    except ValueError:
        raise ProgramError(f"{path}: the column line '{columns}' is missing") from None
    for row in rows[1 : start - 1]:
        key, _, value = row[2:].partition(": ")
        head[key] = value
    lines = rows[start:]
    stored = head.get("CRC32", "").split(" ")[0]
    if stored != f"0x{_crc(lines):08x}":
        raise ProgramError(
            f"{path}: CRC32 mismatch (header {stored or 'missing'}): a line was changed; do not run it"
        )
    try:
        data = np.array([[float(v) for v in line.split()] for line in lines], dtype=np.float64)
    except ValueError as exc:
        raise ProgramError(f"{path}: a data line is not {columns.count(' ') + 1} numbers ({exc})") from None
    if data.ndim != 2 or data.shape[1] != columns.count(" ") + 1:
        raise ProgramError(f"{path}: every data line must hold {columns}")
    return head, data


def verify_program(
    path: Path, progress: Callable[[int, int], None] | None = None, pv_tolerance_nm: float | None = None
) -> dict[str, Any]:
    """Check a program and its sidecar, rebuild the path from its lines (C, X, Z) and
    re-simulate the part from them. Raises :class:`ProgramError` (an ``ExportError``) on any
    mismatch; returns the re-simulated record with the predicted P-V and the tolerance
    applied."""
    path = Path(path)
    with open(path, encoding="utf-8", errors="replace") as fh:
        if fh.readline().startswith(D_MAGIC):
            return verify_dpath(path, progress, pv_tolerance_nm)
    head, data = read_program(path)
    meta = _checked_sidecar(path, head)
    case, specs = recorded_case_of(meta, sidecar_path(path))
    phi = np.radians(data[:, 0])
    feed, rho0 = float(meta["feed_um"]), float(meta["rho0_um"])
    rule, value = case.layout.spiral_rule()
    spiral_path = SpiralPath("spiral", phi, rho0, feed, rule, value)
    off = np.max(np.abs(spiral_path.rho * 1e-3 - data[:, 1]))
    if not off <= 1e-6:
        raise ProgramError(f"{path}: X leaves the spiral of the recorded feed by up to {off * 1e3:.3g} µm")
    values = data[:, 2] * 1e3
    planned = layer_schedule(resolve_case(case, specs=specs, program=(spiral_path, values)), values)
    check_schedule(meta.get("layers"), planned, path)
    record = run_case(case, specs=specs, progress=progress, program=(spiral_path, values))
    return _checked_pv(path, meta, record, pv_tolerance_nm)


def _checked_sidecar(path: Path, head: dict[str, str]) -> dict[str, Any]:
    """The sidecar of a program, refused unless it and the program name each other."""
    import json

    side = sidecar_path(path)
    try:
        meta = json.loads(side.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ProgramError(f"{side}: the sidecar cannot be read ({exc})") from None
    if meta.get("program_sha256") != hashlib.sha256(path.read_bytes()).hexdigest():
        raise ProgramError(f"{side} does not belong to {path} (SHA-256 of the program differs)")
    if head.get("sidecar", "").split(" sha256 ")[-1] != sidecar_digest(meta, TEXT_FIELDS):
        raise ProgramError(f"{path}: the sidecar was changed (its SHA-256 differs from the header's)")
    return dict(meta)


def _checked_pv(
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
    data = np.array([[float(v) for v in line.split()] for line in lines])
    reason = _limits_of_lines(specs[1], data)
    if reason:
        raise ProgramError(
            f"the program leaves the axis limits of machine '{case.machine}': {reason}; nothing exported"
        )
    g = path.geometry
    meta = {
        "generator": f"ftsweep {__version__}",
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
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
        f"# generator: ftsweep {__version__}; created {meta['created']}",
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
    return _write_program(out, side, head, D_COLUMNS, lines, meta)


def verify_dpath(
    path: Path, progress: Callable[[int, int], None] | None = None, pv_tolerance_nm: float | None = None
) -> dict[str, Any]:
    """Check a D-path program: CRC and sidecar, every line within the machine's axis limits,
    C and X on the path its recorded case plans (within 1 nm and 1e-6°), and the part
    re-simulated from the lines' Z."""
    head, data = read_program(path, D_MAGIC, D_COLUMNS)
    meta = _checked_sidecar(path, head)
    case, specs = recorded_case_of(meta, sidecar_path(path))
    reason = _limits_of_lines(specs[1], data)
    if reason:
        raise ProgramError(
            f"{path}: a line leaves the axis limits of machine '{case.machine}': {reason}; do not run it"
        )
    rcase = resolve_case(case, specs=specs)
    planned = rcase.layout
    if planned.n_points != data.shape[0]:
        raise ProgramError(
            f"{path}: {data.shape[0]} lines, but the recorded case plans {planned.n_points} points"
        )
    off_x = float(np.max(np.abs(planned.rho * 1e-3 - data[:, 2])))
    off_c = float(np.max(np.abs(np.degrees(planned.phi) - data[:, 1])))
    if not (off_x <= 1e-6 and off_c <= 1e-6):
        raise ProgramError(
            f"{path}: the lines leave the planned D path (X by {off_x * 1e3:.3g} µm, C by {off_c:.3g}°)"
        )
    values = data[:, 3] * 1e3
    record = run_case(case, specs=specs, progress=progress, program=(planned, values))
    return _checked_pv(path, meta, record, pv_tolerance_nm)
