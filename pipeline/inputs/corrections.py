"""A measured correction of a catalog surface: the design less a gain times the low-passed
error a measured part showed beyond its prediction (the machine's share,
:func:`ftsweep.tools.measure.explain`), as a surface entry's ``correction`` block.

    f_corrected = f − g·L_N(U),    L_N(U) = Σ_{k=4..N} u_k·B_k                         (1)

B_k are Noll's Zernike polynomials over the aperture's circle (the ``zernike`` family's) or
products of Chebyshev polynomials T_i(2x/w)·T_j(2y/h) over its rectangle (the
``chebyshev_freeform`` family's) in :func:`ftsweep.stages.measurement.chebyshev_order`; the
first three (piston and tilts) are never kept: the set-up gives them anyway. N, the terms
kept, is the low-pass: a term of radial order n varies on about 2R/n, which must span many
of the layout's pitches for the servo and the table to follow it. Both families return the
slopes with the heights, so (1) is exact to the last term, slopes included.

The block names the measurement's SHA-256 and the registration's fitted terms, so every cube
and exported file planned on the corrected surface records which measurement made it. A
case's ``correction_gain`` and ``correction_terms`` (a sweep's axes of the same names) stand
in for the block's gain and N (:func:`as_cased`).
"""

from __future__ import annotations

import math
from typing import Any, Optional

import numpy as np
from pydantic import Field, PositiveInt, model_validator

from ftsweep.inputs.strict import Strict
from ftsweep.stages.sampling.surfaces import Aperture, SurfaceFn

MAX_GAIN = 1.5
SETUP_TERMS = 3  # piston and the two tilts


class MeasuredCorrection(Strict):
    """Eq. (1): the unexplained error's terms (one of ``zernike_um`` or ``chebyshev_um``), the
    gain g and the terms N kept, and where they came from."""

    measurement_sha256: str = Field(pattern=r"^[0-9a-f]{64}$", description="SHA-256 of the measured file")
    gain: float = Field(1.0, gt=0.0, le=MAX_GAIN, description="gain g of eq. (1) [-]")
    terms: PositiveInt = Field(15, description="terms N kept (the low-pass): Noll index or product count")
    zernike_um: Optional[dict[int, float]] = Field(
        None, description="{Noll j: u_j [µm]} of the unexplained error over the aperture's circle"
    )
    chebyshev_um: Optional[list[list[float]]] = Field(
        None, description="u_ij [µm] of T_i(2x/w)·T_j(2y/h), rows i, over the aperture's rectangle"
    )
    fit: dict[str, float] = Field(
        default_factory=dict, description="the registration's fitted set-up terms (µm, rad)"
    )

    @model_validator(mode="after")
    def _one_breakdown(self) -> MeasuredCorrection:
        if (self.zernike_um is None) == (self.chebyshev_um is None):
            raise ValueError("a correction gives one of zernike_um (a circle) or chebyshev_um (a rectangle)")
        values = list((self.zernike_um or {}).values()) + [v for row in self.chebyshev_um or [] for v in row]
        if not all(math.isfinite(v) for v in values):
            raise ValueError("a correction's terms are finite numbers [µm]")
        if self.zernike_um is not None and not all(1 <= j <= 231 for j in self.zernike_um):
            raise ValueError("zernike_um: Noll indices run from 1 to 231")
        if self.chebyshev_um is not None and len({len(row) for row in self.chebyshev_um}) != 1:
            raise ValueError("chebyshev_um: every row has as many columns")
        check_terms(self, self.terms)
        return self

    @property
    def available(self) -> int:
        """How many terms (1) may keep: the highest Noll index given, or every product."""
        if self.zernike_um is not None:
            return max(self.zernike_um, default=0)
        rows = self.chebyshev_um or []
        return len(rows) * len(rows[0]) if rows else 0


def check_terms(correction: MeasuredCorrection, terms: int) -> None:
    """Refuse keeping more terms than the measurement's breakdown has, or none beyond the set-up."""
    if not SETUP_TERMS < terms <= correction.available:
        raise ValueError(
            f"a correction keeps {SETUP_TERMS + 1}…{correction.available} terms (its breakdown's; "
            f"the first {SETUP_TERMS} are piston and tilts), got {terms}"
        )


def as_cased(spec: Any, gain: Optional[float], terms: Optional[int]) -> Any:
    """The surface entry ``spec`` with a case's gain and terms in its correction (unchanged
    where both are None); refused where the entry has no correction or too few terms."""
    if gain is None and terms is None:
        return spec
    if spec.correction is None:
        raise ValueError(
            "the case sets a correction's gain or terms, but its surface has no measured correction "
            "(ftsweep correct writes one)"
        )
    update: dict[str, Any] = {}
    if gain is not None:
        if not 0.0 < gain <= MAX_GAIN:
            raise ValueError(f"correction gain {gain:g}: it lies in (0, {MAX_GAIN:g}]")
        update["gain"] = float(gain)
    if terms is not None:
        check_terms(spec.correction, int(terms))
        update["terms"] = int(terms)
    return spec.model_copy(update={"correction": spec.correction.model_copy(update=update)})


def corrected_callable(fn: SurfaceFn, correction: MeasuredCorrection, aperture: Aperture) -> SurfaceFn:
    """Eq. (1) of surface ``fn`` (µm in, (f, fx, fy) out)."""
    part = low_pass_callable(correction, aperture)
    gain = correction.gain

    def corrected(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        f, fx, fy = fn(x, y)
        c, cx, cy = part(x, y)
        return f - gain * c, fx - gain * cx, fy - gain * cy

    return corrected


def low_pass_callable(correction: MeasuredCorrection, aperture: Aperture) -> SurfaceFn:
    """L_N(U) of eq. (1) with its slopes: the terms 4…N of the correction's breakdown."""
    from ftsweep.stages.sampling import forms

    keep = correction.terms
    if correction.zernike_um is not None:
        kept = {j: a for j, a in correction.zernike_um.items() if SETUP_TERMS < j <= keep}
        radius = float(aperture.radius_um)
        return lambda x, y: forms.zernike(x, y, norm_radius_um=radius, terms_um=kept or {1: 0.0})
    from ftsweep.stages.measurement import chebyshev_order

    given = np.asarray(correction.chebyshev_um, dtype=float)
    grid = np.zeros_like(given)
    rows, cols = given.shape
    order = [(i, j) for i, j in chebyshev_order(max(rows, cols) - 1) if i < rows and j < cols]
    for i, j in order[SETUP_TERMS:keep]:
        grid[i, j] = given[i, j]
    coefficients = grid.tolist()
    width, height = float(aperture.width_um), float(aperture.height_um)
    return lambda x, y: forms.chebyshev_freeform(
        x, y, base_radius_um=0.0, coefficients_um=coefficients, norm_x_um=width / 2, norm_y_um=height / 2
    )
