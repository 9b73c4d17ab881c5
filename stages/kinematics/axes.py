"""Axis kinematics of any program and the machine's limits (model §6 "Dynamics"; [2] eq. 14).

A program is its axes' positions q (P points × A axes, SI: C in rad, linear axes in m) at
times t (P) [s]; the machine moves every axis linearly from point to point. One difference
scheme serves every kind:

- velocity over step i (between points i and i+1): v_i = (q_{i+1} − q_i)/T_i, what the axis
  moves at along the step;
- acceleration at point i: a_i = 2·(v_i − v_{i−1})/(T_{i−1} + T_i), the velocity change at the
  point over the mean of its two steps ([2] eq. 14; on a uniform step T it is the second
  difference (q_{i+1} − 2q_i + q_{i−1})/T², the scheme of the W command at the controller's
  command period, :mod:`ftsweep.stages.kinematics.dynamics`); zero at the first and last point.

At a slope discontinuity (a junction of two curves), the acceleration is the velocity jump over
the local step: it grows as the step shrinks, so it means something only at a step the machine
sets (its command period, or the program's own step if the controller runs it point by point).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numba import njit

# display units of each axis kind: (position, velocity, acceleration) names and factors from SI
_LINEAR = (("mm", 1e3), ("mm/s", 1e3), ("m/s²", 1.0))
_ROTARY = (("°", 180.0 / math.pi), ("rpm", 60.0 / (2.0 * math.pi)), ("rad/s²", 1.0))


@njit(nogil=True, cache=True)
def accelerations(q: np.ndarray, steps: np.ndarray) -> np.ndarray:  # pragma: no cover - jit
    """Accelerations a (P, A) [q's unit/s²] of positions q (P, A) over timesteps ``steps``
    (P − 1) [s]: the velocity change at each point over the mean of its two steps ([2] eq. 14);
    zero at the first and last point."""
    n, m = q.shape
    a = np.zeros((n, m))
    for i in range(1, n - 1):
        t0, t1 = steps[i - 1], steps[i]
        for j in range(m):
            a[i, j] = 2.0 * ((q[i + 1, j] - q[i, j]) / t1 - (q[i, j] - q[i - 1, j]) / t0) / (t0 + t1)
    return a


@njit(nogil=True, cache=True)
def turn_peaks(
    q: np.ndarray,
    steps: np.ndarray,
    accel_limit: np.ndarray,
    velocity_limit: np.ndarray,
    k: int,
    which: np.ndarray,
    peak_a: np.ndarray,
    peak_v: np.ndarray,
) -> None:  # pragma: no cover - jit
    """Largest relative acceleration |a|/a_lim over the points of each turn in ``which`` (K
    points from turn·K on; eq. 14 as :func:`accelerations`, the same arithmetic) and largest
    relative velocity |v|/v_lim over its K steps, into ``peak_a`` and ``peak_v`` at the turn's
    index: the turns whose timesteps changed, without the whole program's arrays."""
    n, m = q.shape
    for turn in which:
        big_a = 0.0
        big_v = 0.0
        for i in range(turn * k, (turn + 1) * k):
            t1 = steps[i]
            for j in range(m):
                big_v = max(big_v, abs((q[i + 1, j] - q[i, j]) / t1) / velocity_limit[j])
                if 0 < i < n - 1:
                    t0 = steps[i - 1]
                    a = 2.0 * ((q[i + 1, j] - q[i, j]) / t1 - (q[i, j] - q[i - 1, j]) / t0) / (t0 + t1)
                    big_a = max(big_a, abs(a) / accel_limit[j])
        peak_a[turn] = big_a
        peak_v[turn] = big_v


@njit(nogil=True, cache=True)
def _velocities(q: np.ndarray, steps: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - jit
    for i in range(out.shape[0]):
        for j in range(out.shape[1]):
            out[i, j] = (q[i + 1, j] - q[i, j]) / steps[i]


def velocities(q: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """Velocities (P − 1, A) [q's unit/s] over each step of positions q (P, A): the
    difference over the step, in one pass (np.diff then a division made two over 10⁶-sample
    programs; the same values)."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    out = np.empty((max(q.shape[0] - 1, 0), q.shape[1]))
    _velocities(q, np.ascontiguousarray(steps, dtype=np.float64), out)
    return out


class Motion(NamedTuple):
    """The kinematics of a program: timesteps (P − 1) [s], velocities over the steps (P − 1, A)
    and accelerations at the points (P, A), SI."""

    steps: np.ndarray
    velocity: np.ndarray
    accel: np.ndarray


def steps_of(t: np.ndarray) -> np.ndarray:
    """The timesteps (P − 1) [s] of times t (P) [s]; raises ValueError unless t increases."""
    steps = np.diff(np.asarray(t, dtype=np.float64))
    if not np.all(steps > 0.0):
        raise ValueError("time does not increase from point to point")
    return steps


def motion(t: np.ndarray, q: np.ndarray) -> Motion:
    """The :class:`Motion` of positions q (P, A) SI at times t (P) [s], which must increase."""
    return over_steps(q, steps_of(t))


def over_steps(q: np.ndarray, steps: np.ndarray) -> Motion:
    """The :class:`Motion` of positions q (P, A) SI over timesteps ``steps`` (P − 1) [s]."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    steps = np.ascontiguousarray(steps, dtype=np.float64)
    return Motion(steps, velocities(q, steps), accelerations(q, steps))


class Limits(NamedTuple):
    """A machine's limits on the axes ``names`` (e.g. ("C", "X", "Y", "Z")), SI: position
    ranges ``low``/``high``, velocities and accelerations (magnitudes); inf where the machine
    sets none. ``rotary`` marks the axes in rad."""

    names: tuple[str, ...]
    rotary: tuple[bool, ...]
    low: np.ndarray
    high: np.ndarray
    velocity: np.ndarray
    accel: np.ndarray


class Extremes(NamedTuple):
    """What a program's limits and peaks need of its motion, per axis (A,), SI: the lowest and
    highest position and the first point of each, the largest |velocity| and the first step
    it occurs over, the largest |acceleration| and its first point, the largest |acceleration|
    over the points of each group (G, A), and the sum of the squared accelerations."""

    low: np.ndarray
    low_at: np.ndarray
    high: np.ndarray
    high_at: np.ndarray
    speed: np.ndarray
    speed_at: np.ndarray
    accel: np.ndarray
    accel_at: np.ndarray
    accel_group: np.ndarray
    accel_sq: np.ndarray


@njit(nogil=True, cache=True)
def _extremes_start(
    q0: np.ndarray,
    low: np.ndarray,
    low_at: np.ndarray,
    high: np.ndarray,
    high_at: np.ndarray,
    speed: np.ndarray,
    speed_at: np.ndarray,
    accel: np.ndarray,
    accel_at: np.ndarray,
    accel_group: np.ndarray,
    accel_sq: np.ndarray,
) -> None:  # noqa: E501  # pragma: no cover - jit
    """The :class:`Extremes` before any point: positions at the first point ``q0`` (A,)."""
    for j in range(q0.size):
        low[j] = high[j] = q0[j]
        low_at[j] = high_at[j] = speed_at[j] = accel_at[j] = 0
        speed[j] = -1.0
        accel[j] = accel_sq[j] = 0.0  # the end points' accelerations are zero
    accel_group[:, :] = 0.0


@njit(nogil=True, cache=True)
def _extremes_span(
    q: np.ndarray,
    steps: np.ndarray,
    group: np.ndarray,
    i0: int,
    i1: int,
    base: int,
    n: int,
    low: np.ndarray,
    low_at: np.ndarray,
    high: np.ndarray,
    high_at: np.ndarray,
    speed: np.ndarray,
    speed_at: np.ndarray,
    accel: np.ndarray,
    accel_at: np.ndarray,
    accel_group: np.ndarray,
    accel_sq: np.ndarray,
) -> None:  # pragma: no cover - jit
    """The extremes carried over points i0 … i1 − 1 of a stretch q (S, A) whose point i is
    point ``base`` + i of ``n``: the stretch holds the neighbours i ± 1 a point's velocity and
    acceleration need, ``steps`` (S − 1) and ``group`` (S) alike. Points in order, so the
    first point of each extreme and the running sum are those of one pass over all."""
    m = q.shape[1]
    # each velocity is formed once: the step's after a point is the next point's before it
    before = np.empty(m)
    if i0 > 0:
        for j in range(m):
            before[j] = (q[i0, j] - q[i0 - 1, j]) / steps[i0 - 1]
    for i in range(i0, i1):
        k = base + i
        for j in range(m):
            x = q[i, j]
            _extreme(x, k, j, low, low_at, -1.0)
            _extreme(x, k, j, high, high_at, 1.0)
            if k < n - 1:
                # the arithmetic of _velocities and accelerations, so the same values
                after = (q[i + 1, j] - x) / steps[i]
                _extreme(abs(after), k, j, speed, speed_at, 1.0)
                if k > 0:
                    a = 2.0 * (after - before[j]) / (steps[i - 1] + steps[i])
                    accel_sq[j] += a * a
                    a = abs(a)
                    _extreme(a, k, j, accel, accel_at, 1.0)
                    if a > accel_group[group[i], j]:
                        accel_group[group[i], j] = a
                before[j] = after


@njit(nogil=True, cache=True, inline="always")
def _extreme(
    x: float, k: int, j: int, value: np.ndarray, at: np.ndarray, sign: float
) -> None:  # pragma: no cover - jit
    """Keep ``x`` of point ``k`` as axis ``j``'s extreme where it passes it: the highest with
    ``sign`` +1, the lowest with −1 (the first point of the extreme kept on a tie)."""
    if sign * x > sign * value[j]:
        value[j] = x
        at[j] = k


class ExtremesOver:
    """The :class:`Extremes` of a motion of ``n`` points and ``axes`` axes taken stretch by
    stretch (:meth:`add`), so a program sampled every controller period need not be held
    whole: the same values and first points as :func:`extremes` of all the points at once."""

    def __init__(self, n: int, axes: int, groups: int = 1) -> None:
        value, at = np.empty, lambda size: np.empty(size, dtype=np.int64)
        self.n, self.groups, self.started = n, groups, False
        self.out = Extremes(
            value(axes),
            at(axes),
            value(axes),
            at(axes),
            value(axes),
            at(axes),
            value(axes),
            at(axes),
            value((groups, axes)),
            value(axes),
        )
        if n == 0:  # no point: nothing to exceed
            e = self.out
            e.low[:], e.high[:], e.speed[:], e.accel[:] = math.inf, -math.inf, -1.0, -1.0
            e.accel_group[:], e.accel_sq[:] = 0.0, 0.0
            e.low_at[:], e.high_at[:], e.speed_at[:], e.accel_at[:] = 0, 0, 0, 0

    def add(
        self, q: np.ndarray, steps: np.ndarray, group: np.ndarray | None, i0: int, i1: int, base: int
    ) -> None:
        """Points ``base`` + i0 … ``base`` + i1 − 1 from the stretch q (S, A) SI of points
        ``base`` … ``base`` + S − 1, its timesteps (S − 1) [s] and groups (S) (0 … groups − 1;
        None: all 0). Stretches must come in order and hold each point's neighbours."""
        q = np.ascontiguousarray(q, dtype=np.float64)
        s = q.shape[0]
        group = np.zeros(s, dtype=np.int64) if group is None else np.asarray(group, dtype=np.int64)
        if group.shape != (s,) or (s and not 0 <= group.min() <= group.max() < self.groups):
            raise ValueError(
                f"a group for each of the {s} points, numbered 0 to {self.groups - 1}, is needed"
            )
        if i0 >= i1:
            return
        if not self.started:
            if base + i0 != 0:
                raise ValueError("the first stretch must start at the first point")
            _extremes_start(q[i0], *self.out)
            self.started = True
        _extremes_span(
            q, np.ascontiguousarray(steps, dtype=np.float64), group, i0, i1, base, self.n, *self.out
        )


def extremes(q: np.ndarray, steps: np.ndarray, group: np.ndarray | None = None, groups: int = 1) -> Extremes:
    """The :class:`Extremes` of positions q (P, A) SI over timesteps ``steps`` (P − 1) [s]
    in one compiled pass: the values :class:`Motion`'s arrays hold (the same arithmetic),
    without forming them (a D path sampled every controller period has millions of points).
    ``group`` (P) numbers each point's group, 0 … ``groups`` − 1 (e.g. on a cut or not)."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    over = ExtremesOver(q.shape[0], q.shape[1], groups)
    over.add(q, steps, group, 0, q.shape[0], 0)
    return over.out


def relative(m: Motion, limits: Limits) -> tuple[np.ndarray, np.ndarray]:
    """Relative accelerations |a|/a_lim (P, A) and velocities |v|/v_lim (P − 1, A)."""
    return np.abs(m.accel) / limits.accel, np.abs(m.velocity) / limits.velocity


def _text(value: float, axis: int, limits: Limits, which: int) -> tuple[str, float]:
    unit, factor = (_ROTARY if limits.rotary[axis] else _LINEAR)[which]
    return unit, value * factor


def limits_reason(
    q: np.ndarray,
    steps: np.ndarray,
    limits: Limits,
    slack: float = 0.0,
    where: Callable[[int], str] | None = None,
) -> str:
    """Every limit positions q (P, A) SI over timesteps ``steps`` (P − 1) [s] exceed
    (:func:`extremes_reason` of their :func:`extremes`)."""
    return extremes_reason(extremes(q, steps), limits, slack, where)


def extremes_reason(
    e: Extremes, limits: Limits, slack: float = 0.0, where: Callable[[int], str] | None = None
) -> str:
    """Every limit a motion with extremes ``e`` exceeds, '; '-joined, each with its worst
    value, the limit and where that value is: ``where(i)`` of its point i (a velocity's step
    starts there), by default the line (1-based point); '' when all hold. ``slack`` is a
    relative allowance (e.g. for the printed digits of a program read back)."""
    at = where if where is not None else (lambda i: f"line {i + 1}")
    out = []
    for j, name in enumerate(limits.names):
        checks = (
            ("", e.low[j], e.low_at[j], limits.low[j], "<", 0),
            ("", e.high[j], e.high_at[j], limits.high[j], ">", 0),
            (" velocity", e.speed[j], e.speed_at[j], limits.velocity[j], ">", 1),
            (" acceleration", e.accel[j], e.accel_at[j], limits.accel[j], ">", 2),
        )
        for what, worst, line, bound, sense, which in checks:
            if not math.isfinite(bound) or (which == 1 and worst < 0.0):  # no step: no velocity
                continue
            allowance = slack * abs(bound)
            if not (worst < bound - allowance if sense == "<" else worst > bound + allowance):
                continue
            unit, shown = _text(float(worst), j, limits, which)
            _, lim = _text(float(bound), j, limits, which)
            out.append(f"{name}{what} {shown:.6g} {unit} {sense} limit {lim:g} {unit} ({at(int(line))})")
    return "; ".join(out)
