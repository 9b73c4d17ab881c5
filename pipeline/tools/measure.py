"""A measured part against its design: the measurement read as it came
(:mod:`ftsweep.inputs.measurements`), registered to the catalog surface over the surface's
aperture (:mod:`ftsweep.stages.measurement`), and its residual — the part's form error —
summarised: P-V and RMS [nm] and its breakdown into Zernike terms (a circular aperture) or
Chebyshev products (a rectangle), each coefficient in nm.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, NamedTuple, Optional

import numpy as np

from ftsweep.inputs import catalogs
from ftsweep.inputs.measurements import Measurement, read_measurement
from ftsweep.stages.measurement import Registration, chebyshev_fit, register, term_name, zernike_fit


class MeasuredPart(NamedTuple):
    """A registered measurement: what was read, the fit, and its summary (the file's hash,
    the fitted terms and their standard errors, P-V, RMS and breakdown in nm)."""

    measurement: Measurement
    registration: Registration
    summary: dict[str, Any]


def measure_part(
    path: Path,
    surface: str,
    catalog_folder: Optional[Path] = None,
    *,
    units: Optional[str] = None,
    pixel_um: Optional[float] = None,
    decentre: bool = True,
    rotation: bool = False,
    power: bool = False,
    terms: int = 15,
) -> MeasuredPart:
    """Read ``path`` and register it to catalog surface ``surface`` (its design and aperture).

    ``units`` and ``pixel_um`` state what the file does not (:func:`read_measurement`);
    ``decentre``, ``rotation``, ``power`` choose the set-up terms fitted besides piston and
    tilt (:func:`ftsweep.stages.measurement.register`); ``terms``: Zernike terms of the
    breakdown (a rectangle takes Chebyshev products up to degree 4)."""
    spec = catalogs.entry("surfaces", surface, catalog_folder)
    design = catalogs.surface_callable(spec, catalog_folder)
    aperture = catalogs.aperture_of(spec)
    measured = read_measurement(path, units=units, pixel_um=pixel_um)
    inside = aperture.contains(measured.x, measured.y)
    fit = register(
        design, measured.x, measured.y, measured.z, inside, decentre=decentre, rotation=rotation, power=power
    )
    rest = fit.residual
    if aperture.shape == "circle":
        coef = zernike_fit(measured.x, measured.y, rest, aperture.radius_um, terms)
        breakdown = [{"term": term_name(j), "nm": 1e3 * c} for j, c in coef.items()]
    else:
        cheb = chebyshev_fit(measured.x, measured.y, rest, aperture.width_um, aperture.height_um)
        breakdown = [{"term": f"T{i}(u)·T{j}(v)", "nm": 1e3 * c} for (i, j), c in cheb.items()]
    found = {
        "measurement": str(path),
        "sha256": measured.sha256,
        "units": measured.units,
        "surface": surface,
        "points": fit.points,
        "terms": fit.terms,
        "sigma": fit.sigma,
        "pv_nm": 1e3 * float(np.nanmax(rest) - np.nanmin(rest)),
        "rms_nm": 1e3 * float(np.nanstd(rest)),
        "breakdown": breakdown,
    }
    return MeasuredPart(measured, fit, found)
