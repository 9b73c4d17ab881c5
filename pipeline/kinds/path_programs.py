"""Export and verification of path programs: spiral ([4]), D-path ([5]) and, through
:mod:`ftsweep.kinds.fresnel.study`, Fresnel ([2]) programs. One plain-text line per control point under a
``#`` header of units, surface, tool, budgets and predicted P-V, with a JSON sidecar holding
the full case; both written atomically.

A spiral line is ``C [deg]  X [mm]  Z [mm]``: C the *accumulated* spindle angle (0 at the
part's edge, increasing by 360 per revolution), X the radius of the tool on the spiral and Z
the compensated tool-tip height; the controller interpolates X and Z linearly in C between
consecutive lines. ``CRC32`` in the header covers every other line of the file (the header
lines, the layer offsets and segments included); the header names the sidecar's SHA-256 and
the sidecar the program's (the shared machinery is :mod:`ftsweep.exports.files`). The verify
functions plan the program again from the recorded case and compare it with every line the
machine reads: the header lines exactly, every data line within ``files.LINE_TOLERANCE`` per
column, the sidecar's claims with the re-derived ones.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ftsweep.engine.case import Case
from ftsweep.exports.dialects import Adapter, Moves, aligned
from ftsweep.exports.files import (
    DataLines,
    FileFormat,
    ProgramError,
    case_meta,
    check_document,
    checked_pv,
    checked_sidecar,
    layer_schedule,
    now,
    pv_lines,
    read_program_file,
    recorded_case_of,
    recorded_entries,
    recorded_extra,
    sidecar_of,
    write_program,
)
from ftsweep.exports.moves import pvt_tangents, with_pvt
from ftsweep.simulate import resolve_case, run_case
from ftsweep.stages.spiral import SpiralPath
from ftsweep.version import __version__

MAGIC = "# ftsweep spiral program"
COLUMNS = "C_deg X_mm Z_mm"  # printed with 9 decimals (files.DECIMALS): 1 pm in X and Z, 1e-9 deg in C


def _data_lines(path: SpiralPath, values_um: np.ndarray) -> DataLines:
    return DataLines.of(np.degrees(path.phi), path.rho * 1e-3, np.asarray(values_um) * 1e-3)


def spiral_document(
    case: Case,
    specs: tuple[Any, Any, Any],
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
        f"# generator: {generator}",
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


def read_program(path: Path, magic: str = MAGIC, columns: str = COLUMNS) -> tuple[dict[str, str], np.ndarray]:
    """The header fields and the (N, columns) data of a program file, its CRC checked."""
    doc = read_program_file(path, magic, columns)
    return doc.fields, doc.data


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
    rule, value = case.layout.spiral_rule()
    spiral_path = SpiralPath("spiral", phi, float(meta["rho0_um"]), float(meta["feed_um"]), rule, value)
    record = run_case(case, specs=specs, progress=progress, program=(spiral_path, data[:, 2] * 1e3))
    return checked_pv(path, meta, record, pv_tolerance_nm)


# --------------------------------------------------------------------------- D paths ([5])
D_MAGIC = "# ftsweep D-path program"
D_COLUMNS = "t_s C_deg X_mm Z_mm"


def _as_run(path: Any, data: np.ndarray) -> Any:
    """The D path as a program's lines (t [s], C [deg], X [mm], Z [mm]) run it: their C, X and
    times on the planned cuts' geometry."""
    return path._replace(phi=np.radians(data[:, 1]), rho=data[:, 2] * 1e3, t_s=data[:, 0])


def _limits_of_lines(machine: Any, rpm: float, path: Any, data: np.ndarray) -> str:
    """The axis limits a D-path program's lines exceed ('' when none) on the planned path
    ``path`` through them, sampled every controller period at the lines' times
    (:func:`ftsweep.kinds.dpath.program.motion_summary` of :func:`_as_run`: what the record of a case
    simulated from these lines reports)."""
    from ftsweep.kinds.dpath import program as dprog

    if not np.all(np.diff(data[:, 0]) > 0.0):
        return "time does not increase from line to line"
    return dprog.motion_summary(_as_run(path, data), data[:, 3] * 1e3, rpm, machine)[1]


def dpath_document(
    case: Case,
    specs: tuple[Any, Any, Any],
    chosen: dict[str, Any],
    extra: dict[str, Any],
    created: str,
    generator: str,
    rcase: Any = None,
) -> tuple[list[str], DataLines, dict[str, Any]]:
    """The header lines, data lines and sidecar content of a D-path case ([5]), planned from
    its spec and entries (or ``rcase``, resolved already): export writes, verify re-derives."""
    from ftsweep.kinds.dpath import program as dprog

    rcase = rcase if rcase is not None else resolve_case(case, specs=specs)
    path, z = rcase.layout, rcase.values
    rpm = specs[2].spindle_rpm
    t = dprog.times(path, z, rpm)
    period = dprog.period_of(specs[1])
    lines = DataLines.of(t, np.degrees(path.phi), path.rho * 1e-3, z * 1e-3)
    g = path.geometry
    own = {
        "spacing_um": g.spacing_um,
        "points_per_cut": path.points_per_cut,
        "transition": g.transition,
        "zones": g.zones,
        "nose_radius_um": rcase.nose_radius_um,
        "spindle_rpm": rpm,
        "machining_s": float(t[-1]),
    }
    meta = case_meta("dpath", case, specs, chosen, extra, (created, generator), path.n_points, own)
    head = [
        f"{D_MAGIC} (X, Z and C move linearly in time between consecutive lines)",
        f"# generator: {generator}",
        f"# surface: {case.surface}; compensation: {case.compensation}; machine: {case.machine}",
        f"# zone: {g.length_um / 1e3:.6g} x {g.width_um / 1e3:.6g} mm, centre {g.centre_um / 1e3:.6g} mm off-axis; "  # noqa: E501
        f"{g.zones} zone(s) per revolution",
        f"# cuts: {path.n_cuts} at spacing {g.spacing_um:.9g} um, {path.points_per_cut} points each; "
        f"transition {g.transition}",
        f"# tool: nose radius {rcase.nose_radius_um:.6g} um; spindle {rpm:g} rpm (constant)",
        f"# timing: {float(t[-1]):.3f} s in all",
        f"# axis limits checked on the planned path through the lines every controller period "
        f"({period * 1e3:.6g} ms, a {math.degrees(period * rpm * math.pi / 30.0):.4g} deg C step)",
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
    rcase: Any = None,
) -> dict[str, Any]:
    """Plan the chosen D-path case again ([5]) and write it as position-time lines
    (t [s] at constant spindle speed, accumulated C [deg], X [mm], Z [mm]) with its sidecar,
    atomically; refused if any line leaves the machine's axis limits. ``rcase``: the case as
    :func:`ftsweep.engine.planning.resolve_case` planned it from these entries already (a study)."""
    rcase = rcase if rcase is not None else resolve_case(case, specs=specs)
    head, lines, meta = dpath_document(case, specs, chosen, extra, now(), f"ftsweep {__version__}", rcase)
    reason = _limits_of_lines(specs[1], specs[2].spindle_rpm, rcase.layout, lines.printed)
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
    meta = checked_sidecar(path, doc)
    case, specs = recorded_case_of(meta, sidecar_of(path), trust_plugins)
    # planned once: its lines are compared, its cut geometry carries the file's points
    rcase = resolve_case(case, specs=specs)
    planned = dpath_document(
        case, specs, meta["selection"], recorded_extra(meta), meta["created"], meta["generator"], rcase
    )
    check_document(path, doc, planned, meta, D_COLUMNS)
    data = doc.data
    if not np.all(np.diff(data[:, 0]) > 0.0):
        raise ProgramError(f"{path}: time does not increase from line to line; do not run it")
    # the record's axis motion is that of the lines as they stand (their times included): the
    # limits check the export made, done once
    record = run_case(
        case, specs=specs, progress=progress, program=(_as_run(rcase.layout, data), data[:, 3] * 1e3)
    )
    if record["infeasible_reason"]:
        raise ProgramError(
            f"{path}: a line leaves the axis limits of machine '{case.machine}': "
            f"{record['infeasible_reason']}; do not run it"
        )
    return checked_pv(path, meta, record, pv_tolerance_nm)


def _dpath_planned(case: Case, specs: tuple[Any, Any, Any]) -> tuple[Moves, list[str], Any]:
    """A D path's moves as planned ([5]): its lines t, C, X, Z as G93 blocks."""
    from ftsweep.kinds.dpath import program as dprog

    rcase = resolve_case(case, specs=specs)
    path, z = rcase.layout, np.asarray(rcase.values)
    rpm = specs[2].spindle_rpm
    t = dprog.run_times(path, z, rpm)
    g = path.geometry
    lines = [
        f"tool: nose radius {rcase.nose_radius_um:.6g} um",
        f"spindle: {rpm:g} rpm constant, C increasing",
        f"points: {path.n_points}, {path.n_cuts} cuts of {path.points_per_cut} at spacing "
        f"{g.spacing_um:.9g} um, {g.zones} zones per revolution, {float(t[-1]):.3f} s",
    ]
    moves = Moves(np.degrees(path.phi), path.rho * 1e-3, z * 1e-3, np.diff(t))
    if path.tangents is not None:
        moves = with_pvt(moves, path.tangents, "CXZ")
    return moves, lines, rcase


def _dpath_columns(moves: Moves, path: Any) -> np.ndarray:
    """A D path's moves as the text program's columns t [s], C [deg], X [mm], Z [mm], C at
    the planned path's revolutions (:func:`ftsweep.exports.dialects.aligned`)."""
    moves = aligned(moves, math.degrees(float(path.phi[0])))
    t = np.concatenate([[0.0], np.cumsum(moves.seconds)])
    return np.column_stack([t, moves.c_deg, moves.x_mm, moves.z_mm])


def _dpath_check(rcase: Any, moves: Moves) -> str:
    path = rcase.layout
    return _limits_of_lines(rcase.machine, rcase.cutting.spindle_rpm, path, _dpath_columns(moves, path))


def _dpath_simulate(
    case: Case, specs: tuple[Any, Any, Any], moves: Moves, progress: Any, rcase: Any
) -> dict[str, Any]:
    """The planned D path (``rcase``) run through the moves' t, C, X and Z (PVT: the
    segments their velocities form)."""
    data = _dpath_columns(moves, rcase.layout)
    run = _as_run(rcase.layout, data)
    if moves.velocity is not None:
        run = run._replace(tangents=pvt_tangents(moves, "CXZ"))
    return run_case(case, specs=specs, progress=progress, program=(run, data[:, 3] * 1e3))


DPATH_ADAPTER = Adapter(planned=_dpath_planned, simulate=_dpath_simulate, check=_dpath_check)


def _program_format(
    title: str, magic: str, columns: str, write: Any, check: Any, dialect: Any = None
) -> FileFormat:
    def exported(out: Path, meta: dict[str, Any]) -> list[str]:
        return [f"program      {out} ({meta['n_points']:,} lines {columns}, CRC-32 0x{meta['crc32']:08x})"]

    def verified(record: dict[str, Any]) -> list[str]:
        return [
            f"checksum     {record['checksum']} (every line) ok; sidecar and file hashes ok",
            f"program      {record['layout']}: {record['n_points']:,} points, every line as re-planned",
            *pv_lines(record, "the program's lines"),
        ]

    def export(*args: Any, name: str | None = None) -> dict[str, Any]:
        return dict(write(*args))  # a program's lines need no C identifiers

    return FileFormat(title, magic, export, check, exported, verified, dialect)


@functools.cache
def spiral_format() -> FileFormat:
    """The spiral program's file format ([4]): one line C X Z per point."""
    from ftsweep.kinds.spiral.dialect import ADAPTER

    return _program_format("spiral program", MAGIC, "C X Z", export_program, verify_program, ADAPTER)


@functools.cache
def dpath_format() -> FileFormat:
    """The D-path program's file format ([5]): one line t C X Z per point."""
    return _program_format("D-path program", D_MAGIC, "t C X Z", export_dpath, verify_dpath, DPATH_ADAPTER)
