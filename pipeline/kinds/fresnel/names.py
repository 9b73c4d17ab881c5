"""The sweep axes and request fields of a Fresnel program ([2]), shared by the kind's class (the
package face), its request model and its planner."""

from __future__ import annotations

AXES = ("facet_height_um", "points_per_turn", "deviation_deg")
FRESNEL_FIELDS = ("facet_height_um", "points_per_turn", "deviation_deg", "safety", "control_points", "timing")
