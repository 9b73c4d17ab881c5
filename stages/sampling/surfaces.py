"""Surface sampling: design heights, their gradients and apertures (model §7).

Every family is a numba kernel over flat float64 arrays plus a thin numpy wrapper with
keyword parameters in catalog units. All lengths are micrometres [µm], heights are
micrometres along the spindle axis, gradients are dimensionless [µm/µm].

A *surface callable* in the rest of ftsweep is any ``fn(x, y) -> (f, dfdx, dfdy)`` taking
arrays of equal shape in µm; the pipeline builds one from a catalog entry with
``functools.partial(FAMILIES[name].evaluate, **params)``.
"""

from __future__ import annotations

from ftsweep.stages.sampling.arrays import cylinder_array, lens_array, sinewave2d, sinusoidal_mesh
from ftsweep.stages.sampling.bspline import bspline2d
from ftsweep.stages.sampling.families import FAMILIES, Family, Param, surface_family
from ftsweep.stages.sampling.forms import chebyshev_freeform, microprism, noll_to_nm, sphere, zernike
from ftsweep.stages.sampling.geometry import (
    Aperture,
    SurfaceFn,
    radial_section,
    sampled_gradient_bound,
)

__all__ = [
    "FAMILIES",
    "Aperture",
    "Family",
    "Param",
    "SurfaceFn",
    "bspline2d",
    "chebyshev_freeform",
    "cylinder_array",
    "lens_array",
    "microprism",
    "noll_to_nm",
    "sinewave2d",
    "sinusoidal_mesh",
    "sphere",
    "zernike",
    "radial_section",
    "sampled_gradient_bound",
    "surface_family",
]
