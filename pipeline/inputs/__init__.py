"""What users bring: catalogs of surfaces, machines and cutting conditions, user surfaces (height
maps, plug-ins), and the trust rules for them.
"""

from __future__ import annotations

from ftsweep.stages import face

# the public names, each loaded from its module on first use (importing the face loads none)
_EXPORTS = {
    "CatalogError": "catalogs",
    "aperture_of": "catalogs",
    "catalog_dir": "catalogs",
    "entries": "catalogs",
    "entry": "catalogs",
    "sliced_callable": "facets",
    "surface_callable": "catalogs",
    "surface_range": "facets",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = face(__name__, _EXPORTS)
