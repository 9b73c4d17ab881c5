"""Kinematics (model §6 "Dynamics"; [2] eq. 14): the axes' velocities and accelerations over
time against the machine's limits, shared by every program kind, and the spectrum of the
W command a table's controller outputs.
"""

from __future__ import annotations

from ftsweep.stages import face

_EXPORTS = {
    "axes": "axes",
    "accelerations": "axes",
    "turn_peaks": "axes",
    "velocities": "axes",
    "Motion": "axes",
    "steps_of": "axes",
    "motion": "axes",
    "over_steps": "axes",
    "Limits": "axes",
    "Extremes": "axes",
    "ExtremesOver": "axes",
    "extremes": "axes",
    "relative": "axes",
    "limits_reason": "axes",
    "extremes_reason": "axes",
    "dynamics": "dynamics",
    "Dynamics": "dynamics",
    "commands_per_revolution": "dynamics",
    "revolution_commands": "dynamics",
    "spectrum": "dynamics",
    "highest_significant_frequency": "dynamics",
    "analyse": "dynamics",
    "feasibility": "dynamics",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = face(__name__, _EXPORTS)
