"""The ``ftsweep fresnel`` study ([2]): plan a Fresnel program for a catalog surface, choose
its timesteps, summarise it (facets, turns, compensation, machining time with constant and
its own timesteps, a lower bound on the least time), plot it ([2] figs. 10, 12, 13) and
export it as position-time lines ``t [s]  C [deg]  X [mm]  Y [mm]  Z [mm]`` with a JSON
sidecar, verified on re-reading.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple, Optional

import numpy as np

from ftsweep.engine.case import Case, CaseError
from ftsweep.exports.fingerprint import fingerprint
from ftsweep.inputs import catalogs
from ftsweep.inputs.case_entries import Entries
from ftsweep.inputs.yamlfiles import CatalogError
from ftsweep.kinds.fresnel import program as fp
from ftsweep.kinds.fresnel.request import FresnelRequest
from ftsweep.simulate import resolve_case
from ftsweep.stages.kinematics import certificate as bounds
from ftsweep.stages.kinematics.axes import Limits
from ftsweep.stages.paths import fresnel as ff
from ftsweep.store.io import sidecar_of
from ftsweep.version import __version__

if TYPE_CHECKING:
    from ftsweep.exports.files import DataLines

F_MAGIC = "# ftsweep Fresnel program"
F_COLUMNS = "t_s C_deg X_mm Y_mm Z_mm"


class Inputs(NamedTuple):
    """What a Fresnel program is made from: catalog entries by name and the options."""

    surface: str
    machine: str
    cutting: str
    facet_height_um: float
    points_per_turn: int
    deviation_deg: float
    compensation: str
    scheme: str
    safety: float
    # a sidecar written before the timing was an input recorded a program timed by [2]'s eqs.
    timing: str = "paper"


def inputs(surface: str, machine: str, cutting: str, **options: Any) -> Inputs:
    """Inputs with the options not given (None) at their defaults (:data:`fresnel.DEFAULTS`)."""
    merged = {k: (fp.DEFAULTS[k] if options.get(k) is None else options[k]) for k in fp.DEFAULTS}
    return Inputs(surface, machine, cutting, **merged)


def _entries(inp: Inputs, folder: Optional[Path] = None) -> Entries:
    return Entries(
        catalogs.entry("surfaces", inp.surface, folder),
        catalogs.entry("machines", inp.machine, folder),
        catalogs.entry("cutting", inp.cutting, folder),
    )


# a study's compensation names [2]'s; a case's are the model's (kinds.fresnel.COMPENSATION)
CASE_COMPENSATION = {"exact": "exact", "straight": "slope", "none": "none"}


def case_of(inp: Inputs) -> Case:
    """The case of a study's inputs: the Fresnel kind's request with the study's options, the
    feed and nose radius of its cutting entry."""
    request = FresnelRequest(
        kind="fresnel",
        facet_height_um=inp.facet_height_um,
        points_per_turn=inp.points_per_turn,
        deviation_deg=inp.deviation_deg,
        safety=inp.safety,
        control_points=inp.scheme,
        timing=inp.timing,
    )
    return Case(
        surface=inp.surface,
        layout=request,
        machine=inp.machine,
        cutting=inp.cutting,
        compensation=CASE_COMPENSATION.get(inp.compensation, inp.compensation),  # else named by Case
    )


def study(
    inp: Inputs,
    folder: Optional[Path] = None,
    progress: Optional[Callable[[int, int], None]] = None,
    specs: Optional[Entries] = None,
) -> dict[str, Any]:
    """Plan, time and summarise a Fresnel program through its kind (the case of ``inp``,
    :func:`case_of`); ``_plan`` and ``_steps`` hold the arrays. ``specs`` (surface, machine,
    cutting) replace the catalog look-up of ``inp``'s names (verify re-plans from the entries
    a sidecar recorded)."""
    specs = specs or _entries(inp, folder)
    limits = fp.limits_of(specs.machine, inp.machine)
    try:
        rcase = resolve_case(case_of(inp), folder, specs, progress=progress)
    except CaseError as exc:
        raise ff.FresnelError(str(exc).removeprefix("Fresnel program: ")) from None
    fplan, steps = rcase.layout.plan, rcase.layout.steps
    out = summary(inp, fplan, steps, limits, catalogs.aperture_of(specs.surface))
    out.update(_plan=fplan, _steps=steps, _specs=specs)
    return out


def feed_per_turn(fplan: fp.FresnelPlan) -> float:
    """Largest distance [µm] between a path point and the same point one turn later ([2] eq. 8
    moves each by 1/M_n of its edge-to-edge step; eq. 7 keeps that within Δr)."""
    k = fplan.path.points_per_turn
    xy = fplan.path.xy[:-1]
    return float(np.max(np.hypot(*(xy[k:] - xy[:-k]).T)))


def summary(
    inp: Inputs, fplan: fp.FresnelPlan, steps: fp.Timesteps, limits: Limits, aperture: Any
) -> dict[str, Any]:
    """The figures of one program (JSON-ready); units in the key names; the compensations over
    the points on the part (inside ``aperture``)."""
    path = fplan.path
    q = fplan.axes_si()
    acc, vel = fp.relative_peaks(q, steps.steps, limits)
    n_steps = q.shape[0] - 1
    time_constant = steps.constant * n_steps
    time_adaptive = float(steps.steps.sum())
    start = time.perf_counter()
    low = fp.certificate(q, limits, inp.safety, steps.constant)
    bound_s = time.perf_counter() - start
    return {
        "surface": inp.surface,
        "machine": inp.machine,
        "cutting": inp.cutting,
        "facet_height_um": inp.facet_height_um,
        "feed_um": fplan.feed_um,
        "nose_radius_um": fplan.nose_radius_um,
        "points_per_turn": path.points_per_turn,
        "deviation_deg": inp.deviation_deg,
        "compensation": inp.compensation,
        "control_points": path.scheme,
        "safety": inp.safety,
        "lowest_point_um": [float(v) for v in fplan.apex_um],
        "height_range_um": fplan.max_um - fplan.f_ref_um,
        "n_facets": path.n_facets,
        "turns_per_facet": [int(m) for m in path.turns],
        "turns_eq7": [float(m) for m in path.turns_eq7],
        "n_turns": path.n_turns,
        "n_points": int(q.shape[0]),
        "feed_per_turn_max_um": feed_per_turn(fplan),
        "slope_max": float(fplan.slope.max()),
        **fp.ez_on_part(fplan, aperture),
        "x_range_mm": [float(fplan.x_um.min() * 1e-3), float(fplan.x_um.max() * 1e-3)],
        "y_range_mm": [float(fplan.y_um.min() * 1e-3), float(fplan.y_um.max() * 1e-3)],
        "reference_step_s": steps.reference,
        "constant_step_s": steps.constant,
        "adaptive_step_min_s": float(steps.steps.min()),
        "adaptive_step_max_s": float(steps.steps.max()),
        "timing": steps.timing,
        "time_constant_s": time_constant,
        "time_adaptive_s": time_adaptive,
        "speedup": time_constant / time_adaptive,
        **certificate_fields(path, steps.steps, low),
        **_paper_fields(steps),
        "relative_accel_max": dict(zip(fp.AXES, (float(v) for v in acc.max(axis=0)), strict=True)),
        "relative_velocity_max": dict(zip(fp.AXES, (float(v) for v in vel.max(axis=0)), strict=True)),
        "limiting_axis_counts": _limiting_axes(acc, path.points_per_turn),
        "within_limits": not fp.limits_reason(q, steps.steps, limits),
        "speedup_account": speedup_account(fplan, steps, limits, inp.safety),
        "planning_s": fplan.planning_s,
        "timesteps_s": steps.seconds,
        "bound_s": bound_s,
        "_bound": low,
    }


def certificate_fields(path: Any, steps: np.ndarray, low: Any) -> dict[str, Any]:
    """The program's time against a lower bound on the time of every program through its
    points within the same limits (``low``, :func:`ftsweep.kinds.fresnel.program.certificate`),
    in all and per facet: times [s], gaps in % of the bound."""
    facet = path.facet[: steps.size]
    starts = np.flatnonzero(np.diff(facet)) + 1
    per_time = np.add.reduceat(steps, np.r_[0, starts])
    per_bound = bounds.block_bounds(low, np.r_[0, starts])
    total = float(steps.sum())
    return {
        "time_bound_s": low.total_s,
        "optimality_gap_pct": 100.0 * (total / low.total_s - 1.0),
        "facet_time_s": [float(v) for v in per_time],
        "facet_bound_s": [float(v) for v in per_bound],
        "facet_gap_pct": [float(100.0 * (a / b - 1.0)) for a, b in zip(per_time, per_bound, strict=True)],
    }


def _paper_fields(steps: fp.Timesteps) -> dict[str, Any]:
    """How much [2]'s eq. 15 cut every turn's peak acceleration (``paper`` timing only)."""
    if steps.peak_optimised is None or steps.peak_constant is None:
        return {}
    reduction = 1.0 - steps.peak_optimised / steps.peak_constant
    return {
        "turn_peak_reduction_first": float(reduction[0]),
        "turn_peak_reduction_median": float(np.median(reduction)),
        "turn_peak_reduction_min": float(reduction.min()),
    }


def speedup_account(
    fplan: fp.FresnelPlan, steps: fp.Timesteps, limits: Limits, safety: float
) -> dict[str, Any]:
    """Where the speed-up of adaptive over constant timesteps comes from ([2] §2.5; README,
    "Fresnel"), the accelerations' bounds alone:

    ``turnwise_constant``: every turn at its own constant timestep, scaled by eq. 16 (the
    motion's range shrinking turn by turn); ``turnwise_optimised``: every turn at its eq. 15
    steps scaled by eq. 16, the steps between turns left free (what the per-turn method can
    reach; ``speedup`` is below it by what joining the turns costs); ``reference``: the axis,
    turn and point whose acceleration sets the constant timestep, and whether that turn enters
    a facet; ``plunging``: the constant timestep [s] if every facet were entered by a step of h
    between two points instead of the ramp (:func:`ftsweep.stages.paths.fresnel.entry_offset`), and
    the speed-up against it."""
    k, t0 = fplan.path.points_per_turn, steps.reference
    n_steps = fplan.path.xy.shape[0] - 1
    time_constant = steps.constant * n_steps
    q = fplan.axes_si()
    acc = fp.relative_peaks(q, np.ones(n_steps), limits)[0]
    point, axis = divmod(int(np.argmax(acc)), acc.shape[1])
    turn = min(point // k, fplan.path.n_turns - 1)
    plunged = q.copy()
    plunged[:, 3] -= ff.entry_offset(fplan.path.facet, k, fplan.facet_height_um) * 1e-6
    step_plunging = fp.constant_step(plunged, limits, safety)

    def turnwise(peaks: np.ndarray) -> float:
        return float(time_constant / float(np.sum(k * np.sqrt(safety * peaks) * t0)))

    paper = {}
    if steps.peak_constant is not None and steps.peak_optimised is not None:
        paper = {
            "turnwise_constant": turnwise(steps.peak_constant),
            "turnwise_optimised": turnwise(steps.peak_optimised),
        }
    return {
        **paper,
        "reference": {
            "axis": fp.AXES[axis],
            "turn": turn,
            "point": point,
            "enters_facet": fplan.path.enters_facet(turn),
        },
        "plunging": {
            "constant_step_s": step_plunging,
            "speedup": step_plunging * n_steps / float(steps.steps.sum()),
        },
    }


def _limiting_axes(acc: np.ndarray, k: int) -> dict[str, int]:
    """How many turns each axis sets the largest relative acceleration of."""
    turns = (acc.shape[0] - 1) // k
    which = acc[: turns * k].reshape(turns, k, acc.shape[1]).max(axis=1).argmax(axis=1)
    return {axis: int(np.sum(which == i)) for i, axis in enumerate(fp.AXES)}


def public(s: dict[str, Any]) -> dict[str, Any]:
    """The summary without its arrays."""
    return {k: v for k, v in s.items() if not k.startswith("_")}


def _hms(seconds: float) -> str:
    h, rest = divmod(int(round(seconds)), 3600)
    return f"{h} h {rest // 60:02d} min {rest % 60:02d} s"


def text_lines(s: dict[str, Any]) -> list[str]:
    """The summary as aligned text lines."""
    acc = ", ".join(f"{a} {v:.3f}" for a, v in s["relative_accel_max"].items())
    return [
        f"surface      {s['surface']}: height range {s['height_range_um']:.3f} µm, lowest point "
        f"({s['lowest_point_um'][0]:.1f}, {s['lowest_point_um'][1]:.1f}) µm",
        f"facets       {s['n_facets']} of {s['facet_height_um']:g} µm; turns per facet "
        f"{s['turns_per_facet']} (eq. 7 estimates {[round(m) for m in s['turns_eq7']]})",
        f"path         {s['n_turns']:,} turns, {s['n_points']:,} points ({s['points_per_turn']} per turn, "
        f"{s['control_points']} control points); feed per turn ≤ {s['feed_per_turn_max_um']:.4f} µm "
        f"(Δr {s['feed_um']:g} µm)",
        f"tool         nose radius {s['nose_radius_um']:g} µm; e_z max {s['ez_exact_max_nm']:.2f} nm "
        "(eq. 10), "
        f"{s['ez_straight_max_nm']:.2f} nm (eq. 12); largest difference {s['ez_difference_max_nm']:.3f} nm",
        f"axes         X {s['x_range_mm'][0]:.3f} to {s['x_range_mm'][1]:.3f} mm, "
        f"Y {s['y_range_mm'][0]:.3f} to {s['y_range_mm'][1]:.3f} mm",
        f"accel        peak |a|/a_lim after K_s = {s['safety']:g}: {acc}",
        *_paper_text(s),
        f"time         constant {s['constant_step_s'] * 1e3:.4f} ms steps: {_hms(s['time_constant_s'])}; "
        f"{s['timing']} timesteps: {_hms(s['time_adaptive_s'])} ({s['time_adaptive_s']:.2f} s, "
        f"{s['speedup']:.2f}× faster)",
        _bound_text(s),
        _account_text(s["speedup_account"]),
        f"limits       {'every axis within its limits on every step' if s['within_limits'] else 'EXCEEDED'}",
        f"compute      planning {s['planning_s']:.1f} s, timesteps {s['timesteps_s']:.1f} s, "
        f"bound {s['bound_s']:.1f} s",
    ]


def _paper_text(s: dict[str, Any]) -> list[str]:
    if "turn_peak_reduction_median" not in s:
        return []
    return [
        f"timesteps    per-turn peak acceleration cut by {100 * s['turn_peak_reduction_median']:.1f} % "
        f"(median; first turn {100 * s['turn_peak_reduction_first']:.1f} %, least "
        f"{100 * s['turn_peak_reduction_min']:.1f} %)"
    ]


def _bound_text(s: dict[str, Any]) -> str:
    """The certificate (:func:`certificate_fields`) as one line: every facet's gap up to
    eight facets, else the median and the largest."""
    gaps = s["facet_gap_pct"]
    worst = int(np.argmax(gaps))
    facets = (
        "per facet " + ", ".join(f"{g:.2f}" for g in gaps) + " %"
        if len(gaps) <= 8
        else f"per facet median {float(np.median(gaps)):.2f} %, at most {gaps[worst]:.2f} % (facet {worst})"
    )
    return (
        f"bound        no program within the same limits is faster than {s['time_bound_s']:.2f} s: this "
        f"one is {s['optimality_gap_pct']:.2f} % above; {facets}"
    )


def _account_text(a: dict[str, Any]) -> str:
    """The speed-up's account (:func:`speedup_account`) as one line."""
    ref = a["reference"]
    where = "a facet's first turn" if ref["enters_facet"] else f"turn {ref['turn']:,}"
    turnwise = (
        f"turn by turn at constant steps {a['turnwise_constant']:.2f}×, at eq. 15's steps "
        f"{a['turnwise_optimised']:.2f}×; "
        if "turnwise_constant" in a
        else ""
    )
    return (
        f"speed-up     {turnwise}the constant step is set by {ref['axis']} on {where}; "
        f"with facets entered by a plunge {a['plunging']['speedup']:.2f}×"
    )


# --------------------------------------------------------------------------- export
# wall times of the study: facts about a run, not about the program (left out of the sidecar)
WALL_TIMES = ("planning_s", "timesteps_s", "bound_s")


def document(
    s: dict[str, Any], inp: Inputs, created: str, generator: str, platform: Any = None
) -> tuple[list[str], DataLines, dict[str, Any]]:
    """The header lines, data lines and sidecar content of a studied Fresnel program: export
    writes them and verify re-derives them from the recorded inputs and entries (``platform``:
    where it was planned, :func:`ftsweep.exports.fingerprint.fingerprint`)."""
    from ftsweep.exports.files import recorded_entries

    fplan, steps, specs = s["_plan"], s["_steps"], s["_specs"]
    lines = _lines(fplan, steps)
    meta = {
        "generator": generator,
        "created": created,
        "layout": "fresnel",
        "inputs": inp._asdict(),
        "summary": {k: v for k, v in public(s).items() if k not in WALL_TIMES},
        "catalog_entries": recorded_entries(specs),
        **({"platform": platform} if platform is not None else {}),
    }
    head = [
        f"{F_MAGIC} (C, X, Y, Z move linearly in time between consecutive lines)",
        f"# generator: {generator}",
        f"# surface: {inp.surface}, Fresnel facets of {inp.facet_height_um:g} um ({s['n_facets']}); "
        f"machine: {inp.machine}",
        f"# path: quasi-spiral, {s['n_turns']} turns of {s['points_per_turn']} points, "
        f"feed {s['feed_um']:g} um per turn; rake face {inp.deviation_deg:g} deg from the cutting direction",
        f"# tool: nose radius {s['nose_radius_um']:g} um; compensation {inp.compensation} "
        f"(e_z max {s['ez_exact_max_nm']:.3f} nm)",
        *timing_lines(s, inp.safety),
        f"# points: {len(lines)}",
        "# units: t [s] from the first line, C [deg] accumulated, X Y [mm] tool, Z [mm] tool tip",
    ]
    return head, lines, meta


# the discretisation every timing holds the limits in (the kinematics stage, [2] eq. 14)
LIMITS_LINE = (
    "# limits: every axis within 1/K_s of its velocity limit on every step, (q[i+1]-q[i])/T[i], and of "
    "its acceleration limit at every point, 2*(v[i]-v[i-1])/(T[i-1]+T[i])"
)


def timing_lines(s: dict[str, Any], safety: float) -> list[str]:
    """The header's timing lines: the timing, its time, the constant one and the bound, and the
    discretisation the limits hold in (the kinematics stage, [2] eq. 14)."""
    if s["timing"] == "paper":  # as programs were headed before the timing was an input
        return [
            f"# timing: adaptive timesteps, {s['time_adaptive_s']:.3f} s in all (constant timesteps: "
            f"{s['time_constant_s']:.3f} s); safety factor K_s {safety:g}"
        ]
    return [
        f"# timing: {s['timing']} timesteps, {s['time_adaptive_s']:.3f} s in all (constant timesteps: "
        f"{s['time_constant_s']:.3f} s; no program through these points within 1/K_s of the limits "
        f"takes less than {s['time_bound_s']:.3f} s); safety factor K_s {safety:g}",
        LIMITS_LINE,
    ]


def export(s: dict[str, Any], out: Path, side: Path, inp: Inputs) -> dict[str, Any]:
    """Write the study's program as ``t C X Y Z`` lines with its sidecar, atomically;
    refused (nothing written) if any line leaves the machine's limits."""
    from ftsweep.exports import files

    created = files.now()
    head, lines, meta = document(s, inp, created, f"ftsweep {__version__}", fingerprint())
    data = lines.printed  # as the machine reads the lines
    reason = lines_reason(data, fp.limits_of(s["_specs"][1], inp.machine))
    if reason:
        raise files.ProgramError(f"the program leaves the limits of machine '{inp.machine}': {reason}")
    return files.write_program(out, side, head, F_COLUMNS, lines, meta)


def lines_reason(data: np.ndarray, limits: Limits) -> str:
    """The limit lines (t [s], C [deg], X, Y, Z [mm]) exceed, checked on every line, or ''."""
    q = np.column_stack([np.radians(data[:, 1]), data[:, 2:] * 1e-3])
    # printed digits (1 ns, 1 pm) move accelerations by far less than this slack
    return fp.limits_reason(q, np.diff(data[:, 0]), limits, slack=1e-6)


def recorded_inputs(meta: dict[str, Any], side: Path) -> Inputs:
    """The :class:`Inputs` a sidecar recorded, refused with the sidecar named if malformed."""
    from ftsweep.exports.files import ProgramError

    try:
        raw = dict(meta["inputs"])
        inp = Inputs(**raw)
    except (KeyError, TypeError, ValueError) as exc:
        raise ProgramError(f"{side}: the recorded inputs cannot be read ({str(exc)[:200]})") from None
    return inp


def verify(
    path: Path,
    trust_plugins: bool = False,
    progress: Optional[Callable[[int, int], None]] = None,
    pv_tolerance_nm: Optional[float] = None,
) -> dict[str, Any]:
    """Re-read a Fresnel program: CRC (every line) and sidecar, every line within the
    recorded machine's limits (positions, velocities, accelerations by eq. 14), and the
    program planned and timed again from the recorded inputs and entries: every header line
    equal, every line's t, C, X, Y, Z within ``files.LINE_TOLERANCE``, the sidecar's
    summary equal. Raises ``ProgramError`` naming what differs."""
    from ftsweep.exports import files
    from ftsweep.inputs import trust

    doc = files.read_program_file(path, F_MAGIC, F_COLUMNS)
    meta = files.checked_sidecar(path, doc)
    if "case" in meta:  # exported from a cube case
        return verify_case(path, doc, meta, trust_plugins, progress, pv_tolerance_nm)
    side = sidecar_of(path)
    inp = recorded_inputs(meta, side)
    try:
        entries = meta["catalog_entries"]
        specs = trust.specs_from_entries(
            entries["surface"], entries["machine"], entries["cutting"], trust_plugins=trust_plugins
        )
    except CatalogError as exc:
        raise files.ProgramError(f"{side}: {exc}") from None
    except (KeyError, TypeError, ValueError) as exc:
        raise files.ProgramError(f"{side}: the recorded entries cannot be read ({str(exc)[:200]})") from None
    reason = lines_reason(doc.data, fp.limits_of(specs.machine, inp.machine))
    if reason:
        raise files.ProgramError(f"{path}: a line leaves the machine's limits: {reason}; do not run it")
    s = study(inp, progress=progress, specs=specs)
    planned = document(s, inp, str(meta["created"]), str(meta["generator"]), meta.get("platform"))
    files.check_document(path, doc, planned, meta, F_COLUMNS)
    data = doc.data
    return {
        "layout": "fresnel",
        "program": str(path),
        "lines": int(data.shape[0]),
        "n_points": int(data.shape[0]),
        "machining_s": float(data[-1, 0]),
        "checksum": doc.crc,
        "within_limits": True,
    }


# --------------------------------------------------------------------------- cube cases
def case_document(
    case: Any,
    specs: Entries,
    chosen: dict[str, Any],
    extra: dict[str, Any],
    created: str,
    generator: str,
    rcase: Any = None,
) -> tuple[list[str], DataLines, dict[str, Any]]:
    """The header lines, data lines and sidecar content of a Fresnel case of a cube, planned
    and timed from its spec and entries (or ``rcase``, resolved already): export writes them,
    verify re-derives them. The sidecar records the case (the kind's request) as for every
    path program."""
    from ftsweep.exports.files import case_meta
    from ftsweep.kinds.fresnel.form import record_fields

    rcase = rcase if rcase is not None else resolve_case(case, specs=specs)
    prog = rcase.layout
    fplan, steps = prog.plan, prog.steps
    lines = _lines(fplan, steps)
    fields = record_fields(rcase)
    own = {"machining_s": fields["machining_s"]}
    meta = case_meta("fresnel", case, specs, chosen, extra, (created, generator), prog.n_points, own)
    head = [
        f"{F_MAGIC} (C, X, Y, Z move linearly in time between consecutive lines)",
        f"# generator: {generator}",
        f"# surface: {case.surface}, Fresnel facets of {fplan.facet_height_um:g} um ({fplan.path.n_facets}); "
        f"machine: {case.machine}",
        f"# path: quasi-spiral, {fplan.path.n_turns} turns of {fplan.path.points_per_turn} points, feed "
        f"{fplan.feed_um:g} um per turn; rake face {fields['deviation_deg']:g} deg from the cutting "
        "direction",
        f"# tool: nose radius {fplan.nose_radius_um:g} um; compensation {fplan.compensation}",
        f"# timing: {steps.timing} timesteps, {fields['machining_s']:.3f} s in all",
        LIMITS_LINE,
        f"# predicted P-V: {chosen['pv_nm']:.6f} nm",
        f"# points: {len(lines)}",
        "# units: t [s] from the first line, C [deg] accumulated, X Y [mm] tool, Z [mm] tool tip",
    ]
    return head, lines, meta


def _lines(fplan: fp.FresnelPlan, steps: fp.Timesteps) -> DataLines:
    """The program's ``t C X Y Z`` lines (:class:`ftsweep.exports.files.DataLines`)."""
    from ftsweep.exports.files import DataLines

    t = np.concatenate([[0.0], np.cumsum(steps.steps)])
    xyz = (fplan.x_um * 1e-3, fplan.y_um * 1e-3, fplan.tool_z_um * 1e-3)
    return DataLines.of(t, np.degrees(fplan.phi), *xyz)


def export_case(
    out: Path,
    side: Path,
    case: Any,
    specs: Entries,
    chosen: dict[str, Any],
    extra: dict[str, Any],
) -> dict[str, Any]:
    """Plan and time the chosen Fresnel case of a cube again ([2]) and write it as ``t C X Y Z``
    lines with its sidecar, atomically; refused if any line leaves the machine's limits."""
    from ftsweep.exports import files

    head, lines, meta = case_document(case, specs, chosen, extra, files.now(), f"ftsweep {__version__}")
    data = lines.printed  # as the machine reads the lines
    reason = lines_reason(data, fp.limits_of(specs.machine, case.machine))
    if reason:
        raise files.ProgramError(f"the program leaves the limits of machine '{case.machine}': {reason}")
    return files.write_program(out, side, head, F_COLUMNS, lines, meta)


def verify_case(
    path: Path, doc: Any, meta: dict[str, Any], trust_plugins: bool, progress: Any, pv_tolerance_nm: Any
) -> dict[str, Any]:
    """Check a Fresnel program exported from a cube case: every line within the machine's
    limits, every header and data line as its recorded case plans and times it again, and the
    part re-simulated from the lines' own C, X, Y and Z (eq. 9 back to the part's frame)."""
    from ftsweep.exports import files
    from ftsweep.simulate import resolve_case, run_case

    case, specs = files.recorded_case_of(meta, sidecar_of(path), trust_plugins)
    reason = lines_reason(doc.data, fp.limits_of(specs.machine, case.machine))
    if reason:
        raise files.ProgramError(f"{path}: a line leaves the machine's limits: {reason}; do not run it")
    rcase = resolve_case(case, specs=specs)
    planned = case_document(
        case, specs, meta["selection"], files.recorded_extra(meta), meta["created"], meta["generator"], rcase
    )
    files.check_document(path, doc, planned, meta, F_COLUMNS)
    data = doc.data
    phi = np.radians(data[:, 1])
    given = rcase.layout._replace(xy=ff.workpiece_of(phi, data[:, 2] * 1e3, data[:, 3] * 1e3))
    record = run_case(case, specs=specs, progress=progress, program=(given, data[:, 4] * 1e3))
    return files.checked_pv(path, meta, record, pv_tolerance_nm)
