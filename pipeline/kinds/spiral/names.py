"""The sweep axes of a spiral program ([4]): its three sampling rules and the residual budget,
shared by the kind's class (the package face) and its planner."""

from __future__ import annotations

AXES = ("points_per_rev", "arc_um", "chord_um", "residual_um")
