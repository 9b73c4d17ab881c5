"""A form error broken down into Noll-indexed Zernike terms over a circular aperture, the
breakdown an interferometer's software reports (Noll 1976; the polynomials, normalised to unit
RMS over the disc, are those of the ``zernike`` surface family, model §7).

Coefficients in the units of the heights (µm); each is the RMS its term contributes.
"""

from __future__ import annotations

import numpy as np

from ftsweep.stages.sampling.forms import noll_to_nm, zernike


def zernike_basis(x: np.ndarray, y: np.ndarray, radius_um: float, terms: int) -> np.ndarray:
    """Z_1 … Z_terms at (x, y) [µm] over the disc of ``radius_um``: an (n, terms) array."""
    if terms < 1:
        raise ValueError(f"at least one Zernike term is needed, got {terms}")
    return np.column_stack(
        [zernike(x, y, norm_radius_um=radius_um, terms_um={j: 1.0})[0] for j in range(1, terms + 1)]
    )


def zernike_fit(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, radius_um: float, terms: int = 15
) -> dict[int, float]:
    """Least-squares Zernike coefficients {Noll j: a_j [µm]} of heights ``z`` at (x, y) [µm]
    within ``radius_um`` of the axis (NaN heights left out)."""
    use = np.isfinite(z) & (x * x + y * y <= radius_um * radius_um)
    if use.sum() <= terms:
        raise ValueError(f"{int(use.sum())} point(s) in the disc: more than {terms} are needed")
    basis = zernike_basis(x[use], y[use], radius_um, terms)
    coef, *_ = np.linalg.lstsq(basis, z[use], rcond=None)
    return {j: float(c) for j, c in zip(range(1, terms + 1), coef, strict=True)}


def term_name(j: int) -> str:
    """A short name of Noll term j: its radial order n and azimuthal frequency m."""
    n, m = noll_to_nm(j)
    return f"Z{j} (n={n}, m={m})"
