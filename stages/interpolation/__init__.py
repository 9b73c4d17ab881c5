"""Interpolation (model §3, §4): what the controller commands at a point of the tool path.
Tool-nose compensation of the stored values (``compensation``, ``ray_commands``), bilinear
interpolation of a table along the spiral (``tables``), the segments a controller forms
between a path program's points (``segments``: linear, PVT cubics, B-splines), a spiral
program as its controller runs it (``spiral_program``: its points, the spiral's geometry, its
command at any angle) and its commands at the simulator's passes, and where a program crosses the simulator's
rays (``rays``: linear segments; ``timed_path``: cubic ones).
"""

from __future__ import annotations

from ftsweep.stages import face

_EXPORTS = {
    "compensation": "compensation",
    "arc_lift": "compensation",
    "contact_window_um": "compensation",
    "slope_compensation": "compensation",
    "compensate": "compensation",
    "scan_samples": "compensation",
    "ray_commands": "ray_commands",
    "compensate_on_ray": "ray_commands",
    "commands_on_rays": "ray_commands",
    "rays": "rays",
    "step_of": "rays",
    "RayGrid": "rays",
    "ray_grid": "rays",
    "segments": "segments",
    "hermite": "segments",
    "natural_spline": "segments",
    "pvt_tangents": "segments",
    "control_points": "segments",
    "added_pieces_segments": "segments",
    "bspline_segments": "segments",
    "evaluate": "segments",
    "deviations": "segments",
    "dense_slopes": "segments",
    "split_until_within": "segments",
    "quantised": "segments",
    "whole_steps": "segments",
    "spiral_passes": "spiral_passes",
    "spiral_program": "spiral_program",
    "SpiralPath": "spiral_program",
    "spiral_commands": "spiral_program",
    "phi_on_path": "spiral_program",
    "spiral_radius": "spiral_program",
    "pass_commands_kernel": "spiral_passes",
    "tables": "tables",
    "bilinear": "tables",
    "table_indices": "tables",
    "interpolate": "tables",
    "pass_commands": "tables",
    "PathGrid": "tables",
    "nonfinite_passes": "tables",
    "sample_on_nodes": "tables",
    "first_machined_node": "tables",
    "line_angles": "tables",
    "path_grid": "tables",
    "timed_path": "timed_path",
    "slopes": "timed_path",
    "tangents": "timed_path",
    "on_time_steps": "timed_path",
    "velocities": "timed_path",
    "from_velocities": "timed_path",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = face(__name__, _EXPORTS)
