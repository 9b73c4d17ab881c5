"""The names a ring or mesh table goes by (model §2): its pitch fields, its noun and its sweep
axes, shared by the kind's class (the package face) and its planner."""

from __future__ import annotations

PITCHES = {"ring": ("drho_um", "dtheta_deg"), "mesh": ("dx_um", "dy_um")}
NOUNS = {"ring": "ring layout", "mesh": "mesh layout"}
AXES = ("points", "aspect")
