"""The D-path program's file ([5]): one plain-text line per point, ``t [s]  C [deg]  X [mm]
Z [mm]``, X, Z and C moving linearly in time between consecutive lines; its dialect adapter.
Verify plans the program again from the recorded case and compares every line the machine
reads (the machinery: :mod:`ftsweep.exports.programs`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ftsweep.engine.case import Case
from ftsweep.engine.contract import FileFormat
from ftsweep.exports.dialects import Adapter, Moves, aligned
from ftsweep.exports.files import (
    DataLines,
    ProgramError,
    case_meta,
    check_document,
    checked_pv,
    checked_sidecar,
    now,
    read_program_file,
    recorded_case_of,
    recorded_extra,
    write_program,
)
from ftsweep.exports.moves import pvt_tangents, with_pvt, without_stop
from ftsweep.exports.programs import program_format
from ftsweep.inputs.case_entries import Entries
from ftsweep.simulate import resolve_case, run_case
from ftsweep.store.io import sidecar_of
from ftsweep.version import __version__

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
    specs: Entries,
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
    rpm = specs.cutting.spindle_rpm
    t = dprog.times(path, z, rpm)
    period = dprog.period_of(specs.machine)
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
    specs: Entries,
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
    reason = _limits_of_lines(specs.machine, specs.cutting.spindle_rpm, rcase.layout, lines.printed)
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


def _dpath_planned(case: Case, specs: Entries) -> tuple[Moves, list[str], Any]:
    """A D path's moves as planned ([5]): its lines t, C, X, Z as G93 blocks."""
    from ftsweep.kinds.dpath import program as dprog

    rcase = resolve_case(case, specs=specs)
    path, z = rcase.layout, np.asarray(rcase.values)
    rpm = specs.cutting.spindle_rpm
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
    moves = aligned(without_stop(moves), math.degrees(float(path.phi[0])))
    t = np.concatenate([[0.0], np.cumsum(moves.seconds)])
    return np.column_stack([t, moves.c_deg, moves.x_mm, moves.z_mm])


def _dpath_check(rcase: Any, moves: Moves) -> str:
    path = rcase.layout
    return _limits_of_lines(rcase.machine, rcase.cutting.spindle_rpm, path, _dpath_columns(moves, path))


def _dpath_simulate(case: Case, specs: Entries, moves: Moves, progress: Any, rcase: Any) -> dict[str, Any]:
    """The planned D path (``rcase``) run through the moves' t, C, X and Z (PVT: the
    segments their velocities form)."""
    data = _dpath_columns(moves, rcase.layout)
    run = _as_run(rcase.layout, data)
    if moves.velocity is not None:
        run = run._replace(tangents=pvt_tangents(without_stop(moves), "CXZ"))
    return run_case(case, specs=specs, progress=progress, program=(run, data[:, 3] * 1e3))


DPATH_ADAPTER = Adapter(planned=_dpath_planned, simulate=_dpath_simulate, check=_dpath_check)


@functools.cache
def dpath_format() -> FileFormat:
    """The D-path program's file format ([5]): one line t C X Z per point."""
    return program_format("D-path program", D_MAGIC, "t C X Z", export_dpath, verify_dpath, DPATH_ADAPTER)
