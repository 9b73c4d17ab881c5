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
    """Whether ``path`` starts like an exported spiral program."""
    with open(path, encoding="utf-8", errors="replace") as fh:
        return fh.readline().startswith(MAGIC)


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
    crc = _crc(lines)
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
        f"# sidecar: {side.name} sha256 {sidecar_digest(meta, TEXT_FIELDS)}",
        f"# CRC32: 0x{crc:08x} over the data lines",
        COLUMNS,
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


def read_program(path: Path) -> tuple[dict[str, str], np.ndarray]:
    """The header fields and the (N, 3) data of a program file, its CRC checked."""
    head: dict[str, str] = {}
    with open(path, encoding="utf-8") as fh:
        text = fh.read()
    rows = text.splitlines()
    if not rows or not rows[0].startswith(MAGIC):
        raise ProgramError(f"{path} is not an ftsweep spiral program (no '{MAGIC}' first line)")
    try:
        start = rows.index(COLUMNS) + 1
    except ValueError:
        raise ProgramError(f"{path}: the column line '{COLUMNS}' is missing") from None
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
        raise ProgramError(f"{path}: a data line is not three numbers ({exc})") from None
    if data.ndim != 2 or data.shape[1] != 3:
        raise ProgramError(f"{path}: every data line must hold C, X and Z")
    return head, data


def verify_program(
    path: Path, progress: Callable[[int, int], None] | None = None, pv_tolerance_nm: float | None = None
) -> dict[str, Any]:
    """Check a program and its sidecar, rebuild the path from its lines (C, X, Z) and
    re-simulate the part from them. Raises :class:`ProgramError` (an ``ExportError``) on any
    mismatch; returns the re-simulated record with the predicted P-V and the tolerance
    applied."""
    import json

    path = Path(path)
    head, data = read_program(path)
    side = sidecar_path(path)
    try:
        meta = json.loads(side.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ProgramError(f"{side}: the sidecar cannot be read ({exc})") from None
    if meta.get("program_sha256") != hashlib.sha256(path.read_bytes()).hexdigest():
        raise ProgramError(f"{side} does not belong to {path} (SHA-256 of the program differs)")
    if head.get("sidecar", "").split(" sha256 ")[-1] != sidecar_digest(meta, TEXT_FIELDS):
        raise ProgramError(f"{path}: the sidecar was changed (its SHA-256 differs from the header's)")
    case, specs = recorded_case_of(meta, side)
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
