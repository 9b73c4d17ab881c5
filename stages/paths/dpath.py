"""D-shaped slow-tool-servo paths for off-axis parts ([5], model §1, §4, §5).

The part sits in a rectangular *cutting zone* of length l (along the cuts) and width s
(across them) off the spindle axis. Every spindle revolution the tool cuts one straight
line across the zone, parallel to the zone's long side at the distance d_n = d_e − n·h
from the C axis (d_e: the zone's outer edge, h: the spacing between cuts), and turns round
outside the part in the *transition zone* to start the next line. In the polar (ρ, θ)
plane a cut of the zone centred at θ_z is

    ρ_c(θ) = d / cos(θ − θ_z),   |θ − θ_z| ≤ a(d) = atan(l / 2d)          ([5] eq. 3)

and the transition joins the end of one cut (θ_a) to the start of the next (θ_b):

* ``traditional`` — the arc of commercial software: the radius held (nearly) constant,
  moving linearly in θ from the end radius to the next start radius. Position is
  continuous, dρ/dθ jumps at both junctions, so the X feed jumps and the X acceleration
  spikes there by ω²·Δ(dρ/dθ)/Δθ over a command step Δθ (it grows as the step shrinks).
* ``optimised`` — a fifth-degree polynomial ρ_t(θ) = Σ c_m θ^m ([5] eq. 4) whose six
  coefficients follow from continuity of ρ, dρ/dθ and d²ρ/dθ² at both junctions ([5]
  eqs. 7–12), solved as the 6×6 linear system of eq. 13 for every transition. It is set up
  in τ = (θ − θ_a)/(θ_b − θ_a) ∈ [0, 1], the same polynomial in a well-conditioned basis.

With a constant spindle speed ω the X feed and acceleration are v = ω·dρ/dθ and
a = ω²·d²ρ/dθ² ([5] eqs. 5–6). One, two or four zones share a revolution ([5] fig. 5):
zone j is centred at θ_z = 2πj/k and every zone cuts line n in revolution n. Z follows the
compensated surface along the cuts and is interpolated linearly in θ across each
transition between the end of one cut and the start of the next ([5] eq. 14).

A program is a list of points (accumulated C angle φ [rad], X = ρ [µm], Z [µm]); the
machine moves every axis linearly in time between them. Its axis accelerations are formed on
the planned path sampled every controller period (:func:`at_period`), the step the machine
sets, not the planner's point spacing (model §6). Lengths µm, angles rad.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Optional

import numpy as np
from numba import njit

TRANSITIONS = ("traditional", "optimised")
ZONE_COUNTS = (1, 2, 4)
TIMINGS = ("spindle", "feed")


class DGeometry(NamedTuple):
    """The cutting zone and the cuts of a D path ([5] fig. 2c). Lengths in µm.

    length_um : l, length of every cut (the zone's extent along the cuts).
    width_um : s, the zone's extent across the cuts.
    outer_um : d_e, distance of the zone's outer edge (the first cut) from the C axis.
    spacing_um : h, distance between consecutive cuts (the feed per revolution).
    zones : cutting zones per revolution (1, 2 or 4), centred at θ = 2πj/zones.
    transition : ``traditional`` or ``optimised`` (module docstring).
    """

    length_um: float
    width_um: float
    outer_um: float
    spacing_um: float
    zones: int
    transition: str

    @property
    def n_cycles(self) -> int:
        """Cuts per zone: the lines d_e − n·h, n = 0 .. floor(s/h), inside the zone."""
        return int(math.floor(self.width_um / self.spacing_um + 1e-9)) + 1

    @property
    def inner_um(self) -> float:
        """d of the last cut [µm]."""
        return self.outer_um - (self.n_cycles - 1) * self.spacing_um

    @property
    def centre_um(self) -> float:
        """Distance of the zone's centre from the C axis [µm] (the off-axis distance)."""
        return self.outer_um - 0.5 * self.width_um

    def half_angle(self, d: np.ndarray | float) -> np.ndarray | float:
        """a(d) = atan(l/2d) [rad]: a cut at distance d spans θ_z ± a(d)."""
        return np.arctan(0.5 * self.length_um / np.asarray(d, dtype=np.float64))


def check_geometry(g: DGeometry) -> None:
    """Refuse a zone the path cannot cut, naming the problem (ValueError)."""
    for name in ("length_um", "width_um", "outer_um", "spacing_um"):
        value = getattr(g, name)
        if not (math.isfinite(value) and value > 0.0):
            raise ValueError(f"{name} must be a positive number of µm, got {value!r}")
    if g.transition not in TRANSITIONS:
        raise ValueError(f"transition must be one of {', '.join(TRANSITIONS)}, got {g.transition!r}")
    if g.zones not in ZONE_COUNTS:
        raise ValueError(f"zones per revolution must be 1, 2 or 4, got {g.zones}")
    if g.spacing_um > g.width_um:
        raise ValueError(f"the spacing h = {g.spacing_um:g} µm exceeds the zone width s = {g.width_um:g} µm")
    if not g.outer_um - g.width_um > 0.0:
        raise ValueError(
            f"the zone reaches the C axis: its outer edge is {g.outer_um:g} µm off the axis and it is "
            f"{g.width_um:g} µm wide; place it further off-axis"
        )
    widest = 2.0 * float(g.half_angle(g.inner_um))
    if not widest < 2.0 * math.pi / g.zones:
        raise ValueError(
            f"{g.zones} zones do not fit in a revolution: the innermost cut spans {math.degrees(widest):.1f}° "  # noqa: E501
            f"of the {360.0 / g.zones:.0f}° each zone has; use fewer zones or place the zone further off-axis"
        )


class DPath(NamedTuple):
    """The points of a D-path program and its analytic path ([5]).

    kind : ``"dpath"`` (the program kind, beside ``ring``, ``mesh`` and ``spiral``).
    geometry : the zone and cuts.
    phi : (N,) accumulated C angle of each point [rad], increasing.
    rho : (N,) polar radius ρ = X of each point [µm].
    cut : (N,) index of the cut a point lies on (revolution·zones + zone), −1 in transitions.
    points_per_cut : points on every cut, equally spaced along it.
    transition_step_deg : largest C step between the points of a transition [deg].
    bounds : (2C,) φ where cut i starts (2i) and ends (2i + 1) [rad].
    cut_d : (C,) distance of cut i from the C axis [µm].
    cut_centre : (C,) φ of the zone centre of cut i [rad].
    coeffs : (C − 1, 6) the transition after cut i as a polynomial in τ ∈ [0, 1].
    t_s : (N,) time of each point [s] as a program file gives it, or None: at constant
        spindle speed (:func:`point_times`).
    tangents : (N − 1, 6) the segments' tangents of C [rad], X and Z [µm] in time when the
        controller joins the points by cubics (PVT, :mod:`ftsweep.stages.interpolation.timed_path`), or None:
        linear segments.
    """

    kind: str
    geometry: DGeometry
    phi: np.ndarray
    rho: np.ndarray
    cut: np.ndarray
    points_per_cut: int
    transition_step_deg: float
    bounds: np.ndarray
    cut_d: np.ndarray
    cut_centre: np.ndarray
    coeffs: np.ndarray
    t_s: Optional[np.ndarray] = None
    tangents: Optional[np.ndarray] = None

    @property
    def n_points(self) -> int:
        return int(self.phi.size)

    @property
    def n_cuts(self) -> int:
        """Cuts over all zones."""
        return int(self.cut_d.size)

    @property
    def revolutions(self) -> float:
        return float((self.phi[-1] - self.phi[0]) / (2.0 * math.pi))

    @property
    def cut_step_um(self) -> float:
        """Distance between consecutive points of a cut [µm]."""
        return self.geometry.length_um / (self.points_per_cut - 1)


def cut_radius(d: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ρ = d·sec x and its first two derivatives in θ [µm, µm/rad, µm/rad²] at the angle x
    from the zone centre ([5] eq. 3)."""
    sec, tan = 1.0 / np.cos(x), np.tan(x)
    return d * sec, d * sec * tan, d * sec * (tan * tan + sec * sec)


def transition_coefficients(
    start: tuple[np.ndarray, np.ndarray, np.ndarray],
    end: tuple[np.ndarray, np.ndarray, np.ndarray],
    span: np.ndarray,
    kind: str,
) -> np.ndarray:
    """Coefficients (T, 6) in τ = (θ − θ_a)/span of the transitions from (ρ, ρ', ρ'') at their
    start to (ρ, ρ', ρ'') at their end (derivatives in θ), over ``span`` = θ_b − θ_a [rad].

    ``optimised``: the quintic of [5] eqs. 4, 7–13: the six conditions (value, slope and
    curvature at both ends) as one 6×6 system per transition, solved by LU. ``traditional``:
    ρ linear from start to end value (the slopes are not matched)."""
    r0, r0p, r0pp = (np.asarray(v, dtype=np.float64) for v in start)
    r1, r1p, r1pp = (np.asarray(v, dtype=np.float64) for v in end)
    span = np.asarray(span, dtype=np.float64)
    out = np.zeros((span.size, 6))
    if kind == "traditional":
        out[:, 0] = r0
        out[:, 1] = r1 - r0
        return out
    # rows: ρ(0), ρ'(0), ρ''(0), ρ(1), ρ'(1), ρ''(1) of Σ b_m τ^m; d/dθ = (1/span)·d/dτ
    m = np.arange(6)
    a = np.zeros((6, 6))
    a[0, 0] = 1.0
    a[1, 1] = 1.0
    a[2, 2] = 2.0
    a[3, :] = 1.0
    a[4, :] = m
    a[5, :] = m * (m - 1)
    rhs = np.stack([r0, r0p * span, r0pp * span**2, r1, r1p * span, r1pp * span**2], axis=-1)
    out[:] = np.linalg.solve(np.broadcast_to(a, (span.size, 6, 6)), rhs[..., None])[..., 0]
    return out


def _poly(coeffs: np.ndarray, tau: np.ndarray, span: np.ndarray) -> tuple[np.ndarray, ...]:
    """Σ b_m τ^m and its first two θ-derivatives (Horner), rows of ``coeffs`` per point."""
    p = np.zeros_like(tau)
    dp = np.zeros_like(tau)
    ddp = np.zeros_like(tau)
    for m in range(5, -1, -1):
        ddp = ddp * tau + 2.0 * dp
        dp = dp * tau + p
        p = p * tau + coeffs[:, m]
    return p, dp / span, ddp / span**2


def _spans(geometry: DGeometry) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per cut: its distance d from the C axis [µm], zone centre and half angle [rad]; per
    transition: its C span [rad]."""
    g = geometry
    n = np.repeat(np.arange(g.n_cycles), g.zones)
    zone = np.tile(np.arange(g.zones), g.n_cycles)
    cut_d = g.outer_um - n * g.spacing_um
    cut_centre = 2.0 * math.pi * (n + zone / g.zones)
    half = np.asarray(g.half_angle(cut_d))
    span = (cut_centre[1:] - half[1:]) - (cut_centre[:-1] + half[:-1])
    return cut_d, cut_centre, half, span


def point_count(geometry: DGeometry, points_per_cut: int, transition_step_deg: float) -> int:
    """Points of the D path :func:`plan` would make, computed without making it (beyond a
    billion cut points, that count alone: the transitions' spans are not worth allocating)."""
    check_geometry(geometry)
    on_cuts = geometry.n_cycles * geometry.zones * int(points_per_cut)
    if on_cuts > 1e9:
        return int(on_cuts)
    span = _spans(geometry)[3]
    steps = np.maximum(np.ceil(span / math.radians(transition_step_deg)), 1.0)
    return int(points_per_cut) * (span.size + 1) + int(np.sum(steps - 1.0))


def _check_plan(
    geometry: DGeometry, points_per_cut: int, transition_step_deg: float, max_points: float
) -> None:
    """Refuse a geometry, point count or transition step :func:`plan` cannot sample."""
    check_geometry(geometry)
    if points_per_cut < 2:
        raise ValueError(f"a cut needs at least 2 points, got {points_per_cut}")
    if not (math.isfinite(transition_step_deg) and transition_step_deg > 0.0):
        raise ValueError(f"transition_step_deg must be positive, got {transition_step_deg!r}")
    count = point_count(geometry, points_per_cut, transition_step_deg)
    if count > max_points:
        raise ValueError(
            f"the D path would hold {count:,} points ({geometry.n_cycles * geometry.zones:,} cuts of "
            f"{points_per_cut:,} points and their transitions at {transition_step_deg:g}° steps), more than "
            f"{max_points:,}: use fewer points per cut, a larger transition step or a larger spacing"
        )


def _transition_points(
    bounds: np.ndarray, span: np.ndarray, steps: np.ndarray, coeffs: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """φ [rad] and ρ [µm] of the transitions' interior points (their ends are the cuts'):
    k = 1 .. steps − 1 of each, in order."""
    owner = np.repeat(np.arange(steps.size), steps - 1)
    first = np.concatenate([[0], np.cumsum(steps - 1)])[:-1] if steps.size else np.empty(0, dtype=np.int64)
    tau = (np.arange(owner.size) - first[owner] + 1) / steps[owner]
    t_phi = bounds[1:-1:2][owner] + tau * span[owner]
    # the polynomial's value alone (Horner, as _poly forms it), each coefficient gathered per
    # point: no (points, 6) copy of the coefficients and no derivatives nobody reads
    t_rho = np.zeros(tau.size)
    for m in range(5, -1, -1):
        t_rho = t_rho * tau + coeffs[owner, m]
    return t_phi, t_rho


def plan(
    geometry: DGeometry, points_per_cut: int, transition_step_deg: float = 1.0, max_points: float = math.inf
) -> DPath:
    """The D path of ``geometry`` ([5]): every cut sampled by ``points_per_cut`` points
    equally spaced along it (ends included), every transition by points at most
    ``transition_step_deg`` apart in C; the transitions solved per cycle.

    The path starts at the first cut's start (φ = −a(d_e), zone 0 centred at φ = 0) and ends
    at the last cut's end; the outermost cut comes first."""
    _check_plan(geometry, points_per_cut, transition_step_deg, max_points)
    g = geometry
    cut_d, cut_centre, half, _ = _spans(geometry)
    bounds = np.empty(2 * cut_d.size)
    bounds[0::2] = cut_centre - half
    bounds[1::2] = cut_centre + half
    start = cut_radius(cut_d[:-1], half[:-1])
    end = cut_radius(cut_d[1:], -half[1:])
    span = bounds[2::2] - bounds[1:-1:2]
    coeffs = transition_coefficients(start, end, span, g.transition)

    u = np.linspace(-0.5 * g.length_um, 0.5 * g.length_um, points_per_cut)
    cut_phi = cut_centre[:, None] + np.arctan(u[None, :] / cut_d[:, None])
    cut_rho = np.hypot(cut_d[:, None], u[None, :])
    steps = np.maximum(np.ceil(span / math.radians(transition_step_deg)).astype(np.int64), 1)
    t_phi, t_rho = _transition_points(bounds, span, steps, coeffs)
    count = points_per_cut * cut_d.size + t_phi.size
    phi, rho = np.empty(count), np.empty(count)
    cut = np.full(count, -1, dtype=np.int32)
    # interleave: cut i, then the interior of transition i; the rest of the slots are transitions'
    lengths = np.full(2 * cut_d.size - 1, points_per_cut)
    lengths[1::2] = steps - 1
    offsets = np.concatenate([[0], np.cumsum(lengths)])
    cut_slots = (offsets[0::2][:, None] + np.arange(points_per_cut)[None, :]).ravel()
    phi[cut_slots] = cut_phi.ravel()
    rho[cut_slots] = cut_rho.ravel()
    cut[cut_slots] = np.repeat(np.arange(cut_d.size), points_per_cut)
    phi[cut < 0] = t_phi
    rho[cut < 0] = t_rho
    return DPath(
        "dpath",
        g,
        phi,
        rho,
        cut,
        int(points_per_cut),
        float(transition_step_deg),
        bounds,
        cut_d,
        cut_centre,
        coeffs,
    )  # noqa: E501


def evaluate(path: DPath, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The analytic path at accumulated angles ``phi`` [rad] within the program: ρ [µm],
    dρ/dθ [µm/rad], d²ρ/dθ² [µm/rad²] and whether each angle lies on a cut (bool). At a
    junction the cut's value is taken. One pass of :func:`_evaluate_kernel` (fastest on
    increasing angles, which it walks along the junctions instead of searching them)."""
    return _evaluated(path, phi, True)


def radius_at(path: DPath, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ρ [µm] of the analytic path at angles ``phi`` [rad] and whether each lies on a cut:
    :func:`evaluate`'s first and last, the same values, without forming the derivatives
    (a cut's tangent costs about as much as the rest of its point)."""
    rho, _, _, on_cut = _evaluated(path, phi, False)
    return rho, on_cut


def _evaluated(
    path: DPath, phi: np.ndarray, derivatives: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    phi = np.ascontiguousarray(phi, dtype=np.float64)
    rho = np.empty(phi.shape)
    d1, d2 = (np.empty(phi.shape), np.empty(phi.shape)) if derivatives else (np.empty(0), np.empty(0))
    on_cut = np.empty(phi.shape, dtype=np.bool_)
    _evaluate_kernel(
        phi.reshape(-1),
        path.bounds,
        path.cut_d,
        path.cut_centre,
        np.ascontiguousarray(path.coeffs),
        rho.reshape(-1),
        d1.reshape(-1),
        d2.reshape(-1),
        on_cut.reshape(-1),
        derivatives,
    )
    return rho, d1, d2, on_cut


@njit(nogil=True, cache=True)
def _evaluate_kernel(
    phi: np.ndarray,
    bounds: np.ndarray,
    cut_d: np.ndarray,
    cut_centre: np.ndarray,
    coeffs: np.ndarray,
    rho: np.ndarray,
    d1: np.ndarray,
    d2: np.ndarray,
    on_cut: np.ndarray,
    derivatives: bool,
) -> None:  # noqa: E501  # pragma: no cover - jit
    """:func:`evaluate` point by point: the segment of each angle (cut 2i or transition 2i + 1
    between ``bounds``), then [5] eq. 3 on a cut or the transition's polynomial in τ; ρ only
    (``d1``, ``d2`` untouched) unless ``derivatives``."""
    nb, ncut, nt = bounds.size, cut_d.size, coeffs.shape[0]
    seg = 0
    for k in range(phi.size):
        p = phi[k]
        if p < bounds[seg]:  # not increasing: search afresh
            seg = max(np.searchsorted(bounds, p, side="right") - 1, 0)
        while seg + 1 < nb and bounds[seg + 1] <= p:
            seg += 1
        # the path ends on a cut: an angle at or past its last bound (the file's C printed to
        # 1e-9° lands a few ulp beyond it) continues that cut, not the last transition's
        # polynomial far outside its span
        on = seg % 2 == 0 or bounds[seg] == p or seg == nb - 1
        on_cut[k] = on
        i = min(seg // 2, ncut - 1)
        if on or nt == 0:
            x = p - cut_centre[i]
            sec = 1.0 / math.cos(x)
            rho[k] = cut_d[i] * sec
            if derivatives:
                tan = math.tan(x)
                d1[k] = cut_d[i] * sec * tan
                d2[k] = cut_d[i] * sec * (tan * tan + sec * sec)
            continue
        j = min(i, nt - 1)
        a = bounds[1 + 2 * j]
        span = bounds[2 + 2 * j] - a
        tau = (p - a) / span
        if not derivatives:
            v = 0.0
            for m in range(5, -1, -1):
                v = v * tau + coeffs[j, m]
            rho[k] = v
            continue
        v, dv, ddv = 0.0, 0.0, 0.0
        for m in range(5, -1, -1):
            ddv = ddv * tau + 2.0 * dv
            dv = dv * tau + v
            v = v * tau + coeffs[j, m]
        rho[k] = v
        d1[k] = dv / span
        d2[k] = ddv / (span * span)
