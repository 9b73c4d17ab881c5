"""Control-point layouts: the table the FTS controller holds (model §2).

A layout is a small immutable value describing a regular grid in *index space*: the
controller maps a query to fractional indices (u, v) = ((q0 − origin0)/pitch0,
(q1 − origin1)/pitch1) and interpolates bilinearly (§3). For the ring method q = (ρ [µm],
θ [deg]) and v is periodic; for the mesh method q = (x [µm], y [µm]).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np


class Layout(NamedTuple):
    """A ring or mesh table.

    kind : ``"ring"`` or ``"mesh"``.
    shape : table shape (M rings, Np points per ring) or (nx, ny).
    pitch : (Δρ [µm], Δθ [deg]) or (Δx [µm], Δy [µm]).
    origin : coordinates of table entry [0, 0]: (0 µm, 0 deg) or (x0 [µm], y0 [µm]).
    """

    kind: str
    shape: tuple[int, int]
    pitch: tuple[float, float]
    origin: tuple[float, float]

    @property
    def n_points(self) -> int:
        """Number of control points N = shape[0]·shape[1]."""
        return self.shape[0] * self.shape[1]

    @property
    def aspect(self) -> float:
        """Aspect ratio α: Δρ[µm]/Δθ[deg] for rings, Δx/Δy for meshes (§2)."""
        return self.pitch[0] / self.pitch[1]

    @property
    def periodic(self) -> bool:
        """Whether the table is polar, its second index θ wrapping around (the ring method)."""
        return self.kind == "ring"


def _cover(extent_um: float, pitch_um: float) -> int:
    """Nodes needed to cover ``extent_um`` at ``pitch_um``: ceil(extent/pitch) + 1 (§2).

    A relative slack of 1e-9 keeps pitches computed as extent/(n−1) from gaining a node
    through floating-point rounding.
    """
    return int(math.ceil(extent_um / pitch_um * (1.0 - 1e-9))) + 1


def _check_positive(**values: float) -> None:
    for name, value in values.items():
        if not (value > 0.0 and math.isfinite(value)):
            raise ValueError(f"{name} must be a positive finite number, got {value!r}")


def nearest_ring_dtheta(dtheta_deg: float) -> tuple[float, int]:
    """The realisable angular pitch nearest ``dtheta_deg`` [deg]: 360/Np [deg] for the integer
    Np = round(360/Δθ) (at least 4), and Np (model §2: Np = 360/Δθ points per ring)."""
    _check_positive(dtheta_deg=dtheta_deg)
    np_int = max(4, int(round(360.0 / dtheta_deg)))
    return 360.0 / np_int, np_int


def ring_layout(radius_um: float, drho_um: float, dtheta_deg: float) -> Layout:
    """Ring (polar) layout from explicit pitches, model §2.

    Rings at ρ_i = i·Δρ, i = 0..M−1 with M = ceil(R/Δρ) + 1; Np = 360/Δθ points per ring.

    Parameters
    ----------
    radius_um : aperture radius R [µm].
    drho_um : ring pitch Δρ [µm].
    dtheta_deg : angular pitch Δθ [deg]; 360/Δθ must be an integer (within 1e-6).
    """
    _check_positive(radius_um=radius_um, drho_um=drho_um, dtheta_deg=dtheta_deg)
    n_per_ring = 360.0 / dtheta_deg
    np_int = int(round(n_per_ring))
    if abs(n_per_ring - np_int) > 1e-6 * n_per_ring:
        raise ValueError(
            f"dtheta_deg={dtheta_deg} does not divide 360°: choose 360/Np for an integer Np, "
            f"e.g. {360.0 / max(np_int, 1)!r} (Np = {np_int})"
        )
    if np_int < 4:
        raise ValueError(f"dtheta_deg={dtheta_deg} gives {np_int} points per ring; at least 4 are needed")
    m = _cover(radius_um, drho_um)
    return Layout("ring", (m, np_int), (float(drho_um), 360.0 / np_int), (0.0, 0.0))


def mesh_layout(width_um: float, height_um: float, dx_um: float, dy_um: float) -> Layout:
    """Mesh (Cartesian) layout from explicit pitches, model §2.

    nx = ceil(W/Δx) + 1, ny = ceil(H/Δy) + 1 nodes, centred on the aperture.

    Parameters
    ----------
    width_um, height_um : aperture width W and height H [µm].
    dx_um, dy_um : pitches Δx, Δy [µm].
    """
    _check_positive(width_um=width_um, height_um=height_um, dx_um=dx_um, dy_um=dy_um)
    nx, ny = _cover(width_um, dx_um), _cover(height_um, dy_um)
    x0 = -0.5 * (nx - 1) * dx_um
    y0 = -0.5 * (ny - 1) * dy_um
    return Layout("mesh", (nx, ny), (float(dx_um), float(dy_um)), (x0, y0))


def ring_layout_for(radius_um: float, n_points: float, aspect: float) -> Layout:
    """Ring layout with about ``n_points`` points at aspect ratio α = Δρ[µm]/Δθ[deg].

    With M ≈ R/Δρ and Np = 360/Δθ = 360·α/Δρ, N ≈ 360·α·R/Δρ², so the continuous
    Δρ = sqrt(360·α·R/N). Np is rounded first, then M = floor(N/Np) rings and
    Δρ = R/(M − 1) so the last ring lies on the aperture edge. The target acts as a budget:
    the actual N is at most the target and within one ring of it (unless the minimum of
    two rings applies), and is reported by the returned layout.
    """
    _check_positive(radius_um=radius_um, n_points=n_points, aspect=aspect)
    drho0 = math.sqrt(360.0 * aspect * radius_um / n_points)
    np_int = max(4, int(round(360.0 * aspect / drho0)))
    m = max(2, int(math.floor(n_points / np_int + 1e-9)))
    return ring_layout(radius_um, radius_um / (m - 1), 360.0 / np_int)


def mesh_layout_for(width_um: float, height_um: float, n_points: float, aspect: float) -> Layout:
    """Mesh layout with about ``n_points`` points at aspect ratio α = Δx/Δy.

    N ≈ (W/Δx)·(H/Δy) = W·H·α/Δx², so Δx = sqrt(W·H·α/N); nx is rounded first, then
    ny = floor(N/nx) and the pitches are W/(nx−1), H/(ny−1) so the mesh spans the
    aperture exactly. The actual N is at most the target and within one row of it.
    """
    _check_positive(width_um=width_um, height_um=height_um, n_points=n_points, aspect=aspect)
    dx0 = math.sqrt(width_um * height_um * aspect / n_points)
    nx = max(2, int(round(width_um / dx0)) + 1)
    ny = max(2, int(math.floor(n_points / nx + 1e-9)))
    return mesh_layout(width_um, height_um, width_um / (nx - 1), height_um / (ny - 1))


def layout_nodes(layout: Layout) -> tuple[np.ndarray, np.ndarray]:
    """Radial position ρ [µm] and radial-section angle θ [rad] of every table entry.

    Arrays of ``layout.shape``. For the ring method the section angle is the ring angle
    (also at ρ = 0, where each column keeps its own direction); for the mesh method it is
    atan2(y, x) (model §4: the same radial-section rule applies to mesh points).
    """
    i = np.arange(layout.shape[0], dtype=np.float64)[:, None]
    j = np.arange(layout.shape[1], dtype=np.float64)[None, :]
    if layout.kind == "ring":
        rho = np.broadcast_to(layout.origin[0] + i * layout.pitch[0], layout.shape)
        theta = np.broadcast_to(np.radians(layout.origin[1] + j * layout.pitch[1]), layout.shape)
        return np.ascontiguousarray(rho), np.ascontiguousarray(theta)
    x = layout.origin[0] + i * layout.pitch[0]
    y = layout.origin[1] + j * layout.pitch[1]
    x, y = np.broadcast_arrays(x, y)
    return np.hypot(x, y), np.arctan2(y, x)
