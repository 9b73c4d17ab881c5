"""Fresnel programs ([2]) in controllers' G-code dialects (docs/controllers.md): the four
channels X, Y, Z, C at the program's own timesteps, one G93 block a point, and the
one simulator run on the blocks as read back."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ftsweep.exports.moves import pvt_tangents, with_pvt, without_stop
from ftsweep.inputs.case_entries import Entries
from ftsweep.kinds.fresnel import program as fp
from ftsweep.kinds.fresnel.study import lines_reason
from ftsweep.stages.paths import fresnel as ff


def _dialect_planned(case: Any, specs: Entries) -> tuple[Any, list[str], Any]:
    """A Fresnel case's moves as planned and timed ([2]): its four channels at its own
    timesteps, one G93 block a point."""
    from ftsweep.exports.dialects import Moves
    from ftsweep.kinds.fresnel.form import record_fields
    from ftsweep.simulate import resolve_case

    rcase = resolve_case(case, specs=specs)
    prog = rcase.layout
    fplan, steps = prog.plan, prog.steps
    fields = record_fields(rcase)
    lines = [
        f"tool: nose radius {fplan.nose_radius_um:g} um, compensation {fplan.compensation}",
        f"spindle: C increasing, {steps.timing} timesteps, {fields['machining_s']:.3f} s in all",
        f"points: {prog.n_points}, {fplan.path.n_turns} turns of {fplan.path.points_per_turn} points, "
        f"feed {fplan.feed_um:g} um per turn, Fresnel facets of {fplan.facet_height_um:g} um",
    ]
    moves = Moves(
        np.degrees(fplan.phi),
        fplan.x_um * 1e-3,
        fplan.tool_z_um * 1e-3,
        np.asarray(steps.steps, dtype=np.float64),
        fplan.y_um * 1e-3,
    )
    if prog.tangents is not None:
        moves = with_pvt(moves, prog.tangents, "CXYZ")
    return moves, lines, rcase


def _columns(moves: Any, rcase: Any) -> np.ndarray:
    """Moves as the text program's columns t [s], C [deg], X, Y, Z [mm], C at the planned
    program's (``rcase``'s) revolutions (:func:`ftsweep.exports.dialects.aligned`)."""
    from ftsweep.exports.dialects import aligned

    moves = aligned(without_stop(moves), math.degrees(float(rcase.layout.plan.phi[0])))
    t = np.concatenate([[0.0], np.cumsum(moves.seconds)])
    return np.column_stack([t, moves.c_deg, moves.x_mm, moves.y_mm, moves.z_mm])


def _dialect_check(rcase: Any, moves: Any) -> str:
    if moves.y_mm is None:
        return "the program gives no Y: a Fresnel program commands X, Y, Z and C"
    return lines_reason(_columns(moves, rcase), fp.limits_of(rcase.machine, rcase.case.machine))


def _dialect_simulate(case: Any, specs: Entries, moves: Any, progress: Any, rcase: Any) -> dict[str, Any]:
    """The planned program (``rcase``) with the moves' X, Y, Z and C (eq. 9 back to the part)."""
    from ftsweep.simulate import run_case

    data = _columns(moves, rcase)
    phi = np.radians(data[:, 1])
    given = rcase.layout._replace(xy=ff.workpiece_of(phi, data[:, 2] * 1e3, data[:, 3] * 1e3))
    if moves.velocity is not None:
        # PVT: the segments the file's C, X, Y and their velocities form
        fplan = given.plan._replace(phi=phi, x_um=data[:, 2] * 1e3, y_um=data[:, 3] * 1e3)
        given = given._replace(plan=fplan, tangents=pvt_tangents(without_stop(moves), "CXYZ"))
    return run_case(case, specs=specs, progress=progress, program=(given, data[:, 4] * 1e3))


def dialect_adapter() -> Any:
    """The Fresnel kind's :class:`ftsweep.exports.dialects.Adapter` (G-code dialects and PMAC PVT)."""
    from ftsweep.exports.dialects import Adapter

    return Adapter(planned=_dialect_planned, simulate=_dialect_simulate, check=_dialect_check)
