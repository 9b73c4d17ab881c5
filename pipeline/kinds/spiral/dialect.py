"""Spiral programs ([4]) in controllers' dialects (docs/controllers.md): the planned spiral as
moves at a constant spindle speed, and any dialect's moves (ftsweep's or another CAM's) as the
program the one simulator runs, its segments formed as the controller forms them."""

from __future__ import annotations

import math
from typing import Any, Optional

import numpy as np

from ftsweep.engine.case import Case, CaseError
from ftsweep.exports.dialects import Adapter, DialectError, Moves
from ftsweep.exports.files import layer_schedule
from ftsweep.simulate import resolve_case, run_case
from ftsweep.stages import segments
from ftsweep.stages.spiral import SpiralPath, angular_speed, spiral_commands


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


def _planned(case: Case, specs: tuple[Any, Any, Any]) -> tuple[Moves, list[str], Any]:
    rcase = resolve_case(case, specs=specs)
    path = rcase.layout
    if layer_schedule(rcase, rcase.values) is not None:
        raise CaseError(
            "a layered spiral (commands beyond the servo's travel, [3]) is written in ftsweep's text "
            "only: its layer changes are not blocks of one Z axis"
        )
    rpm = specs[2].spindle_rpm
    lines = [
        f"tool: nose radius {rcase.nose_radius_um:.6g} um, feed {rcase.feed_um:.9g} um/rev",
        f"spindle: {rpm:g} rpm, C increasing, the spiral runs from the edge to the centre",
        f"points: {path.n_points}, {path.max_points_per_rev} per revolution at most, "
        f"{path.revolutions:.6g} revolutions",
    ]
    return moves_of(path, rcase.values, rpm), lines, rcase


# how far a program's X may lie off the Archimedean spiral its first and last points set [µm]:
# the printed digits' rounding and a thousandth of the feed
SPIRAL_SLACK_UM = 1e-3
SPIRAL_SLACK_FEED = 1e-3


def program_of(moves: Moves) -> tuple[SpiralPath, np.ndarray]:
    """The spiral path and commands [µm] a program's moves give the one simulator: φ from C
    (accumulated), ρ0 and the feed from X (refused unless X follows ρ0 − F·φ/2π), and the
    segments its interpolation forms (PVT: tangents V·T; SPLINE1: the B-spline of its
    control points)."""
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
            f"point {worst + 1}: X is {off[worst]:.4g} µm off the spiral of constant feed {feed:.6g} µm/rev "
            "through the first and last points: the one simulator predicts constant-feed spirals only"
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
    specs: Optional[tuple[Any, Any, Any]],
    moves: Moves,
    progress: Any = None,
    rcase: Any = None,
) -> dict[str, Any]:
    """The case with its program as ``moves`` command it (``rcase`` unused: the moves are the
    whole program)."""
    return run_case(case, specs=specs, progress=progress, program=program_of(moves))


def _commands(moves: Moves, per: int) -> np.ndarray:
    """The simulator's commands [µm] at u = (j + 0.5)/per of every segment, by the spiral's
    own evaluation (:func:`ftsweep.stages.spiral.spiral_commands`) at those angles."""
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
