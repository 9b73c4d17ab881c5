"""How a path kind's programs go into controllers' dialects and come back (docs/controllers.md):
the adapter each kind declares, PVT velocities, a program's stop, its summary and its peaks
against the machine; the moves themselves are :mod:`ftsweep.inputs.programs.moves`."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, Optional

import numpy as np

from ftsweep.inputs.programs.moves import DialectError, Moves
from ftsweep.stages.interpolation import timed_path
from ftsweep.stages.kinematics import axes as kinematics

# PVT velocities in a file's units from the simulator's (C rad/s → deg/s, lengths µm/s → mm/s)
# and back (multiplied both ways, as numpy's degrees and radians do)
_TO_FILE = {"C": math.degrees(1.0), "X": 1e-3, "Y": 1e-3, "Z": 1e-3}
_FROM_FILE = {"C": math.radians(1.0), "X": 1e3, "Y": 1e3, "Z": 1e3}


def with_pvt(moves: Moves, tangents: np.ndarray, axes: str) -> Moves:
    """``moves`` as a PVT program whose segments have ``tangents`` (N − 1, 2K) of the axes
    ``axes`` in the simulator's units (C [rad], lengths [µm]): the velocities a file writes."""
    v = timed_path.velocities(tangents, moves.seconds)
    velocity = {a: v[:, k] * _TO_FILE[a] for k, a in enumerate(axes)}
    return replace(moves, velocity=velocity, interpolation="pvt")


def pvt_tangents(moves: Moves, axes: str) -> np.ndarray:
    """The segments' tangents (N − 1, 2K) a PVT program's velocities of ``axes`` form, in the
    simulator's units (the inverse of :func:`with_pvt`)."""
    assert moves.velocity is not None
    v = np.column_stack([moves.velocity[a] * _FROM_FILE[a] for a in axes])
    return timed_path.from_velocities(v, moves.seconds)


@dataclass(frozen=True)
class Adapter:
    """How a path kind's programs go into controllers' dialects and come back (each kind
    declares its own beside its file format; :mod:`ftsweep.exports.nc` is the generic part).

    planned : ``(case, specs) -> (moves, lines, rcase)``: the program its case plans, as
        moves, the kind's comment-header lines (tool, spindle, points per revolution …) and the
        resolved case it planned, which ``check`` and ``simulate`` take instead of planning again.
    simulate : ``(case, specs, moves, progress, rcase) -> record``: the one simulator on the
        case with its program as ``moves`` command it (``rcase`` None: a program from elsewhere).
    check : ``(rcase, moves) -> reason``: the machine limits the moves leave ('' none).
    commands : ``(moves, per) -> values``: the commands [µm] the simulator forms at ``per``
        parameters u = (j + 0.5)/per of every segment (the compiled reference's check); None:
        the kind's segments are not checked against the reference.
    stand_in : ``(surface, machine, cutting) -> case``: the case a program from elsewhere is
        simulated as (None: only ftsweep's own programs of this kind are read).
    """

    planned: Callable[..., tuple[Moves, list[str], Any]]
    simulate: Callable[..., dict[str, Any]]
    check: Callable[..., str]
    commands: Optional[Callable[[Moves, int], np.ndarray]] = None
    stand_in: Optional[Callable[[str, str, str], Any]] = None


def stop_seconds(m: Moves, machine: Any, quantum_s: float) -> float:
    """How long a PVT program takes to stop after its last point [s]: each axis decelerating
    at a constant rate from its last velocity, no faster than the machine's declared limits
    (its ``axes`` accelerations, the servo's peak acceleration for Z), nor in less time than
    the last segment took; on whole time steps of the controller."""
    assert m.velocity is not None
    rates = {"Z": machine.peak_accel_m_s2 * 1e3}  # mm/s²
    if machine.axes is not None:
        a = machine.axes
        rates.update(X=a.x_accel_m_s2 * 1e3, Z=a.z_accel_m_s2 * 1e3)
        if a.y_accel_m_s2 is not None:
            rates["Y"] = a.y_accel_m_s2 * 1e3
        if a.c_accel_rad_s2 is not None:
            rates["C"] = math.degrees(a.c_accel_rad_s2)
    need = [abs(float(v[-1])) / rates[k] for k, v in m.velocity.items() if k in rates]
    t = max([float(m.seconds[-1]), *need])
    return math.ceil(t / quantum_s - 1e-9) * quantum_s


def with_stop(m: Moves, seconds: float) -> Moves:
    """A PVT program that stops after its last point (docs/controllers.md): one more segment
    of ``seconds`` [s] to a point half its last velocity times that time on, where every axis
    is at rest — the segments' cubic is then a constant deceleration."""
    assert m.velocity is not None
    axes = {"C": m.c_deg, "X": m.x_mm, "Y": m.y_mm, "Z": m.z_mm}
    end = {
        k: float(v[-1]) + 0.5 * float(m.velocity[k][-1]) * seconds for k, v in axes.items() if v is not None
    }
    grown = {k: np.append(v, end[k]) for k, v in axes.items() if v is not None}
    velocity = {k: np.append(v, 0.0) for k, v in m.velocity.items()}
    return replace(
        m,
        c_deg=grown["C"],
        x_mm=grown["X"],
        y_mm=grown.get("Y"),
        z_mm=grown["Z"],
        seconds=np.append(m.seconds, seconds),
        velocity=velocity,
        stopped=True,
        point_lines=None if m.point_lines is None else np.append(m.point_lines, m.point_lines[-1]),
    )


def without_stop(m: Moves) -> Moves:
    """The moves of the planned path: a stopped program's stop segment left out (it runs
    after the last point, beyond the part a kind judges)."""
    if not m.stopped:
        return m
    velocity = None if m.velocity is None else {k: v[:-1] for k, v in m.velocity.items()}
    return replace(
        m,
        c_deg=m.c_deg[:-1],
        x_mm=m.x_mm[:-1],
        y_mm=None if m.y_mm is None else m.y_mm[:-1],
        z_mm=m.z_mm[:-1],
        seconds=m.seconds[:-1],
        velocity=velocity,
        stopped=False,
        point_lines=None if m.point_lines is None else m.point_lines[:-1],
    )


def aligned(moves: Moves, c0_deg: float) -> Moves:
    """``moves`` with C shifted by whole revolutions so that it starts nearest ``c0_deg``: a C
    printed modulo 360 gives the angle, not the revolutions turned before the program starts."""
    turns = round((c0_deg - float(moves.c_deg[0])) / 360.0)
    return replace(moves, c_deg=moves.c_deg + 360.0 * turns)


def _stats(values: np.ndarray) -> dict[str, float]:
    v = values[np.isfinite(values)]
    if not v.size:
        return {"min": math.nan, "median": math.nan, "max": math.nan}
    return {"min": float(v.min()), "median": float(np.median(v)), "max": float(v.max())}


def _feeds(turn: np.ndarray, x_um: np.ndarray) -> np.ndarray:
    """X's drop [µm] over the revolution after each point of a cut that has a whole revolution
    after it (printed positions' rounding averages out over a revolution, where a block's own
    drop of a few nm does not); a cut of less than a revolution: its blocks' drop per turn."""
    on = turn + 1.0 <= turn[-1]
    if np.any(on):
        return x_um[on] - np.interp(turn[on] + 1.0, turn, x_um)
    dx, dturn = -np.diff(x_um), np.diff(turn)
    return np.divide(dx, dturn, out=np.full(dx.shape, np.nan), where=dturn > 0)


def summary(m: Moves) -> dict[str, Any]:
    """Points, revolutions, points per revolution, the feed per revolution [µm] (X's drop
    over a revolution of C, :func:`_feeds`), the time [s] and the spindle speed [rpm] of a program's moves,
    over its cuts (a layered program's approach moves between cuts left out); the spindle
    either way (revolutions counted as turned). Feed, points per revolution (per whole
    revolution turned) and spindle speed (per block) also as min / median / max; the feed per
    block too (X's drop in a block [µm], and that drop over the block's turn [µm/rev]); the
    moves that are not cuts (approaches, returns, standstills) by line."""
    revs, seconds, feeds, counts, rpm, drops, block_feeds = 0.0, 0.0, [], [], [], [], []
    for lo, hi in m.cuts():
        turn = np.abs(m.c_deg[lo:hi] - m.c_deg[lo]) / 360.0
        revs += float(turn[-1])
        drop = -np.diff(m.x_mm[lo:hi] * 1e3)
        drops.append(drop)
        block_feeds.append(
            np.divide(drop, np.diff(turn), out=np.full(drop.shape, np.nan), where=np.diff(turn) > 0)
        )
        dt = m.seconds[lo : hi - 1]
        # SPLINE1 runs one TA more at each end (the controller's added pieces, from and to rest)
        seconds += float(np.sum(dt)) + (
            2.0 * float(dt[0]) if m.interpolation == "spline1" and dt.size else 0.0
        )
        feeds.append(_feeds(turn, m.x_mm[lo:hi] * 1e3))
        dturn = np.diff(turn)
        rpm.append(np.divide(dturn * 60.0, dt, out=np.full(dt.shape, np.nan), where=dt > 0))
        whole = np.maximum(np.ceil(turn[1:]) - 1.0, 0.0)  # a point ending a revolution counts in it
        counts.append(np.bincount(whole.astype(np.int64))[: int(turn[-1])].astype(np.float64))
    direction = "C decreasing" if m.n_points > 1 and m.c_deg[-1] < m.c_deg[0] else "C increasing"
    return {
        "n_points": m.n_points,
        "cuts": len(m.cuts()),
        "revolutions": revs,
        "points_per_rev": (m.n_points - len(m.cuts())) / revs if revs > 0 else math.nan,
        "points_per_rev_range": _stats(np.concatenate(counts)),
        "feed_um_per_rev": _stats(np.concatenate(feeds)),
        # a block's own X drop [µm], and as a feed per revolution (drop / the block's turn), as CAM quotes it
        "feed_um_per_block": _stats(np.concatenate(drops)),
        "feed_um_per_rev_by_block": _stats(np.concatenate(block_feeds)),
        "machining_s": seconds,
        "dwell_s": float(m.dwell_s),
        "standstill_s": float(m.still_s),
        "not_cut": [{"line": line, "what": what} for line, what in m.not_cut],
        "started_from": m.started_from or "the profile's power-on state",
        "spindle_rpm": revs / seconds * 60.0 if seconds > 0 else math.nan,
        "spindle_rpm_range": _stats(np.concatenate(rpm)),
        "spindle_direction": direction,
    }


def peaks(moves: Moves) -> dict[str, float]:
    """Peak X, (Y of a four-axis program), Z and (W, a layered program's servo) speeds [mm/s]
    and accelerations [m/s²] of a program's segments (speeds per segment, accelerations between
    consecutive segments' speeds), over its cuts."""
    cols = {"x": moves.x_mm, "y": moves.y_mm, "z": moves.z_mm, "w": moves.w_mm}
    present = {a: v for a, v in cols.items() if v is not None}
    names = list(present)
    q = np.column_stack(list(present.values())) * 1e-3
    out: dict[str, float] = {f"{a}_{k}": 0.0 for a in names for k in ("speed_mm_s", "accel_m_s2")}
    for lo, hi in moves.cuts():
        if hi - lo < 2:
            continue
        motion = kinematics.over_steps(q[lo:hi], moves.seconds[lo : hi - 1])
        for j, axis in enumerate(names):
            v = float(np.max(np.abs(motion.velocity[:, j]), initial=0.0)) * 1e3
            a = float(np.max(np.abs(motion.accel[:, j]), initial=0.0))
            out[f"{axis}_speed_mm_s"] = max(out[f"{axis}_speed_mm_s"], v)
            out[f"{axis}_accel_m_s2"] = max(out[f"{axis}_accel_m_s2"], a)
    return out


def against(peaks: dict[str, float], machine: Any) -> dict[str, Any]:
    """The peaks beside the machine's limits (its X-Z axes, or the servo's acceleration)."""
    axes = machine.axes
    limits = {
        "x_speed_mm_s": axes.x_feed_mm_s if axes else None,
        "x_accel_m_s2": axes.x_accel_m_s2 if axes else None,
        "y_speed_mm_s": axes.y_feed_mm_s if axes else None,
        "y_accel_m_s2": axes.y_accel_m_s2 if axes else None,
        "z_speed_mm_s": axes.z_velocity_mm_s if axes else None,
        "z_accel_m_s2": axes.z_accel_m_s2 if axes else machine.peak_accel_m_s2,
        "w_speed_mm_s": None,
        "w_accel_m_s2": machine.peak_accel_m_s2,
    }
    return {
        k: {"peak": v, "limit": limits[k], "ok": limits[k] is None or v <= limits[k]}
        for k, v in peaks.items()
    }


def check_velocities(m: Moves, machine: Any, name: str) -> None:
    """Refuse a program's speed over the machine's declared axis limits (its ``axes``: X and Y
    feed, Z velocity [mm/s], C speed [rpm] as deg/s), naming the point's line: a PVT
    program's velocity words, and any program's spindle speed over a block (C's turn over
    the block's time)."""
    axes = machine.axes
    if axes is None:
        return
    limit_c = axes.c_speed_rpm * 6.0
    with np.errstate(divide="ignore", invalid="ignore"):
        spindle = np.abs(np.diff(m.c_deg)) / np.asarray(m.seconds, dtype=np.float64)
    fast = np.flatnonzero(np.isfinite(spindle) & (spindle > limit_c))
    if fast.size:
        k = int(fast[0])
        raise DialectError(
            f"{m.where(k + 1)}: the block turns the spindle at {spindle[k] / 6.0:.6g} rpm, over the "
            f"{axes.c_speed_rpm:g} rpm of machine '{name}'"
        )
    if m.velocity is None:
        return
    limits = {
        "C": limit_c,
        "X": axes.x_feed_mm_s,
        "Y": axes.y_feed_mm_s,
        "Z": axes.z_velocity_mm_s,
    }
    units = {"C": "deg/s", "X": "mm/s", "Y": "mm/s", "Z": "mm/s"}
    for axis, v in m.velocity.items():
        limit = limits.get(axis)
        over = np.flatnonzero(np.abs(v) > limit) if limit is not None else np.empty(0, dtype=np.int64)
        if over.size:
            k = int(over[0])
            raise DialectError(
                f"{m.where(k)}: a {axis} velocity of {float(v[k]):.6g} {units[axis]}, over the "
                f"{limit:g} {units[axis]} of machine '{name}'"
            )
