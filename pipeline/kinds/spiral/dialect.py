"""Spiral programs ([4]) in controllers' dialects (docs/controllers.md): the planned spiral as
moves at a constant spindle speed, and any dialect's moves (ftsweep's or another CAM's) as the
program the one simulator runs, its segments formed as the controller forms them."""

from __future__ import annotations

import math
from typing import Any, Optional

import numpy as np

from ftsweep.engine.case import Case, CaseError
from ftsweep.engine.planning import layer_plan
from ftsweep.exports.dialects import Adapter, DialectError, Moves
from ftsweep.exports.moves import pvt_tangents
from ftsweep.inputs.case_entries import Entries
from ftsweep.simulate import resolve_case, run_case
from ftsweep.stages.interpolation import segments
from ftsweep.stages.interpolation.spiral_program import (
    SpiralPath,
    angular_speed,
    spiral_commands,
    spiral_radius,
)
from ftsweep.stages.paths.commanded import CommandedPath


def moves_of(path: SpiralPath, values_um: np.ndarray, rpm: float) -> Moves:
    """A planned spiral (points, commands [µm], its segments) as a controller's moves at a
    constant spindle speed: C accumulated [deg], X [mm], Z [mm], segment times [s]; PVT
    velocities from the segments' tangents (C¹: one velocity a point); a SPLINE1 program's Z
    as its control points."""
    w = angular_speed(rpm)
    phi = path.phi
    seconds = np.diff(phi) / w
    z = np.asarray(values_um) * 1e-3
    velocity = None
    if path.interpolation == "pvt":
        assert path.d0 is not None and path.d1 is not None
        dphi = np.diff(phi)
        slope = np.append(path.d0 / dphi, path.d1[-1] / dphi[-1])  # µm/rad
        velocity = {
            "C": np.full(phi.size, math.degrees(w)),
            "X": np.full(phi.size, -path.feed_um / (2.0 * math.pi) * w * 1e-3),
            "Z": slope * w * 1e-3,
        }
    elif path.interpolation == "spline1":
        z = segments.control_points(np.asarray(values_um)) * 1e-3
    return Moves(np.degrees(phi), path.rho * 1e-3, z, seconds, None, velocity, path.interpolation)


def _planned(case: Case, specs: Entries) -> tuple[Moves, list[str], Any]:
    rcase = resolve_case(case, specs=specs)
    path = rcase.layout
    rpm = specs.cutting.spindle_rpm
    lines = [
        f"tool: nose radius {rcase.nose_radius_um:.6g} um, feed {rcase.feed_um:.9g} um/rev",
        f"spindle: {rpm:g} rpm, C increasing, the spiral runs from the edge to the centre",
        f"points: {path.n_points}, {path.max_points_per_rev} per revolution at most, "
        f"{path.revolutions:.6g} revolutions",
    ]
    servo_s = specs.machine.controller.servo_period_s if specs.machine.controller is not None else None
    if servo_s and path.interpolation != "spline1":
        last_ms = float(path.phi[-1] - path.phi[-2]) / angular_speed(rpm) * 1e3
        lines.append(
            f"end: the last block into the centre takes {last_ms:.6g} ms, a last block under the "
            f"controller's servo period {servo_s * 1e3:g} ms is merged into the one before it"
        )
    plan = layer_plan(rcase, np.asarray(rcase.values, dtype=np.float64))
    if plan is None:
        return moves_of(path, rcase.commands_um, rpm), lines, rcase
    if path.interpolation != "linear":
        raise CaseError("a layered spiral ([3]) is planned for linear segments only")
    moves = layered_moves(path, rcase.commands_um, rpm, plan)
    lines.append(
        f"layers: {plan.n_layers} of {plan.zone_um:.6g} um, {len(moves.cuts())} cuts, Z the slide's "
        f"offset in each layer, W the servo's stroke from 0 to {plan.travel_um:.6g} um, the tool at Z + W"
    )
    return moves, lines, rcase


def layered_moves(path: SpiralPath, values_um: np.ndarray, rpm: float, plan: Any) -> Moves:
    """A layered spiral ([3], :mod:`ftsweep.stages.paths.layers`) as a controller's cuts, one a
    segment in the plan's order: the spiral's points inside the segment with its two ends
    (on the program's linear segments, so the path is the single pass's), C accumulated
    [deg], X [mm], Z the layer's slide offset [mm], W = clip(w − offset, 0, travel) the
    servo's stroke [mm], block times [s] at the spindle speed (NaN into a cut's start)."""
    w = angular_speed(rpm)
    phi, values = path.phi, np.asarray(values_um, dtype=np.float64)
    parts: dict[str, list[np.ndarray]] = {"phi": [], "w": [], "z": []}
    offsets = plan.offsets_um
    for layer, a, b in zip(
        plan.seg_layer.tolist(), plan.seg_start.tolist(), plan.seg_end.tolist(), strict=True
    ):
        if not b > a:
            continue  # a segment of no length cuts nothing
        inside = slice(int(np.searchsorted(phi, a, side="right")), int(np.searchsorted(phi, b, side="left")))
        ends = spiral_commands(path, values, np.array([a, b]))
        parts["phi"].append(np.concatenate([[a], phi[inside], [b]]))
        parts["w"].append(np.concatenate([ends[:1], values[inside], ends[1:]]))
        parts["z"].append(np.full(parts["w"][-1].size, offsets[layer]))
    sizes = np.array([p.size for p in parts["phi"]])
    phi_all, total, slide = (np.concatenate(parts[k]) for k in ("phi", "w", "z"))
    seconds = np.diff(phi_all) / w
    starts = np.cumsum(sizes)[:-1]
    seconds[starts - 1] = np.nan
    stroke = np.clip(total - slide, 0.0, plan.travel_um)
    rho = spiral_radius(phi_all, path.rho0_um, path.feed_um)
    return Moves(
        np.degrees(phi_all),
        rho * 1e-3,
        slide * 1e-3,
        seconds,
        w_mm=stroke * 1e-3,
        cut_starts=starts if starts.size else None,
    )


# why a layered program's P-V is not predicted from the file alone: it does not say the stroke its W
# was clipped to, nor (C modulo 360) the revolution each cut starts on
LAYERED_FROM_ELSEWHERE = (
    "a layered program (several cuts, a servo W at the slide's offsets) is predicted from its "
    "export: ftsweep verify FILE; predict --program reads single-cut programs"
)

# how far a program's X may lie off the Archimedean spiral its first and last points set [µm]:
# the printed digits' rounding and a thousandth of the feed
SPIRAL_SLACK_UM = 1e-3
SPIRAL_SLACK_FEED = 1e-3


def program_of(moves: Moves) -> tuple[SpiralPath, np.ndarray]:
    """The spiral path and commands [µm] a program's moves give the one simulator: φ from C
    (accumulated), ρ0 and the feed from X (refused unless X follows ρ0 − F·φ/2π), and the
    segments its interpolation forms (PVT: tangents V·T; SPLINE1: the B-spline of its
    control points)."""
    if moves.cut_starts is not None or moves.w_mm is not None:
        raise DialectError(LAYERED_FROM_ELSEWHERE)
    phi = np.radians(moves.c_deg)
    if moves.n_points < 3 or not np.all(np.diff(phi) > 0.0):
        raise DialectError("a spiral program needs at least 3 points with C increasing from block to block")
    x_um = moves.x_mm * 1e3
    feed = 2.0 * math.pi * float(x_um[0] - x_um[-1]) / float(phi[-1] - phi[0])
    if not feed > 0.0:
        raise DialectError(
            "X does not decrease along the program: not a facing spiral from the edge to the centre"
        )
    rho0 = float(x_um[0]) + feed * float(phi[0]) / (2.0 * math.pi)
    off = np.abs(rho0 - feed * phi / (2.0 * math.pi) - x_um)
    worst = int(np.argmax(off))
    if off[worst] > SPIRAL_SLACK_UM + SPIRAL_SLACK_FEED * feed:
        raise DialectError(
            f"{moves.where(worst)}: X is {off[worst]:.4g} µm off the spiral of constant feed {feed:.6g} "
            "µm/rev through the first and last points: the one simulator predicts constant-feed spirals only"
        )
    z_um = moves.z_mm * 1e3
    path = SpiralPath("spiral", phi, rho0, feed, "chord", 0.0)
    if moves.interpolation == "linear":
        return path, z_um
    if moves.interpolation == "pvt":
        assert moves.velocity is not None
        d0, d1 = segments.pvt_tangents(moves.velocity["Z"] * 1e3, moves.seconds)
        return path._replace(interpolation="pvt", d0=d0, d1=d1), z_um
    way, d0, d1 = segments.bspline_segments(z_um)
    return path._replace(interpolation="spline1", d0=d0, d1=d1), way


def _simulate(
    case: Case,
    specs: Optional[Entries],
    moves: Moves,
    progress: Any = None,
    rcase: Any = None,
) -> dict[str, Any]:
    """The case with its program as ``moves`` command it: ftsweep's own program (``rcase``,
    the case it was planned as) as the spiral it plans, judged as its cube was, from the
    centre to the outer edge band (a layered program's single pass: :func:`single_pass`); a
    program from elsewhere as every pass it makes, as its controller makes it
    (:func:`commanded_of`), judged over the same zone."""
    if rcase is None:
        return run_case(case, specs=specs, progress=progress, program=commanded_of(moves))
    program = program_of(moves) if moves.w_mm is None else single_pass(moves, rcase)
    return run_case(case, specs=specs, progress=progress, program=program)


def commanded_of(moves: Moves) -> tuple[CommandedPath, np.ndarray]:
    """A program's moves as the path the one simulator follows and its tool tip's Z [µm]
    (Z + W for a layered program): C in rad times the spindle's sense, so that the angle
    increases, X in µm (a four-axis program's (X, Y) turned by C: :func:`_turned`); the
    segments the controller forms (PVT: the velocities' tangents; SPLINE1: the B-spline's
    way-points and tangents over each cut's control points)."""
    c, rho = np.radians(moves.c_deg), moves.x_mm * 1e3
    if moves.y_mm is not None and np.any(moves.y_mm != 0.0):
        c, rho = _turned(moves)
    sense = -1.0 if c[-1] < c[0] else 1.0
    angle = sense * c
    z = moves.z_mm * 1e3 + (0.0 if moves.w_mm is None else moves.w_mm * 1e3)
    starts = np.array([lo for lo, _ in moves.cuts()], dtype=np.int64)
    for lo, hi in moves.cuts():
        if np.any(np.diff(angle[lo:hi]) <= 0.0):
            k = lo + int(np.flatnonzero(np.diff(angle[lo:hi]) <= 0.0)[0]) + 1
            raise DialectError(
                f"{moves.where(k)}: C stands still or turns back within a cut; the spindle turns one way"
            )
    tangents = None
    if moves.interpolation == "pvt":
        tangents = pvt_tangents(moves, "CXZ")
        tangents[:, 0:2] *= sense
    elif moves.interpolation == "spline1":
        return _spline1_path(moves, angle, rho, z, sense)
    path = CommandedPath(
        "spiral", angle, rho, starts, sense, moves.interpolation, tangents, np.asarray(moves.seconds)
    )
    return path, z


def _turned(moves: Moves) -> tuple[np.ndarray, np.ndarray]:
    """A four-axis program's tool on the part: (X, Y) turned by C, its polar angle C +
    atan2(Y, X) [rad] (unwrapped along each cut) and radius hypot(X, Y) [µm] — linear between
    points in those, as a C-X program is in C and X."""
    if moves.interpolation != "linear":
        raise DialectError(
            "a four-axis PVT or SPLINE1 program (Y moving) is predicted from its export (ftsweep "
            "verify FILE); predict --program simulates its G-code"
        )
    assert moves.y_mm is not None
    x, y = moves.x_mm * 1e3, moves.y_mm * 1e3
    turn = np.radians(moves.c_deg) + np.arctan2(y, x)
    for lo, hi in moves.cuts():
        turn[lo:hi] = turn[lo] + np.unwrap(turn[lo:hi] - turn[lo])
    return turn, np.hypot(x, y)


def _spline1_path(
    moves: Moves, angle: np.ndarray, rho: np.ndarray, z: np.ndarray, sense: float
) -> tuple[CommandedPath, np.ndarray]:
    """A SPLINE1 program's path as the controller runs it: each cut's control points with the
    manual's added pieces (from and to rest, one TA more at each end:
    :func:`ftsweep.stages.interpolation.segments.added_pieces_segments`); the segment from one
    cut's end to the next cut's start is an approach (its time NaN, never cut)."""
    chans: list[list[np.ndarray]] = [[], [], []]
    tans: list[np.ndarray] = []
    times: list[np.ndarray] = []
    starts: list[int] = []
    for lo, hi in moves.cuts():
        if starts:  # the approach into this cut
            tans.append(np.zeros((1, 6)))
            times.append(np.array([np.nan]))
        starts.append(sum(c.size for c in chans[0]))
        cut = []
        for k, chan in enumerate((angle, rho, z)):
            way, d0, d1 = segments.added_pieces_segments(chan[lo:hi])
            chans[k].append(way)
            cut += [d0, d1]
        tans.append(np.column_stack(cut))
        times.append(np.full(hi - lo + 1, float(moves.seconds[lo])))
    a, r, zz = (np.concatenate(c) for c in chans)
    starts_ = np.array(starts, dtype=np.int64)
    path = CommandedPath("spiral", a, r, starts_, sense, "spline1", np.vstack(tans), np.concatenate(times))
    return path, zz


def single_pass(moves: Moves, rcase: Any) -> tuple[SpiralPath, np.ndarray]:
    """The single pass a layered program's cuts execute ([3]): every cut on the spiral's
    revolutions (C printed modulo 360 placed by its X on the planned spiral ``rcase``), the
    tool at Z + W [µm]; a point several cuts pass takes the command of the cut whose servo
    was not at an end of its stroke there (a dip below a layer's zone is cut in the air at the
    zone's bottom), else the lowest. The simulator plans the layers again from it."""
    if rcase is None:
        raise DialectError(LAYERED_FROM_ELSEWHERE)
    assert moves.w_mm is not None
    rho0, feed = rcase.rho0_um, rcase.feed_um
    travel = float(rcase.machine.travel_um)
    phi, x, tool, free = [], [], [], []
    for lo, hi in moves.cuts():
        c = moves.c_deg[lo:hi]
        expected = math.degrees(2.0 * math.pi * (rho0 - moves.x_mm[lo] * 1e3) / feed)
        phi.append(np.radians(c + 360.0 * round((expected - float(c[0])) / 360.0)))
        x.append(moves.x_mm[lo:hi])
        w = moves.w_mm[lo:hi] * 1e3
        tool.append(moves.z_mm[lo:hi] * 1e3 + w)
        free.append((w > 0.0) & (w < travel))
    p, xs, t, f = (np.concatenate(v) for v in (phi, x, tool, free))
    # per angle: the unclipped command first, then the lowest
    order = np.lexsort((t, ~f, p))
    p, xs, t = p[order], xs[order], t[order]
    first = np.concatenate([[True], np.diff(p) > 0.0])
    one = Moves(np.degrees(p[first]), xs[first], t[first] * 1e-3, np.diff(p[first]))
    return program_of(one)


def _commands(moves: Moves, per: int) -> np.ndarray:
    """The simulator's commands [µm] at u = (j + 0.5)/per of every segment, by the spiral's
    own evaluation (:func:`ftsweep.stages.interpolation.spiral_program.spiral_commands`) at those angles."""
    if moves.w_mm is not None:
        raise DialectError(
            "a layered program's cuts are checked by verify's reader and re-simulation; the compiled "
            "reference runs single-cut programs"
        )
    path, values = program_of(moves)
    u = (np.arange(per) + 0.5) / per
    phi = path.phi[:-1, None] + np.diff(path.phi)[:, None] * u[None, :]
    return spiral_commands(path, values, phi.ravel())


def stand_in_case(surface: str, machine: str, cutting: str) -> Case:
    """The case a spiral program from elsewhere is simulated as: its surface and entries, a
    spiral request whose program the file's moves replace."""
    from ftsweep.engine.case import program_request

    try:
        return Case(
            surface=surface,
            machine=machine,
            cutting=cutting,
            layout=program_request(kind="spiral", points_per_rev=16),
        )
    except ValueError as exc:
        raise CaseError(str(exc)) from None


ADAPTER = Adapter(
    planned=_planned,
    simulate=_simulate,
    check=lambda rcase, moves: "",  # the spiral's limits are checked in planning
    commands=_commands,
    stand_in=stand_in_case,
)
