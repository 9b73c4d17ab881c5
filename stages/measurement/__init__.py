"""Measurement (corrective machining): a measured part registered to its design, its set-up
terms with their uncertainties, and its form error broken down into Zernike terms (a circle)
or Chebyshev products (a rectangle).
"""

from __future__ import annotations

from ftsweep.stages import face

_EXPORTS = {
    "Registration": "registration",
    "register": "registration",
    "registered_like": "registration",
    "TERMS": "registration",
    "zernike_basis": "zernike",
    "zernike_fit": "zernike",
    "term_name": "zernike",
    "chebyshev_fit": "chebyshev",
    "chebyshev_order": "chebyshev",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = face(__name__, _EXPORTS)
