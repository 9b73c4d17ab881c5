"""Sweeps: the sweep spec, its run into a cube (resume, growth), and the Dask execution of its
tasks.
"""

from __future__ import annotations

from ftsweep.stages import face

# the public names, each loaded from its module on first use (importing the face loads none)
_EXPORTS = {
    "SweepSpec": "spec",
    "case_at": "spec",
    "coordinates": "spec",
    "load_sweep": "spec",
    "run_sweep": "run",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = face(__name__, _EXPORTS)
