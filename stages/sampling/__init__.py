"""Surface sampling (model §7): every family's numba kernel over flat float64 arrays, its
thin wrapper in catalog units, the family registry, the shared geometry of apertures and
radial sections, and bicubic B-splines for height maps. Lengths in µm, gradients in µm/µm.
"""

from __future__ import annotations

from ftsweep.stages import face

_EXPORTS = {
    "arrays": "arrays",
    "sinewave2d_gradient_bound": "arrays",
    "sinewave2d_curvature_bound": "arrays",
    "sinewave2d": "arrays",
    "lens_array_gradient_bound": "arrays",
    "lens_array_curvature_bound": "arrays",
    "lens_array": "arrays",
    "sinusoidal_mesh": "arrays",
    "cylinder_array_gradient_bound": "arrays",
    "cylinder_array": "arrays",
    "bspline": "bspline",
    "bspline2d": "bspline",
    "families": "families",
    "Param": "families",
    "Family": "families",
    "surface_family": "families",
    "forms": "forms",
    "chebyshev_freeform": "forms",
    "sphere": "forms",
    "noll_to_nm": "forms",
    "zernike": "forms",
    "microprism_gradient_bound": "forms",
    "microprism": "forms",
    "geometry": "geometry",
    "flat_pair": "geometry",
    "evaluate_flat": "geometry",
    "evaluate_lines": "geometry",
    "line_evaluator": "geometry",
    "sampled_gradient_bound": "geometry",
    "radial_section": "geometry",
    "Aperture": "geometry",
    "surfaces": "surfaces",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = face(__name__, _EXPORTS)
