"""The declared result of a case: every field a prediction reports, with its units, long name
and how cubes store it. One vocabulary everywhere: ``run_case`` returns these names (and
``predict --json`` prints them), cubes hold the stored ones under the same names with these
units, and ``select``/``describe`` read them back unchanged. Units are ones unit libraries
parse (pint, UDUNITS); ``None`` marks text and flags, which carry none (CF).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional

import numpy as np

KINDS = ("ring", "mesh", "spiral", "dpath", "fresnel")
TABLES = ("ring", "mesh")
SPINDLE = ("ring", "mesh", "spiral")  # programs on the spiral about the spindle axis
PATHS = ("spiral", "dpath", "fresnel")
DPATH = ("dpath",)
FRESNEL = ("fresnel",)


@dataclass(frozen=True)
class Quantity:
    """One declared field of a case result.

    units : parseable units, or a mapping layout kind → units where they differ by kind.
    dtype, fill : how a cube stores it (``dtype`` None: not stored per case in a cube).
    kinds : the program kinds whose results hold it.
    """

    name: str
    long_name: str
    units: Any = None
    dtype: Optional[str] = None
    fill: Any = None
    kinds: tuple[str, ...] = KINDS

    def units_for(self, kind: str) -> Optional[str]:
        return self.units.get(kind) if isinstance(self.units, dict) else self.units


def _f(name: str, units: Any, long_name: str, kinds: tuple[str, ...] = KINDS) -> Quantity:
    return Quantity(name, long_name, units, "float64", np.nan, kinds)


def _i(name: str, long_name: str, dtype: str = "int64", kinds: tuple[str, ...] = KINDS) -> Quantity:
    return Quantity(name, long_name, "1", dtype, -1, kinds)


def _text(name: str, long_name: str) -> Quantity:
    return Quantity(name, long_name)


def _input(name: str, units: Any, long_name: str) -> Quantity:
    return Quantity(name, long_name, units)


STAGES = ("sampling", "compensation", "interpolation", "envelope", "metrics", "dynamics")

RESULT: tuple[Quantity, ...] = (
    # what was simulated
    _text("surface", "surface catalog entry"),
    _text("layout", "program kind: ring or mesh table, spiral path, D path or Fresnel program"),
    _text("compensation", "tool-nose compensation of the table: exact, slope or none"),
    _text("machine", "machine catalog entry"),
    _input("feed_um", "um", "feed per spindle revolution"),
    _input("nose_radius_um", "um", "tool nose radius"),
    _input("spindle_rpm", "1/min", "spindle speed"),
    _input("points_per_feed", "1", "evaluation points per feed along each angle"),
    _input("edge_band_um", "um", "band at the aperture's edge outside the fully machined zone"),
    # the table
    _i("n_points", "number of control points of the program"),
    _i("table_rows", "table rows (rings M or mesh nx)", "int32", TABLES),
    _i("table_cols", "table columns (points per ring Np or mesh ny)", "int32", TABLES),
    _f("drho_um", "um", "ring pitch Δρ", ("ring",)),
    _f("dtheta_deg", "deg", "angular pitch Δθ", ("ring",)),
    _f("dx_um", "um", "mesh pitch Δx", ("mesh",)),
    _f("dy_um", "um", "mesh pitch Δy", ("mesh",)),
    # the spiral program ([4])
    Quantity("spiral_rule", "spiral sampling rule: angle, arc or chord", kinds=("spiral",)),
    # the rule's parameters are inputs (a spiral cube's axes), not stored per case
    Quantity("points_per_rev", "points per revolution of the constant-angle rule", "1", kinds=("spiral",)),
    Quantity("arc_um", "path length between points of the constant-arc rule", "um", kinds=("spiral",)),
    Quantity("chord_um", "chord-error budget of the chord rule", "um", kinds=("spiral",)),
    Quantity("residual_um", "residual (cusp) budget that set the feed", "um", kinds=("spiral",)),
    _f("revolutions", "1", "revolutions of the path (spiral: from the edge to the centre)", PATHS),
    _f("dphi_deg", "deg", "mean spindle-angle step between points", PATHS),
    _f("ds_um", "um", "mean path length between points", PATHS),
    _f("chord_error_nm", "nm", "largest chord deviation from the compensated path", ("spiral",)),
    _f(
        "residual_error_nm",
        "nm",
        "largest residual (cusp) height from the feed and the section curvature",
        ("spiral",),
    ),  # noqa: E501
    _f(
        "aspect_actual",
        {"ring": "um/deg", "mesh": "1", "spiral": "um/deg"},
        "aspect ratio of the realised pitches (spiral: feed over mean angular step)",
        SPINDLE,
    ),
    # the D-shaped slow-tool-servo path ([5]); its options are inputs (a D-path cube's axes)
    Quantity("spacing_um", "spacing h between the D path's cuts", "um", kinds=DPATH),
    Quantity("points_per_cut", "points on every cut of the D path", "1", kinds=DPATH),
    Quantity("transition", "turn-round between cuts: traditional (arc) or optimised (quintic)", kinds=DPATH),
    Quantity("zones", "cutting zones per revolution", "1", kinds=DPATH),
    Quantity("offaxis_um", "distance of the part's centre from the C axis", "um", kinds=DPATH),
    Quantity("cut_angle_deg", "direction of the cuts in the part's frame", "deg", kinds=DPATH),
    _i("n_cuts", "cuts over all zones", kinds=DPATH),
    _f("cut_length_um", "um", "length l of the cuts (the zone along them)", DPATH),
    _f("cut_width_um", "um", "width s of the cutting zone across the cuts", DPATH),
    _f("cut_step_um", "um", "distance between consecutive points of a cut", DPATH),
    # the freeform Fresnel program on an X-Y-Z-C lathe ([2]); its options are inputs
    Quantity("facet_height_um", "height h of every Fresnel facet", "um", kinds=FRESNEL),
    Quantity("points_per_turn", "control points K on every turn of the quasi-spiral", "1", kinds=FRESNEL),
    Quantity("deviation_deg", "rake face turned from the cutting direction", "deg", kinds=FRESNEL),
    _i("n_facets", "Fresnel facets the surface is sliced into", "int32", FRESNEL),
    _f("ez_exact_max_nm", "nm", "largest tool-edge compensation by [2] eq. 10 on the part", FRESNEL),
    _f("ez_straight_max_nm", "nm", "largest tool-edge compensation by [2] eq. 12 on the part", FRESNEL),
    Quantity(
        "facets", "P-V and RMS of every facet's interior, outermost first (predict, not cubes)", kinds=FRESNEL
    ),
    _f("time_constant_s", "s", "machining time at the least constant timestep within the limits", FRESNEL),
    _f("speedup", "1", "machining time at the constant timestep over that of the adaptive ones", FRESNEL),
    # the form error (model §6)
    _f("pv_nm", "nm", "peak-to-valley form error"),
    _f("rms_nm", "nm", "RMS form error about its mean"),
    _f("mean_nm", "nm", "mean form error"),
    _f("error_min_nm", "nm", "lowest form error"),
    _f("error_max_nm", "nm", "highest form error"),
    _f("pv_inner_nm", "nm", "P-V in the inner zone"),
    _f("pv_outer_nm", "nm", "P-V in the outer zone"),
    _f("pv_interp_nm", "nm", "P-V of the interpolation-only error"),
    _f("cusp_nm", "nm", "feed cusp height of a flat surface F^2/(8 Rc)"),
    _i("gouge_points", "control points whose section is concave with radius below Rc"),
    _i("n_theta", "simulated spindle angles"),
    _i("n_eval", "evaluation points"),
    # the W motion ([2] dynamics, model §6)
    _f("stroke_um", "um", "W stroke used (range of the table)"),
    _f("w_velocity_peak_mm_s", "mm/s", "peak W velocity at the spindle speed"),
    _f("w_accel_peak_m_s2", "m/s^2", "peak W acceleration at the spindle speed"),
    _f("w_accel_rms_m_s2", "m/s^2", "RMS W acceleration at the spindle speed"),
    _f("w_freq_max_hz", "Hz", "highest significant frequency of the W command", SPINDLE),
    # the X axis of a D path at constant spindle speed ([5] eqs. 5-6)
    _f("x_min_um", "um", "smallest X (polar radius) of the path", DPATH),
    _f("x_max_um", "um", "largest X (polar radius) of the path, transitions included", DPATH),
    _f("x_feed_peak_mm_s", "mm/s", "peak X feed-rate at the spindle speed", DPATH),
    _f(
        "x_accel_peak_m_s2",
        "m/s^2",
        "peak X acceleration at the spindle speed, formed over the controller's command period",
        DPATH,
    ),
    _f("accel_period_s", "s", "controller command period the D path's accelerations are formed over", DPATH),
    _f("accel_step_deg", "deg", "C step of one command period at the spindle speed", DPATH),
    _f("x_accel_cut_m_s2", "m/s^2", "peak X acceleration on the cuts", DPATH),
    _f("x_accel_transition_m_s2", "m/s^2", "peak X acceleration in the transitions", DPATH),
    _f(
        "slope_jump_um_rad",
        "um/rad",
        "largest jump of d(rho)/d(theta) at a junction of cut and transition",
        DPATH,
    ),
    Quantity(
        "feasible", "1 if the W motion fits the machine's travel, acceleration and bandwidth", "1", "int8", -1
    ),  # noqa: E501
    _text("infeasible_reason", "machine limits the W motion exceeds (empty when feasible)"),
    # layered machining of parts deeper than the travel ([3])
    _i("n_layers", "layers the part is cut in (1: one pass)", "int32", SPINDLE),
    _i(
        "layer_segments",
        "spiral segments cut over all layers (each begins with a stop and a Z move)",
        kinds=SPINDLE,
    ),  # noqa: E501
    _f(
        "layer_zone_um",
        "um",
        "height of a layer's stroke zone (travel less margin; one pass: the travel)",
        SPINDLE,
    ),  # noqa: E501
    _f("layer_stroke_um", "um", "largest W range within one layer", SPINDLE),
    _f("z_error_um", "um", "Z positioning error per retraction between layers", SPINDLE),
    _f(
        "machining_s",
        "s",
        "machining time: the path at the spindle speed (spiral: plus the stops of the layers)",
    ),
    _f("single_pass_s", "s", "machining time of one uninterrupted spiral", SPINDLE),
    Quantity(
        "layer_change_s", "time per layer segment to stop the spindle, move Z and restart", "s", kinds=SPINDLE
    ),
    Quantity("layer_change_share", "share of the machining time spent changing segments", "1", kinds=SPINDLE),
    Quantity(
        "layers", "layer schedule: offsets, start radii, strokes, lengths and times per layer", kinds=SPINDLE
    ),
    # wall times
    *(_f(f"seconds_{stage}", "s", f"wall time of {stage}") for stage in STAGES),
    _f("seconds", "s", "wall time of the case"),
)
BY_NAME = {q.name: q for q in RESULT}


def result_names(kind: str) -> list[str]:
    """Every field a result of layout ``kind`` holds (without the optional error maps)."""
    return [q.name for q in RESULT if kind in q.kinds]


PITCHES = {
    "ring": ("drho_um", "dtheta_deg"),
    "mesh": ("dx_um", "dy_um"),
    "spiral": ("dphi_deg", "ds_um"),
    "dpath": ("dphi_deg", "ds_um"),
    "fresnel": ("dphi_deg", "ds_um"),
}


def pitch_names(kind: str) -> tuple[str, str]:
    """The two pitch fields of program ``kind``: Δρ, Δθ for rings; Δx, Δy for meshes; the
    mean angular and path steps between a spiral's points."""
    return PITCHES[kind]


def stored(kind: str) -> dict[str, tuple[str, Optional[str], str, Any]]:
    """The per-case numeric variables a cube of layout ``kind`` stores:
    name → (dtype, units, long_name, fill)."""
    return {
        q.name: (q.dtype, q.units_for(kind), q.long_name, q.fill)
        for q in RESULT
        if q.dtype is not None and kind in q.kinds
    }


def in_declared_order(record: dict[str, Any]) -> dict[str, Any]:
    """``record`` with its declared fields in declared order, then any others (error maps)."""
    ordered = {q.name: record[q.name] for q in RESULT if q.name in record}
    ordered.update((k, v) for k, v in record.items() if k not in ordered)
    return ordered
