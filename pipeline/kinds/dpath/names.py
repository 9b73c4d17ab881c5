"""The sweep axes and command-line options of a D-path program ([5]), shared by the kind's
class (the package face) and its planner."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

AXES = ("spacing_um", "points_per_cut")
OPTIONS = ("spacing_um", "points_per_cut", "zones", "offaxis_mm", "cut_angle_deg", "transition_step_deg")


def request_options(opts: Mapping[str, Any]) -> dict[str, Any]:
    """The D-path request fields of command-line options (mm and choice strings converted;
    options not given left out)."""
    fields = {
        "spacing_um": opts.get("spacing_um"),
        "points_per_cut": opts.get("points_per_cut"),
        "zones": int(opts["zones"]) if opts.get("zones") else None,
        "offaxis_um": opts["offaxis_mm"] * 1e3 if opts.get("offaxis_mm") else None,
        "cut_angle_deg": opts.get("cut_angle_deg"),
        "transition_step_deg": opts.get("transition_step_deg"),
    }
    return {k: v for k, v in fields.items() if v is not None}
