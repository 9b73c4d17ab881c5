"""The declared result of a case: every field a prediction reports, with its units, long name
and how cubes store it. One vocabulary everywhere: ``run_case`` returns these names (and
``predict --json`` prints them), cubes hold the stored ones under the same names with these
units, and ``select``/``describe`` read them back unchanged. Units are ones unit libraries
parse (pint, UDUNITS); ``None`` marks text and flags, which carry none (CF).

A record is the head every kind shares, its kind's own fields (``ProgramKind.fields``,
declared in the kind's package, naming the groups here it shares with other kinds: tables,
paths, spindle programs) and the tail every kind shares.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional

import numpy as np


@dataclass(frozen=True)
class Quantity:
    """One declared field of a case result.

    units : parseable units (None: text or a flag).
    dtype, fill : how a cube stores it (``dtype`` None: not stored per case in a cube).
    """

    name: str
    long_name: str
    units: Optional[str] = None
    dtype: Optional[str] = None
    fill: Any = None


def number(name: str, units: str, long_name: str) -> Quantity:
    """A float field a cube stores (NaN where a case has none)."""
    return Quantity(name, long_name, units, "float64", np.nan)


def count(name: str, long_name: str, dtype: str = "int64") -> Quantity:
    """An integer count a cube stores (−1 where a case has none)."""
    return Quantity(name, long_name, "1", dtype, -1)


def text(name: str, long_name: str) -> Quantity:
    """A text field of a record, not stored per case in a cube."""
    return Quantity(name, long_name)


def given(name: str, units: Optional[str], long_name: str) -> Quantity:
    """An input a record repeats (a sweep axis or option), not stored per case in a cube."""
    return Quantity(name, long_name, units)


STAGES = ("sampling", "compensation", "interpolation", "envelope", "metrics", "dynamics")

# what was simulated: every record begins so
HEAD: tuple[Quantity, ...] = (
    text("surface", "surface catalog entry"),
    text("layout", "program kind (a name the registry knows: ftsweep predict --help lists them)"),
    text("compensation", "tool-nose compensation of the table: exact, slope or none"),
    text("machine", "machine catalog entry"),
    given("feed_um", "um", "feed per spindle revolution"),
    given("nose_radius_um", "um", "tool nose radius"),
    given("spindle_rpm", "1/min", "spindle speed"),
    given("points_per_feed", "1", "evaluation points per feed along each angle"),
    given("edge_band_um", "um", "band at the aperture's edge outside the fully machined zone"),
    count("n_points", "number of control points of the program"),
)
# the groups of fields kinds share, which a kind names among its own (ProgramKind.fields)
TABLE: tuple[Quantity, ...] = (
    count("table_rows", "table rows (its first index: M in ρ, or nx)", "int32"),
    count("table_cols", "table columns (its second index: Np in θ, or ny)", "int32"),
)
PATH: tuple[Quantity, ...] = (
    number(
        "revolutions",
        "1",
        "revolutions of the path (from the edge to the centre where it turns about the axis)",
    ),
    number("dphi_deg", "deg", "mean spindle-angle step between points"),
    number("ds_um", "um", "mean path length between points"),
)
# programs on a path about the spindle axis: the W spectrum and layered machining ([3])
SPINDLE: tuple[Quantity, ...] = (
    number("w_freq_max_hz", "Hz", "highest significant frequency of the W command"),
    count("n_layers", "layers the part is cut in (1: one pass)", "int32"),
    count("layer_segments", "path segments cut over all layers (each begins with a stop and a Z move)"),
    number(
        "layer_zone_um", "um", "height of a layer's stroke zone (travel less margin; one pass: the travel)"
    ),
    number("layer_stroke_um", "um", "largest W range within one layer"),
    number("z_error_um", "um", "Z positioning error per retraction between layers"),
    number("single_pass_s", "s", "machining time of one uninterrupted pass"),
    Quantity("layer_change_s", "time per layer segment to stop the spindle, move Z and restart", "s"),
    Quantity("layer_change_share", "share of the machining time spent changing segments", "1"),
    Quantity("layers", "layer schedule: offsets, start radii, strokes, lengths and times per layer"),
)


def aspect_actual(units: str) -> Quantity:
    """The aspect ratio of a spindle program's realised pitches, in its kind's units."""
    long_name = "aspect ratio of the realised pitches (a path: feed over mean angular step)"
    return number("aspect_actual", units, long_name)


# every record ends so: the form error (model §6), the W motion ([2] dynamics), the machine's
# verdict, the machining time and the wall times
TAIL: tuple[Quantity, ...] = (
    number("pv_nm", "nm", "peak-to-valley form error"),
    number("rms_nm", "nm", "RMS form error about its mean"),
    number("mean_nm", "nm", "mean form error"),
    number("error_min_nm", "nm", "lowest form error"),
    number("error_max_nm", "nm", "highest form error"),
    number("pv_inner_nm", "nm", "P-V in the inner zone"),
    number("pv_outer_nm", "nm", "P-V in the outer zone"),
    number("pv_interp_nm", "nm", "P-V of the interpolation-only error"),
    number("cusp_nm", "nm", "feed cusp height of a flat surface F^2/(8 Rc)"),
    count("gouge_points", "control points whose section is concave with radius below Rc"),
    count("n_theta", "simulated spindle angles"),
    count("n_eval", "evaluation points"),
    number("stroke_um", "um", "W stroke used (range of the table)"),
    number("w_velocity_peak_mm_s", "mm/s", "peak W velocity at the spindle speed"),
    number("w_accel_peak_m_s2", "m/s^2", "peak W acceleration at the spindle speed"),
    number("w_accel_rms_m_s2", "m/s^2", "RMS W acceleration at the spindle speed"),
    Quantity(
        "feasible", "1 if the W motion fits the machine's travel, acceleration and bandwidth", "1", "int8", -1
    ),
    text("infeasible_reason", "machine limits the W motion exceeds (empty when feasible)"),
    number(
        "machining_s",
        "s",
        "machining time: the path at the spindle speed (layered: plus the stops of the layers)",
    ),
    *(
        number(f"seconds_{stage}", "s", f"time of {stage}, summed over the case's threads")
        for stage in STAGES
    ),
    number("seconds", "s", "wall time of the case"),
)
TIMING = tuple(q.name for q in TAIL if q.name.startswith("seconds"))


def declared(kind: Any) -> tuple[Quantity, ...]:
    """Every field a record of ``kind`` (a :class:`~ftsweep.engine.contract.ProgramKind`)
    holds, in order: the head, the kind's own fields, the tail."""
    return (*HEAD, *kind.fields, *TAIL)


def result_names(kind: Any) -> list[str]:
    """Every field a result of ``kind`` holds (without the optional error maps)."""
    return [q.name for q in declared(kind)]


def stored(kind: Any) -> dict[str, tuple[str, Optional[str], str, Any]]:
    """The per-case numeric variables a cube of ``kind``'s cases stores:
    name → (dtype, units, long_name, fill)."""
    return {q.name: (q.dtype, q.units, q.long_name, q.fill) for q in declared(kind) if q.dtype is not None}


def in_declared_order(record: dict[str, Any], kind: Any) -> dict[str, Any]:
    """``record`` with ``kind``'s declared fields in declared order, then any others (error maps)."""
    ordered = {q.name: record[q.name] for q in declared(kind) if q.name in record}
    ordered.update((k, v) for k, v in record.items() if k not in ordered)
    return ordered
