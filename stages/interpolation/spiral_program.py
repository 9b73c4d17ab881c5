"""A spiral program as the controller runs it (model §1, [4]): its control points on the
Archimedean spiral ρ(φ) = ρ0 − F·φ/2π, the spiral's geometry, and the command the
controller forms at any accumulated spindle angle (linear in φ between points, or the
cubic segments of :mod:`ftsweep.stages.interpolation.segments`). The planners that place
the points are :mod:`ftsweep.stages.paths.spiral`'s."""

from __future__ import annotations

import math
from typing import NamedTuple, Optional

import numpy as np

from ftsweep.stages.interpolation import segments

# revolutions: the rounding slack of angles printed to 1e-9° (2.8e-12 rev), with room to spare
REV_SLACK = 1e-9


class SpiralPath(NamedTuple):
    """The control points of a spiral program (model §1). Angles in rad, lengths in µm.

    kind : ``"spiral"`` (the program kind, beside the tables' ``"ring"`` and ``"mesh"``).
    phi : (N,) accumulated spindle angle of each point [rad], increasing from 0 to Φ.
    rho0_um : radius where the spiral starts [µm].
    feed_um : feed per revolution F [µm/rev].
    rule : sampling rule, one of :data:`ftsweep.stages.paths.spiral.RULES`.
    parameter : the rule's parameter: points per revolution, arc length [µm] or chord
        budget [µm].
    interpolation : how the controller forms the command between points: ``"linear"``,
        ``"pvt"`` or ``"spline1"`` (:mod:`ftsweep.stages.interpolation.segments`).
    d0, d1 : (N − 1,) the segments' end tangents [µm per segment] of a cubic
        interpolation (None: linear segments).
    """

    kind: str
    phi: np.ndarray
    rho0_um: float
    feed_um: float
    rule: str
    parameter: float
    interpolation: str = "linear"
    d0: Optional[np.ndarray] = None
    d1: Optional[np.ndarray] = None

    @property
    def n_points(self) -> int:
        """Number of control points N."""
        return int(self.phi.size)

    @property
    def rho(self) -> np.ndarray:
        """Radius of each point [µm] (model §1)."""
        return spiral_radius(self.phi, self.rho0_um, self.feed_um)

    @property
    def theta(self) -> np.ndarray:
        """Spindle angle of each point, φ mod 2π [rad]."""
        return np.mod(self.phi, 2.0 * math.pi)

    @property
    def revolutions(self) -> float:
        """Revolutions from the outer edge to the centre, ρ0/F."""
        return self.rho0_um / self.feed_um

    @property
    def dphi_deg(self) -> float:
        """Mean angular step between consecutive points [deg]."""
        return math.degrees(float(self.phi[-1] - self.phi[0]) / max(self.n_points - 1, 1))

    @property
    def ds_um(self) -> float:
        """Mean path length between consecutive points [µm] (in the XY plane)."""
        return path_length_um(self.rho0_um, self.feed_um) / max(self.n_points - 1, 1)

    @property
    def aspect(self) -> float:
        """Aspect ratio F [µm] / mean Δφ [deg], the ring method's Δρ/Δθ for a path."""
        return self.feed_um / self.dphi_deg

    @property
    def max_points_per_rev(self) -> int:
        """Most points any one revolution holds. A point within 1e-9 rev below a revolution's
        start counts in that revolution: angles read back from a program printed to 1e-9°
        fall just short of k·360° and must give the same count as the planned path."""
        rev = np.floor(self.phi / (2.0 * math.pi) + REV_SLACK).astype(np.int64)
        return int(np.bincount(rev - rev.min()).max())


def angular_speed(rpm: float) -> float:
    """Spindle angular speed ω [rad/s] of ``rpm`` [rev/min]."""
    return rpm * math.pi / 30.0


def spiral_end_rad(rho0_um: float, feed_um: float) -> float:
    """Accumulated spindle angle Φ = 2π·ρ0/F [rad] where the spiral reaches the centre."""
    return 2.0 * math.pi * rho0_um / feed_um


def spiral_radius(phi: np.ndarray, rho0_um: float, feed_um: float) -> np.ndarray:
    """ρ(φ) = max(ρ0 − F·φ/2π, 0) [µm] (model §1)."""
    return np.maximum(rho0_um - feed_um * np.asarray(phi) / (2.0 * math.pi), 0.0)


def _arc_from_centre(rho: np.ndarray, b: float) -> np.ndarray:
    """Length [µm] of the spiral ρ = b·ψ from the centre out to radius ρ: (b/2)·(u·sqrt(1+u²)
    + asinh u), u = ρ/b."""
    u = np.asarray(rho, dtype=np.float64) / b
    return 0.5 * b * (u * np.sqrt(1.0 + u * u) + np.arcsinh(u))


def path_length_um(rho0_um: float, feed_um: float) -> float:
    """Length [µm] of the whole spiral in the XY plane, from ρ0 to the centre."""
    return float(_arc_from_centre(np.array(rho0_um), feed_um / (2.0 * math.pi)))


def arc_length_between(phi_a: np.ndarray, phi_b: np.ndarray, rho0_um: float, feed_um: float) -> np.ndarray:
    """Length [µm] of the spiral in the XY plane between accumulated angles φa ≤ φb [rad]."""
    b = feed_um / (2.0 * math.pi)
    return _arc_from_centre(spiral_radius(phi_a, rho0_um, feed_um), b) - _arc_from_centre(
        spiral_radius(phi_b, rho0_um, feed_um), b
    )


def spiral_commands(path: SpiralPath, values: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """The controller's command w [µm] at accumulated spindle angles ``phi`` [rad]: linear
    interpolation in φ between consecutive control points, or the path's cubic segments
    (:mod:`ftsweep.stages.interpolation.segments`), the end values held outside."""
    if path.d0 is None or path.d1 is None:
        return np.interp(phi, path.phi, values)
    return segments.evaluate(path.phi, values, path.d0, path.d1, phi)


def phi_on_path(path: SpiralPath, rho: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Accumulated angle [rad] of tool positions (ρ [µm], θ [rad]) on the spiral: θ plus the
    whole revolutions that bring ρ(φ) nearest ρ (model §1)."""
    theta = np.mod(theta, 2.0 * math.pi)
    k = np.rint((path.rho0_um - path.feed_um * theta / (2.0 * math.pi) - rho) / path.feed_um)
    return 2.0 * math.pi * np.maximum(k, 0.0) + theta
