"""The spiral program's file ([4]): one plain-text line per control point, ``C [deg]  X [mm]
Z [mm]``: C the *accumulated* spindle angle (0 at the part's edge, increasing by 360 per
revolution), X the radius of the tool on the spiral and Z the compensated tool-tip height;
the controller interpolates X and Z linearly in C between consecutive lines. Verify plans
the program again from the recorded case and compares it with every line the machine reads:
the header lines exactly, every data line within ``files.LINE_TOLERANCE`` per column, the
sidecar's claims with the re-derived ones (the machinery: :mod:`ftsweep.exports.programs`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ftsweep.engine.case import Case
from ftsweep.engine.contract import FileFormat
from ftsweep.exports.files import (
    DataLines,
    ProgramError,
    check_document,
    checked_pv,
    checked_sidecar,
    layer_schedule,
    now,
    read_program_file,
    recorded_case_of,
    recorded_entries,
    recorded_extra,
    write_program,
)
from ftsweep.exports.programs import program_format
from ftsweep.inputs.case_entries import Entries
from ftsweep.kinds.spiral.request import request_of
from ftsweep.simulate import resolve_case, run_case
from ftsweep.stages.interpolation.spiral_program import SpiralPath
from ftsweep.store.io import sidecar_of
from ftsweep.version import __version__

MAGIC = "# ftsweep spiral program"
COLUMNS = "C_deg X_mm Z_mm"  # printed with 9 decimals (files.DECIMALS): 1 pm in X and Z, 1e-9 deg in C


def _data_lines(path: SpiralPath, values_um: np.ndarray) -> DataLines:
    return DataLines.of(np.degrees(path.phi), path.rho * 1e-3, np.asarray(values_um) * 1e-3)


def spiral_document(
    case: Case,
    specs: Entries,
    chosen: dict[str, Any],
    extra: dict[str, Any],
    created: str,
    generator: str,
) -> tuple[list[str], DataLines, dict[str, Any]]:
    """The header lines, data lines and sidecar content of a spiral case ([4]), planned from
    its spec and entries: export writes them and verify re-derives them."""
    rcase = resolve_case(case, specs=specs)
    assert isinstance(rcase.layout, SpiralPath) and rcase.values is not None
    path = rcase.layout
    if path.n_points != chosen["n_points"]:
        raise ProgramError(f"the cube says {chosen['n_points']} points but the spec plans {path.n_points}")
    lines = _data_lines(path, rcase.values)
    # planned from Z as printed, as the controller executes it
    schedule = layer_schedule(rcase, lines.printed[:, 2] * 1e3)
    rule, value = request_of(case).spiral_rule()
    residual = request_of(case).residual_um
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
        "spindle_rpm": specs.cutting.spindle_rpm,
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
        f"# generator: {generator}",
        f"# surface: {case.surface}; compensation: {case.compensation}",
        f"# tool: nose radius {rcase.nose_radius_um:.6g} um; feed {rcase.feed_um:.9g} um/rev; "
        f"spindle {specs.cutting.spindle_rpm:g} rpm",
        f"# rule: {rule} {value:g} {unit}; residual budget "
        + (f"{residual:g} um" if residual is not None else "none (feed given)"),
        f"# predicted P-V: {chosen['pv_nm']:.6f} nm",
        f"# points: {path.n_points}",
        *_layer_lines(schedule),
        "# units: C [deg] accumulated spindle angle from the edge, X [mm] radius, Z [mm] tool tip",
    ]
    return head, lines, meta


def export_program(
    out: Path,
    side: Path,
    case: Case,
    specs: Entries,
    chosen: dict[str, Any],
    extra: dict[str, Any],
) -> dict[str, Any]:
    """Plan the chosen spiral case again from its recorded spec and entries (the same
    program the cube predicted), and write the program and its sidecar atomically."""
    head, lines, meta = spiral_document(case, specs, chosen, extra, now(), f"ftsweep {__version__}")
    return write_program(out, side, head, COLUMNS, lines, meta)


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


def verify_program(
    path: Path,
    progress: Callable[[int, int], None] | None = None,
    pv_tolerance_nm: float | None = None,
    trust_plugins: bool = False,
) -> dict[str, Any]:
    """Check a spiral program and its sidecar against the program its recorded case plans
    (every header line, every data line within ``LINE_TOLERANCE``: :func:`check_document`),
    then re-simulate the part from the file's own lines. Raises :class:`ProgramError` (an
    ``ExportError``) naming the first mismatch; returns the re-simulated record with the
    predicted P-V and the tolerance applied."""
    path = Path(path)
    doc = read_program_file(path, MAGIC, COLUMNS)
    meta = checked_sidecar(path, doc)
    case, specs = recorded_case_of(meta, sidecar_of(path), trust_plugins)
    planned = spiral_document(
        case, specs, meta["selection"], recorded_extra(meta), meta["created"], meta["generator"]
    )
    check_document(path, doc, planned, meta, COLUMNS)
    data = doc.data
    phi = np.radians(data[:, 0])
    rule, value = request_of(case).spiral_rule()
    spiral_path = SpiralPath("spiral", phi, float(meta["rho0_um"]), float(meta["feed_um"]), rule, value)
    record = run_case(case, specs=specs, progress=progress, program=(spiral_path, data[:, 2] * 1e3))
    return checked_pv(path, meta, record, pv_tolerance_nm)


@functools.cache
def spiral_format() -> FileFormat:
    """The spiral program's file format ([4]): one line C X Z per point."""
    from ftsweep.kinds.spiral.dialect import ADAPTER

    return program_format("spiral program", MAGIC, "C X Z", export_program, verify_program, ADAPTER)
