"""A form error over a rectangular aperture broken down into products of Chebyshev polynomials
T_i(u)·T_j(v), u = 2x/width and v = 2y/height (the breakdown the Chebyshev freeform family
uses, model §7), fitted by least squares.

Coefficients in the units of the heights (µm).
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import chebyshev


def chebyshev_fit(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, width_um: float, height_um: float, degree: int = 4
) -> dict[tuple[int, int], float]:
    """Least-squares coefficients {(i, j): c_ij [µm]} of heights ``z`` at (x, y) [µm] over the
    centred ``width_um`` × ``height_um`` rectangle, for every i, j ≤ ``degree`` (NaN heights
    left out)."""
    u, v = 2.0 * x / width_um, 2.0 * y / height_um
    use = np.isfinite(z) & (np.abs(u) <= 1.0) & (np.abs(v) <= 1.0)
    terms = (degree + 1) ** 2
    if use.sum() <= terms:
        raise ValueError(f"{int(use.sum())} point(s) in the rectangle: more than {terms} are needed")
    basis = chebyshev.chebvander2d(u[use], v[use], [degree, degree])
    coef, *_ = np.linalg.lstsq(basis, z[use], rcond=None)
    pairs = [(i, j) for i in range(degree + 1) for j in range(degree + 1)]
    return {pair: float(c) for pair, c in zip(pairs, coef, strict=True)}


def chebyshev_order(degree: int = 4) -> list[tuple[int, int]]:
    """The products (i, j), i, j ≤ ``degree``, in the order a low-pass keeps them: by total
    degree i + j, then from the highest power of u; the first three are piston T0·T0 and the
    tilts T1·T0, T0·T1, as Noll's order starts with piston and tilts."""
    pairs = []
    for total in range(2 * degree + 1):
        for i in range(min(total, degree), max(total - degree, 0) - 1, -1):
            pairs.append((i, total - i))
    return pairs
