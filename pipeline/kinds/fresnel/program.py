"""Freeform Fresnel programs on an X-Y-Z-C lathe ([2]): slicing a catalog surface, planning
its quasi-spiral path and 4-axis trajectory (:mod:`ftsweep.stages.paths.fresnel`), and choosing the
timesteps (model §6 axis dynamics).

*Timesteps*. The positions of every axis along the path are fixed by the plan; the time
between consecutive points is free. Every timing keeps every axis within 1/K_s of its
velocity limit on every step and of its acceleration limit at every point, by [2]'s
discretisation (eq. 14: the velocity change at a point over the mean of its two steps; the
kinematics stage). ``timing``:

- ``optimal`` (the default): the least total time under those limits, by forward-backward
  passes over the steps' speeds (:mod:`ftsweep.stages.kinematics.timing`); the study
  certifies it with a lower bound on the time of every program through the same points
  within the same limits, in all and per facet (:func:`certificate`, docs/kinds.md
  "Time-optimal timing").
- ``paper``: [2] §2.5, below.
- ``constant``: the reference's one constant step.

*[2]'s timesteps* (§2.5). Per turn of the path (K steps) the timesteps
minimise the largest relative acceleration max |a/a_lim| over the four axes with their
mean held at T0 (eq. 15), warm-started from the previous turn's solution; the step into a
turn is taken at the turn's own last timestep (adjacent turns are nearly periodic, [2]
§2.5); the max is replaced by a p-norm so that a quasi-Newton method can follow its gradient
(L-BFGS, compiled whole: :mod:`ftsweep.stages.paths.turnopt`), and the timesteps are parametrised
as K·T0·softmax(u) so the mean constraint always holds.
The first turn starts cold (uniform steps) and is solved by continuation, p = 64 then 512,
up to 2,000 iterations each; later turns start from the previous one's steps, p = 64, 200
iterations: every turn comes within 3 % of a direct minimax solution of the same turn
(SLSQP on the epigraph form, tests/kinds/test_fresnel.py), where a single p = 32 stage stopped 3×
above it on the first turn. A turn the optimiser would leave worse than constant steps
keeps constant steps (the fallback). Each turn is then scaled so that its largest relative
acceleration is 1/K_s (eq. 16) and no axis exceeds 1/K_s of its velocity limit; the factor
is interpolated between turn centres so consecutive turns meet without a jump in timestep,
and raised for the turns where a step between turns would still exceed a bound (only
those turns' neighbourhoods are measured again): every step of the final program is
within 1/K_s of every limit. The reference program runs at one constant timestep, the
least for which the whole program meets the same bounds ([2]: "a constant timestep
determined by the global maximum acceleration").

Units: positions µm (C in rad), timesteps s, accelerations m/s² (C rad/s²).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any, NamedTuple, Optional

import numpy as np

from ftsweep.inputs.facets import surface_range
from ftsweep.stages.interpolation import timed_path
from ftsweep.stages.kinematics import axes as kinematics
from ftsweep.stages.kinematics import certificate as bounds
from ftsweep.stages.kinematics import timing as least_time
from ftsweep.stages.kinematics.axes import Limits
from ftsweep.stages.kinematics.certificate import LeastTimeBound
from ftsweep.stages.paths import fresnel as ff
from ftsweep.stages.paths import turnopt

DEFAULTS: dict[str, Any] = {
    "facet_height_um": 10.0,
    "points_per_turn": 360,
    "deviation_deg": 0.0,
    "safety": 1.25,
    "compensation": "exact",
    "scheme": "auto",
    "timing": "optimal",
}
# how a program is timed (module docstring): the least time the limits allow, [2]'s eqs.
# 15-16, or one constant step
TIMINGS = ("optimal", "paper", "constant")
COMPENSATIONS = ("exact", "straight", "none")
AXES = ("C", "X", "Y", "Z")
# the p-norm standing in for the max of eq. 15, and the optimiser's budget per turn: p = 32 puts
# the smooth maximum within 1.2 % of the true one for K = 360 steps of four axes
POWER = 64.0
MAX_ITERATIONS = 200
# the optimiser's stages (p, iterations): a cold first turn by continuation, later turns warm
COLD = ((POWER, 2000), (512.0, 2000))
WARM = ((POWER, MAX_ITERATIONS),)
# an iteration lowering the cost by at most FTOL (relative) ends a stage, as does a gradient
# whose largest component is at most GTOL (SciPy's L-BFGS-B defaults as this module used them)
FTOL = 1e-7
GTOL = 1e-5


class FresnelPlan(NamedTuple):
    """A planned Fresnel program: the quasi-spiral and its 4-axis trajectory.

    path : the quasi-spiral (:class:`ftsweep.stages.paths.fresnel.QuasiSpiral`).
    f_ref_um, max_um : the surface's lowest point in the aperture and its highest [µm].
    apex_um : (X, Y) of the lowest point [µm].
    z_um : Z of the sliced surface at every point [µm] ([2] eq. 8), each entry onto a new
        facet ramped over its first turn (:func:`ftsweep.stages.paths.fresnel.entry_offset`).
    ez_exact_um, ez_straight_um : tool-edge compensation by [2] eq. 10 and eq. 12 [µm].
    ez_um : the compensation applied (``compensation``), z = Z + e_z ([2] eq. 13).
    phi, x_um, y_um : spindle angle [rad] and the tool's global X, Y [µm] ([2] eq. 9).
    slope : |∇f| at every point [-].
    """

    path: ff.QuasiSpiral
    f_ref_um: float
    max_um: float
    apex_um: np.ndarray
    facet_height_um: float
    feed_um: float
    nose_radius_um: float
    deviation_rad: float
    compensation: str
    z_um: np.ndarray
    ez_exact_um: np.ndarray
    ez_straight_um: np.ndarray
    phi: np.ndarray
    x_um: np.ndarray
    y_um: np.ndarray
    slope: np.ndarray
    planning_s: float

    @property
    def ez_um(self) -> np.ndarray:
        if self.compensation == "none":
            return np.zeros_like(self.z_um)
        return self.ez_exact_um if self.compensation == "exact" else self.ez_straight_um

    @property
    def tool_z_um(self) -> np.ndarray:
        """The Z axis: the sliced surface plus the compensation ([2] eq. 13) [µm]."""
        return np.asarray(self.z_um + self.ez_um)

    def axes_si(self) -> np.ndarray:
        """(P, 4) positions C [rad], X, Y, Z [m] of every point."""
        return np.column_stack([self.phi, self.x_um * 1e-6, self.y_um * 1e-6, self.tool_z_um * 1e-6])


def ez_on_part(fplan: FresnelPlan, aperture: Any) -> dict[str, float]:
    """The largest tool-edge compensations [nm] by eq. 10 and eq. 12 and their largest
    difference over the path's points on the part (inside the aperture: the quasi-spiral's
    outer turns run beyond it, where the slopes are largest and nothing is cut)."""
    on = aperture.contains(fplan.path.xy[:, 0], fplan.path.xy[:, 1])
    exact, straight = fplan.ez_exact_um[on], fplan.ez_straight_um[on]
    return {
        "ez_exact_max_nm": float(exact.max() * 1e3),
        "ez_straight_max_nm": float(straight.max() * 1e3),
        "ez_difference_max_nm": float(np.abs(exact - straight).max() * 1e3),
    }


# --------------------------------------------------------------------------- surface
# --------------------------------------------------------------------------- planning
def _facets(
    fn: Callable[..., Any], aperture: Any, h: float, feed_um: float, points_per_turn: int, max_points: float
) -> tuple[dict[str, Any], int]:
    """The surface's range (its interior lowest point, [2] appendix A.2) and the facets of
    height ``h`` [µm] it slices into; refuses, before the path is made, a program of more than
    ``max_points`` points (K a turn, a turn per facet at least and one per feed over the reach)."""
    rng = surface_range(fn, aperture)
    if not rng["interior"]:
        raise ff.FresnelError(
            "the surface's lowest point lies on the aperture's edge: its contours do not close "
            "inside the part, so it cannot be cut along a quasi-spiral path ([2] appendix A.2: "
            "split it into sub-regions first)"
        )
    n_facets = max(1, math.ceil((rng["max_um"] - rng["f_ref_um"]) / h - 1e-9))
    # every ray advances at most Δr a turn ([2] eq. 7), and reach_um is 1.5 × the farthest edge
    turns = max(n_facets, rng["reach_um"] / 1.5 / feed_um)
    if points_per_turn * turns > max_points:
        raise ff.FresnelError(
            f"the path would hold at least {points_per_turn * turns:.3g} points ({n_facets:,} facet(s) of "
            f"{h:g} µm, {turns:.3g} turns of {points_per_turn:,} points), more than the machine holds "
            f"({max_points:,.0f}): use a larger --facet-height-um, fewer --points-per-turn or a larger feed"
        )
    return rng, n_facets


def _commands(
    fn: Callable[..., Any], path: Any, f_ref_um: float, h: float, rc: float
) -> tuple[np.ndarray, ...]:
    """At the path's points: the facet heights f_c [µm] ([2] eq. 3) with the entries onto new
    facets ramped over their first turn (:func:`ftsweep.stages.paths.fresnel.entry_offset`), the exact
    (eq. 10) and straight-line (eq. 12) compensations e_z [µm], and the slopes ∂f/∂x, ∂f/∂y."""
    f, gx, gy = fn(path.xy[:, 0], path.xy[:, 1])
    z = ff.sliced(f, f_ref_um, h, path.level)[0] + ff.entry_offset(path.facet, path.points_per_turn, h)
    exact = ff.compensation_exact(fn, path.xy[:, 0], path.xy[:, 1], rc)
    return z, exact, ff.compensation_straight(gx, gy, rc), gx, gy


def _pose(
    xy: np.ndarray, gx: np.ndarray, gy: np.ndarray, dev: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """C [rad], X, Y [µm] of the path's points ([2] eq. 9, rake face turned ``dev`` [rad])."""
    phi, x, y = ff.pose(xy, gx, gy, dev)
    # the closing point is the lowest point itself, where ∇f = 0 leaves eq. 9's angle open:
    # the spindle carries on at its last speed
    phi[-1] = 2.0 * phi[-2] - phi[-3]
    x[-1:], y[-1:] = ff.global_of(phi[-1:], xy[-1:])
    return phi, x, y


def plan(
    fn: Callable[..., Any],
    aperture: Any,
    facet_height_um: float,
    feed_um: float,
    nose_radius_um: float,
    points_per_turn: int = DEFAULTS["points_per_turn"],
    deviation_deg: float = DEFAULTS["deviation_deg"],
    compensation: str = DEFAULTS["compensation"],
    scheme: str = DEFAULTS["scheme"],
    max_points: float = math.inf,
) -> FresnelPlan:
    """Slice the surface at ``facet_height_um`` [µm] and plan its quasi-spiral path, the
    4-axis trajectory (rake face turned ``deviation_deg`` [deg] from the cutting direction)
    and both tool-edge compensations ([2] §2.1–2.4). Raises ``FresnelError`` naming the
    problem when the surface has no interior lowest point or its contours do not close, or
    when the path would hold more than ``max_points`` points (estimated before it is made:
    K points per turn, a turn per facet at least and one per feed Δr over the reach)."""
    if compensation not in COMPENSATIONS:
        raise ff.FresnelError(f"compensation {compensation!r} is not one of {', '.join(COMPENSATIONS)}")
    if not facet_height_um > 0.0 or not feed_um > 0.0:
        raise ff.FresnelError(
            f"facet height {facet_height_um:g} µm and feed {feed_um:g} µm per turn must be positive"
        )
    start = time.perf_counter()
    rng, n_facets = _facets(fn, aperture, float(facet_height_um), float(feed_um), points_per_turn, max_points)
    h = float(facet_height_um)
    path = ff.plan(
        fn,
        rng["apex_um"],
        rng["f_ref_um"],
        h,
        n_facets,
        float(feed_um),
        int(points_per_turn),
        rng["reach_um"],
        scheme,
    )
    z, exact, straight, gx, gy = _commands(fn, path, rng["f_ref_um"], h, float(nose_radius_um))
    dev = math.radians(float(deviation_deg))
    phi, x, y = _pose(path.xy, gx, gy, dev)
    return FresnelPlan(
        path,
        rng["f_ref_um"],
        rng["max_um"],
        rng["apex_um"],
        h,
        float(feed_um),
        float(nose_radius_um),
        dev,
        compensation,
        z,
        exact,
        straight,
        phi,
        x,
        y,
        np.hypot(gx, gy),
        time.perf_counter() - start,
    )


# --------------------------------------------------------------------------- timesteps


def limits_of(machine: Any, name: str = "machine") -> Limits:
    """The 4-axis limits (C, X, Y, Z in SI, :mod:`ftsweep.stages.kinematics.axes`) of a machine
    entry; raises ``FresnelError`` when it lacks a Y axis or a C acceleration (a Fresnel
    program needs an X-Y-Z-C lathe, [2] §2.3)."""
    ax = machine.axes
    missing = (
        []
        if ax is None
        else [
            k for k in ("y_min_mm", "y_feed_mm_s", "y_accel_m_s2", "c_accel_rad_s2") if getattr(ax, k) is None
        ]
    )
    if ax is None or missing:
        what = "axes" if ax is None else "axes." + ", axes.".join(missing)
        raise ff.FresnelError(
            f"machine '{name}' is not a 4-axis X-Y-Z-C lathe (no {what}); a Fresnel program needs "
            "all four axes' limits"
        )
    limits: Limits = ax.limits(AXES)
    return limits


def relative_peaks(q: np.ndarray, steps: np.ndarray, limits: Limits) -> tuple[np.ndarray, np.ndarray]:
    """Relative accelerations |a|/a_lim at every point ([2] eq. 14) and relative velocities
    |v|/v_lim over every step, (P, 4) and (P − 1, 4), of positions q (P, 4) in SI (the
    kinematics stage)."""
    return kinematics.relative(kinematics.over_steps(q, steps), limits)


def limits_reason(q: np.ndarray, steps: np.ndarray, limits: Limits, slack: float = 0.0) -> str:
    """Which limits a program of positions q (P, 4) SI and timesteps (P − 1) [s] exceeds on
    any line (the kinematics stage: [2] eq. 14 for accelerations, differences for
    velocities), or ''."""
    if not np.all(steps > 0.0):
        return "time does not increase from line to line"
    return kinematics.limits_reason(q, steps, limits, slack)


def constant_step(q: np.ndarray, limits: Limits, safety: float) -> float:
    """The least constant timestep [s] at which no axis exceeds 1/K_s of its acceleration or
    velocity limit anywhere in the program (the reference of [2] §2.5)."""
    one = np.ones(q.shape[0] - 1)
    acc, vel = relative_peaks(q, one, limits)
    # at T = 1 s: accelerations scale as 1/T², velocities as 1/T
    return max(math.sqrt(safety * float(acc.max())), safety * float(vel.max()), 1e-12)


class Timesteps(NamedTuple):
    """The timesteps of a program (module docstring).

    steps : (P − 1,) final timesteps [s] (within 1/K_s of every limit).
    reference : T0 [s]. constant : the constant timestep of the reference program [s].
    peak_constant, peak_optimised : (turns,) max relative acceleration of every turn with
    constant timesteps T0 and with eq. 15's (same mean T0), before scaling; ``paper`` only.
    scale : (turns,) the factor applied to every turn (eq. 16); ``paper`` only.
    seconds : wall time of the timing [s]. timing : one of :data:`TIMINGS`.
    """

    steps: np.ndarray
    reference: float
    constant: float
    peak_constant: Optional[np.ndarray]
    peak_optimised: Optional[np.ndarray]
    scale: Optional[np.ndarray]
    seconds: float
    timing: str = "paper"


def _turn_deltas(q: np.ndarray, k: int, turn: int) -> np.ndarray:
    """(K + 1, 4) position differences of one turn, row 0 the step into its first point."""
    lo = turn * k
    rows = np.diff(q[max(lo - 1, 0) : lo + k + 1], axis=0)
    return rows if lo > 0 else np.vstack([np.zeros((1, q.shape[1])), rows])


def _optimise_turn(
    u0: np.ndarray,
    t0: float,
    deltas: np.ndarray,
    inv: np.ndarray,
    first: bool,
    stages: tuple[tuple[float, int], ...] = WARM,
) -> np.ndarray:
    """Minimise the turn's largest relative acceleration at mean timestep T0 (eq. 15):
    L-BFGS on the p-norm, in softmax coordinates u (:func:`ftsweep.stages.paths.turnopt.minimise_turn`),
    for each (p, iterations) of ``stages`` in turn (continuation: each stage starts where the
    last ended)."""
    total = u0.size * t0
    u = np.ascontiguousarray(u0, dtype=np.float64)
    deltas = np.ascontiguousarray(deltas)
    for power, iterations in stages:
        u = turnopt.minimise_turn(u, total, deltas, inv, first, power, iterations, FTOL, GTOL)[0]
    return np.asarray(u - u.mean())


def _turn_steps(
    u: np.ndarray, t0: float, deltas: np.ndarray, inv: np.ndarray, first: bool, previous: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """A turn's optimised steps: warm-started from the previous turn's ``u`` (the first turn
    cold, by continuation); where the warm start lands above 1.1 × ``previous`` (this turn's
    constant-step peak reduced as much as the previous turn's was; 0 for a turn onto a new
    facet), also solved cold and by continuation from the warm result, the best kept. Returns
    (u, steps [s], peak)."""

    total = u.size * t0

    def peak_of(v: np.ndarray) -> float:
        return float(ff.turn_peak(turnopt.softmax_steps(v, total), deltas, inv, first))

    tries = [_optimise_turn(u, t0, deltas, inv, first, COLD if first else WARM)]
    peaks = [peak_of(tries[0])]
    if not first and peaks[0] > 1.1 * previous:
        tries.append(_optimise_turn(np.zeros(u.size), t0, deltas, inv, first, COLD))
        tries.append(_optimise_turn(tries[0], t0, deltas, inv, first, COLD[1:]))
        peaks += [peak_of(v) for v in tries[1:]]
    best = int(np.argmin(peaks))
    return tries[best], turnopt.softmax_steps(tries[best], total), peaks[best]


def _smoothly_scaled(
    q: np.ndarray, unscaled: np.ndarray, knots: np.ndarray, k: int, limits: Limits, safety: float
) -> tuple[np.ndarray, np.ndarray]:
    """Final timesteps [s]: the optimised ones times a factor interpolated linearly between
    turn centres from eq. 16's per-turn factors ``knots``, so that consecutive turns' steps
    meet without a jump; a turn where an axis still exceeds 1/K_s of a limit (a step between
    turns) has its factor raised until none does. Returns (steps, final factors)."""
    turns = knots.size
    centres = np.arange(turns) * k + 0.5 * (k - 1)
    index = np.arange(unscaled.size)
    knots = knots.copy()
    q = np.ascontiguousarray(q)
    steps = np.interp(index, centres, knots) * unscaled
    peak_a, peak_v = np.empty(turns), np.empty(turns)
    dirty = np.arange(turns)
    for attempt in range(300):
        # a knot moves the steps between its neighbours' centres: only turns within two of a
        # raised knot are measured again (the same values a whole-program pass gives)
        kinematics.turn_peaks(q, steps, limits.accel, limits.velocity, k, dirty, peak_a, peak_v)
        need = np.maximum(np.sqrt(safety * peak_a), safety * peak_v)
        if np.all(need <= 1.0 + 1e-9):
            return steps, knots
        grow = np.where(need > 1.0 + 1e-9, need, 1.0)
        if attempt >= 100:
            # a step between two turns takes both turns' factors: where raising a turn's own
            # has not settled it (it creeps up by 1e-6 an iteration), raise its neighbours too
            own = grow.copy()
            grow[1:] = np.maximum(grow[1:], own[:-1])
            grow[:-1] = np.maximum(grow[:-1], own[1:])
        raised = np.flatnonzero(grow > 1.0)
        knots[raised] *= grow[raised] * (1.0 + 1e-6)
        dirty = _near(raised, turns)
        lo, hi = dirty[0] * k, min((dirty[-1] + 1) * k, steps.size)
        steps[lo:hi] = np.interp(index[lo:hi], centres, knots) * unscaled[lo:hi]
    raise ff.FresnelError("the timesteps could not be brought within the axis limits")


def _near(turns: np.ndarray, count: int) -> np.ndarray:
    """The turns within two of any of ``turns`` (sorted), among ``count``."""
    mark = np.zeros(count + 4, dtype=bool)
    for shift in range(5):
        mark[turns + shift] = True
    return np.flatnonzero(mark[2 : count + 2])


def timesteps(
    fplan: FresnelPlan,
    limits: Limits,
    safety: float,
    reference_s: float,
    progress: Optional[Callable[[int, int], None]] = None,
    timing: str = DEFAULTS["timing"],
) -> Timesteps:
    """The timesteps of a planned program with safety factor K_s = ``safety`` by ``timing``
    (module docstring): ``optimal`` the least-time profile, ``paper`` [2]'s eqs. 15-16 turn by
    turn with reference timestep T0 = ``reference_s`` [s], ``constant`` the reference's one
    step. Raises ``FresnelError`` for a safety factor below 1 or another timing."""
    if not safety >= 1.0:
        raise ff.FresnelError(f"the safety factor K_s must be at least 1 (got {safety:g})")
    if timing == "paper":
        return _paper_steps(fplan, limits, safety, reference_s, progress)
    if timing not in TIMINGS:
        raise ff.FresnelError(f"timing {timing!r} is not one of {', '.join(TIMINGS)}")
    start = time.perf_counter()
    q = fplan.axes_si()
    constant = constant_step(q, limits, safety)
    if timing == "constant":
        steps = np.full(q.shape[0] - 1, constant)
    else:
        steps = least_time.least_time_steps(q, limits.velocity / safety, limits.accel / safety)
    if progress is not None:
        progress(fplan.path.n_turns, fplan.path.n_turns)
    return Timesteps(steps, reference_s, constant, None, None, None, time.perf_counter() - start, timing)


def certificate(q: np.ndarray, limits: Limits, safety: float, constant_s: float) -> LeastTimeBound:
    """A lower bound on the time of every program through the points q (P, 4) SI within 1/K_s
    of every limit ([2] eq. 14 at every point; :mod:`ftsweep.stages.kinematics.certificate`),
    starting from the class of programs none of whose steps is longer than the constant step
    ``constant_s`` [s] (:func:`constant_step`, which every :class:`Timesteps` holds): that
    class holds the constant program, and the bound is one whatever the timing."""
    return bounds.least_time_bound(q, limits.velocity / safety, limits.accel / safety, constant_s)


def _paper_steps(
    fplan: FresnelPlan,
    limits: Limits,
    safety: float,
    reference_s: float,
    progress: Optional[Callable[[int, int], None]] = None,
) -> Timesteps:
    """Adaptive timesteps ([2] §2.5, module docstring) of a planned program, turn by turn,
    with reference timestep T0 = ``reference_s`` [s] and safety factor K_s = ``safety``."""
    start = time.perf_counter()
    q = fplan.axes_si()
    k = fplan.path.points_per_turn
    turns = fplan.path.n_turns
    inv = 1.0 / limits.accel
    steps = np.empty(q.shape[0] - 1)
    peak_c, peak_o, scale = np.empty(turns), np.empty(turns), np.empty(turns)
    u = np.zeros(k)
    const = np.full(k, reference_s)
    unscaled = np.empty(q.shape[0] - 1)
    for m in range(turns):
        deltas = _turn_deltas(q, k, m)
        first = m == 0
        peak_c[m] = ff.turn_peak(const, deltas, inv, first)
        # a turn onto a new facet changes course (Z steps by h): solved cold too
        onto = fplan.path.enters_facet(m)
        previous = peak_o[m - 1] / peak_c[m - 1] if m and not onto else 0.0
        u, t, peak_o[m] = _turn_steps(u, reference_s, deltas, inv, first, previous * peak_c[m])
        if peak_o[m] > peak_c[m]:  # the fallback: never worse than constant steps
            t, peak_o[m], u = const.copy(), peak_c[m], np.zeros(k)
        unscaled[m * k : (m + 1) * k] = t
        # eq. 16, and 1/K_s of every velocity limit
        v = float(np.max(np.abs(deltas[1:]) / t[:, None] / limits.velocity))
        scale[m] = max(math.sqrt(safety * peak_o[m]), safety * v, 1e-12)
        if progress is not None:
            progress(m + 1, turns)
    steps, scale = _smoothly_scaled(q, unscaled, scale, k, limits, safety)
    return Timesteps(
        steps,
        reference_s,
        constant_step(q, limits, safety),
        peak_c,
        peak_o,
        scale,
        time.perf_counter() - start,
        "paper",
    )


def pvt_form(prog: FresnelProgram, z_um: np.ndarray, controller: Any) -> FresnelProgram:
    """The program as a PVT controller runs it (docs/controllers.md): the points' times (the
    adaptive timesteps summed) rounded to the controller's whole time steps, and the cubic
    segments in time through C, X, Y and Z with each point's local slope as its velocity (the
    velocities export writes, :func:`ftsweep.stages.interpolation.timed_path.tangents`). Refuses
    (ValueError) two points within one step or a segment over the controller's longest."""
    t = np.concatenate([[0.0], np.cumsum(prog.steps.steps)])
    t = timed_path.on_time_steps(t, controller.time_quantum_s, controller.max_segment_s)
    p = prog.plan
    chan = np.column_stack([p.phi, p.x_um, p.y_um, z_um])
    return prog._replace(steps=prog.steps._replace(steps=np.diff(t)), tangents=timed_path.tangents(t, chan))


class FresnelProgram(NamedTuple):
    """A timed Fresnel program, what the machine runs: its plan, its timesteps, and the path's
    points (X, Y) [µm] in the part's frame the simulator takes (the plan's, or those a program
    file's lines give back through eq. 9); ``tangents`` (P − 1, 8): when the controller joins
    the points by cubics in time (PVT), the segments' tangents of C [rad], X, Y, Z [µm]
    (:mod:`ftsweep.stages.interpolation.timed_path`), the plan's C, X, Y and the commands the points."""

    kind: str
    plan: FresnelPlan
    steps: Timesteps
    xy: np.ndarray
    tangents: Optional[np.ndarray] = None

    @property
    def n_points(self) -> int:
        return int(self.xy.shape[0])
