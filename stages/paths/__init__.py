"""The path kinds' planners and the paths programs command: spiral programs from error
budgets ([4]) and their cusp budget, layered trajectories ([3]), D paths and their motion
([5]), Fresnel quasi-spirals and the timesteps of their turns ([2]), and any program read
from a file as its controller commands it. Each module is its own namespace.
"""

from __future__ import annotations

from ftsweep.stages import face

_EXPORTS = {
    "commanded": "commanded",
    "cusp_budget": "cusp_budget",
    "dpath": "dpath",
    "dpath_motion": "dpath_motion",
    "fresnel": "fresnel",
    "layers": "layers",
    "spiral": "spiral",
    "turnopt": "turnopt",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = face(__name__, _EXPORTS)
