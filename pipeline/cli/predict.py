"""``ftsweep predict``: one case from command-line options, its record printed."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import click

from ftsweep.cli.common import (
    FINITE,
    POSITIVE,
    KindChoice,
    KindsHelp,
    echo_json,
    fail,
    first_compile_notice,
    progress_done,
    stderr_progress,
    threads_option,
)
from ftsweep.defaults import MAX_NODES, POINTS_PER_FEED, SAMPLES_PER_CELL
from ftsweep.options import flag

if TYPE_CHECKING:  # annotations only: the commands import what they run when they run
    from pydantic import ValidationError

    from ftsweep.engine.case import Case


class _PredictCommand(KindsHelp):
    """``predict`` with every registered kind's own options
    (:func:`ftsweep.registry.predict_option_groups`) after ``--layout``, read once per
    invocation when the command parses or shows its help, so a kind registered later, or
    installed from outside the package, adds its options without touching this module; its
    help describes each kind as the kind describes itself (:class:`KindsHelp`)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, kinds_say="predict", **kwargs)

    @staticmethod
    def _groups(ctx: click.Context) -> dict[str, list[click.Parameter]]:
        """The kinds' option groups of this invocation: built once, the same parameters for
        parsing and for help."""
        if "ftsweep.predict_groups" not in ctx.meta:
            from ftsweep import registry

            ctx.meta["ftsweep.predict_groups"] = registry.predict_option_groups()
        return ctx.meta["ftsweep.predict_groups"]  # type: ignore[no-any-return]

    def get_params(self, ctx: click.Context) -> list[click.Parameter]:
        params = super().get_params(ctx)
        at = next(i for i, p in enumerate(params) if p.name == "layout") + 1
        own = {p.name for p in params}
        kinds = [p for group in self._groups(ctx).values() for p in group if p.name not in own]
        return [*params[:at], *kinds, *params[at:]]

    def format_options(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The options in groups: those of every program first, then each kind's own."""
        groups = self._groups(ctx)
        grouped = {p.name for params in groups.values() for p in params}
        common = [p for p in self.get_params(ctx) if p.name not in grouped]
        for title, params in {"Options": common, **groups}.items():
            rows = [r for r in (p.get_help_record(ctx) for p in params) if r is not None]
            if rows:
                with formatter.section(title):
                    formatter.write_dl(rows)


@click.command(cls=_PredictCommand)
@click.option(
    "--surface",
    metavar="NAME",
    help="Surface of the catalog, as `ftsweep catalogs` lists them (required, but with --program: then "
    "only to predict its P-V).",
)
@click.option(
    "--program",
    type=click.Path(exists=True, dir_okay=False),
    help="A lathe program in any supported dialect (ISO STS or LinuxCNC G-code, PMAC PVT or SPLINE1; "
    "ftsweep's or another CAM's), read as the controller of its machine reads it (--machine, else the one "
    "its header names, else its dialect's): print its points, cuts, feed, points per revolution and "
    "spindle speed, the conventions it was read by and its axes against the machine's limits; with "
    "--surface and the tool (--cutting or --nose-radius-um) its predicted form error, as the passes it "
    "commands cut the part (docs/controllers.md).",
)
@click.option(
    "--map",
    "map_png",
    type=click.Path(dir_okay=False),
    help="With --program and --surface: also write the program's error map (peak form error over the "
    "part, nm) as a PNG.",
)
@click.option(
    "--preamble",
    type=click.Path(exists=True, dir_okay=False),
    help="With --program: a template's lines read before the program's own, so that a bare point "
    "list (C X Z blocks only, published to be pasted into a template) is read with the template's "
    "modal state (G93 and its F, G90, offsets, the position its approach left the tool at). The "
    "summary says the state the program started from; refusals name preamble lines as such.",
)
@click.option(
    "--compiled",
    is_flag=True,
    help="With --program: also read the program with the C99 reference shipped with ftsweep (built "
    "with the system's C compiler; macro-free programs, docs/controllers.md) and compare every axis of "
    "every cut with the strict reader's reading, at 10^5 points or more.",
)
@click.option(
    "--g93-f",
    type=click.Choice(["inverse_minutes", "seconds"]),
    default=None,
    help="With --program: what F means under G93 on the controller the program was written for, "
    "overriding the machine's profile (machine.controller.g93_f; docs/controllers.md).",
)
@click.option(
    "--layout",
    type=KindChoice(),
    default=None,
    help='Program kind (below, "Program kinds"). Default: the surface entry\'s layout.',
)
@click.option("--feed-um", type=FINITE, help="Feed per revolution F [µm/rev]. Default: cutting entry.")
@click.option("--nose-radius-um", type=FINITE, help="Tool nose radius Rc [µm]. Default: cutting entry.")
@click.option(
    "--compensation",
    type=click.Choice(["exact", "slope", "none"]),
    default="exact",
    show_default=True,
    help="Tool-nose compensation of the table: exact arc contact, the slope approximation, or none.",
)
@click.option(
    "--machine",
    help="Machine of the catalog (`ftsweep catalogs`). Default: the program kind's (below).",
)
@click.option(
    "--cutting",
    help="Cutting entry of the catalog (`ftsweep catalogs`). Default: the program kind's (below).",
)
@click.option(
    "--layers",
    type=click.Choice(["auto", "off"]),
    default="auto",
    show_default=True,
    help="auto: commands spanning more than the machine's travel are cut in layers, the Z axis "
    "retracting the part by one stroke zone between them ([3]); off: one pass, infeasible when "
    "the commands exceed the travel.",
)
@click.option(
    "--z-error-um",
    type=FINITE,
    help="Z positioning error per retraction between layers [µm] (positive: each falls short, "
    "so later layers cut deeper). Default: the machine entry's.",
)
@click.option(
    "--layer-change-s",
    type=FINITE,
    help="Time per layer segment to stop the spindle, move Z and restart [s] (layered machining). "
    "Default: the machine entry's layer_change_s.",
)
@click.option(
    "--samples-per-cell",
    type=int,
    default=SAMPLES_PER_CELL,
    show_default=True,
    help="Spindle angles simulated per table cell along the outer circumference.",
)
@click.option(
    "--points-per-feed",
    type=int,
    default=POINTS_PER_FEED,
    show_default=True,
    help="Evaluation points per feed along each simulated angle (even).",
)
@click.option(
    "--n-theta", type=int, help="Simulated spindle angles over 360° (overrides --samples-per-cell)."
)
@click.option(
    "--interp-error/--no-interp-error",
    default=True,
    show_default=True,
    help="Also simulate the exact commands for the interpolation-only P-V (pv_interp_nm); "
    "off saves about a fifth of the time.",
)
@click.option(
    "--strict",
    is_flag=True,
    help="Refuse an explicit Δθ that does not divide 360° instead of rounding it to the nearest that does.",
)
@click.option(
    "--max-nodes",
    type=POSITIVE,
    default=MAX_NODES,
    show_default=True,
    help="Refuse cases of more evaluation nodes than this (about 3·10⁶ nodes a second on one core).",
)
@threads_option
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object on stdout.")
def predict(**opts: Any) -> None:
    """Predict the form error one program leaves on the machined surface.

    A program of one kind (--layout, below "Program kinds"), planned from its own options, or
    --program FILE: any lathe program read as its controller reads it, summarised and (with
    --surface) predicted.

    Commands spanning more than the machine's travel are cut in layers (--layers auto, [3]):
    stroke zones of the travel less the machine's margin, one Z offset each; the JSON's
    "layers" holds the schedule (offsets, start radii, strokes, lengths, times per layer).

    \b
    Examples:
      ftsweep predict --program shop.nc --machine sts-moore --surface sinusoidal_mesh --nose-radius-um 496
    """
    if opts["program"] is not None:
        return _predict_program(opts)
    for name in ("preamble", "compiled", "g93_f"):
        if opts[name]:
            fail(f"--{name.replace('_', '-')} reads a program: it needs --program FILE")
    record = _simulate(_build_case(opts), opts)
    if opts["as_json"]:
        echo_json(record)
    else:
        click.echo(summary_text(record))


def _simulate(case: Case, opts: dict[str, Any]) -> dict[str, Any]:
    """The case's record, its progress on stderr; a machine's first run records how long its
    compile took (:func:`ftsweep.engine.compiling.recorded_first_compile`)."""
    from ftsweep.engine import compiling
    from ftsweep.engine.case import CaseError
    from ftsweep.inputs.catalogs import CatalogError
    from ftsweep.inputs.usersurfaces import SurfaceLoadError
    from ftsweep.simulate import run_case

    first_compile_notice()
    progress = stderr_progress("simulating", opts["as_json"])
    try:
        with compiling.recorded_first_compile():
            return run_case(case, progress=progress, max_nodes=opts["max_nodes"])
    except (CaseError, CatalogError, SurfaceLoadError) as exc:
        raise click.ClickException(str(exc)) from None
    finally:
        progress_done(progress)


def _predict_program(opts: dict[str, Any]) -> None:
    """``predict --program``: a program file read, summarised and (with --surface) predicted."""
    from ftsweep.engine.case import CaseError
    from ftsweep.exports import nc
    from ftsweep.inputs.catalogs import CatalogError
    from ftsweep.inputs.usersurfaces import SurfaceLoadError

    progress = stderr_progress("simulating", opts["as_json"]) if opts["surface"] else None
    try:
        info = nc.predict_program(
            opts["program"],
            opts["surface"],
            opts["machine"],
            opts["cutting"],
            opts["g93_f"],
            progress,
            map_bins=160 if opts["map_png"] else None,
            nose_radius_um=opts["nose_radius_um"],
            preamble=opts["preamble"],
            compiled=opts["compiled"],
        )
    except (nc.ProgramError, CaseError, CatalogError, SurfaceLoadError) as exc:
        raise click.ClickException(str(exc)) from None
    finally:
        if progress is not None:
            progress_done(progress)
    if opts["map_png"]:
        _save_map(info, opts["map_png"])
    if opts["as_json"]:
        echo_json({k: v for k, v in info.items() if not str(k).startswith("error_map")})
        return
    _echo_program(info)


def _echo_program(info: dict[str, Any]) -> None:
    """``predict --program``'s summary: the program as read, its motion, and its prediction."""
    feed = info["feed_um_per_rev"]
    click.echo(f"program      {info['program']} ({info['dialect']}, {info['interpolation']} segments)")
    click.echo(f"machine      {info['machine']} ({info['machine_from']})")
    click.echo(
        f"points       {info['n_points']:,} over {info['revolutions']:.4g} revolutions "
        f"({info['points_per_rev']:.4g} per revolution on average)"
        + (f" in {info['cuts']:,} cuts" if info["cuts"] > 1 else "")
    )
    ppr, rpm = info["points_per_rev_range"], info["spindle_rpm_range"]
    block, by_block = info["feed_um_per_block"], info["feed_um_per_rev_by_block"]
    click.echo(
        f"feed         {feed['min']:.4g} / {feed['median']:.4g} / {feed['max']:.4g} µm/rev over each "
        f"revolution; per block {by_block['median']:.4g} µm/rev ({block['median']:.4g} µm a block); points "
        f"per revolution {ppr['min']:.4g} / {ppr['median']:.4g} / {ppr['max']:.4g} (min / median / max)"
    )
    click.echo(
        f"spindle      {rpm['min']:.4g} / {rpm['median']:.4g} / {rpm['max']:.4g} rpm, "
        f"{info['spindle_direction']}; {info['machining_s']:.4g} s cutting"
        + (f", {info['dwell_s']:.4g} s dwelling" if info["dwell_s"] else "")
        + (f", {info['standstill_s']:.4g} s standing still" if info["standstill_s"] else "")
    )
    click.echo(f"started from {info['started_from']}")
    for line in info["conventions"]:
        click.echo(f"read as      {line}")
    click.echo(f"cuts         {info['cut_rule']}")
    passed = info["not_cut"]
    if passed:
        shown = "; ".join(f"line {p['line']}: {p['what']}" for p in passed[:6])
        more = f"; … ({len(passed)} listed in --json)" if len(passed) > 6 else ""
        click.echo(f"not cut      {shown}{more}")
    for name, a in info["axes"].items():
        unit = name.rsplit("_", 2)[-2] + "/" + name.rsplit("_", 1)[-1]
        limit = (
            "no limit declared"
            if a["limit"] is None
            else f"limit {a['limit']:g}: {'ok' if a['ok'] else 'OVER'}"
        )
        click.echo(f"{name[:7]:<12} peak {a['peak']:.4g} {unit} on machine {info['machine']} ({limit})")
    for note in info["notes"]:
        click.echo(f"note         {note}")
    if "compiled" in info:
        c = info["compiled"]
        diffs = ", ".join(f"{a} {d:.2g}" for a, (d, _) in c["compiled_axes"].items())
        click.echo(
            f"compiled     the C reference reads the same moves at {c['compiled_points']:,} points: largest "
            f"differences {diffs} µm (bound {c['compiled_bound_um']:.2g})"
        )
    if "record" in info:
        _echo_prediction(info)


def _echo_prediction(info: dict[str, Any]) -> None:
    """The predicted part of ``predict --program`` (the stand-in request's rule lines say
    nothing of the program, so they are left out)."""
    lines = summary_text(info["record"]).split("\n")
    click.echo("\n".join(x for x in lines if not x.startswith(("program ", "steps "))))
    if "judged_radii_mm" in info:
        (lo, hi), (a, b) = info["judged_radii_mm"], info["cut_radii_mm"]
        click.echo(
            f"judged       from radius {lo:.4g} to {hi:.4g} mm: the program cuts {a:.4g} to {b:.4g} mm, "
            "less its edge bands"
        )
    for name, at in info["extremes"].items():
        click.echo(
            f"{name:<12} {at['error_nm']:+.4g} nm at x = {at['x_mm']:.4g} mm, y = {at['y_mm']:.4g} mm "
            f"(r = {at['r_mm']:.4g} mm)"
        )


def _save_map(info: dict[str, Any], out: str) -> None:
    """The error map of a predicted program as a PNG (the peak form error per bin [nm])."""
    from pathlib import Path

    from ftsweep.store.io import save_figure
    from ftsweep.tools.accessor import plot_map

    if "record" not in info:
        fail("--map needs --surface: the map is the form error the program leaves on it")
    record = info["record"]
    shown = {"layout": record["layout"], "pv_nm": record["pv_nm"], "n_points": record["n_points"], **record}
    ax = plot_map(record["error_map_x_um"], record["error_map_peak_nm"], shown, "peak")
    info["map"] = str(save_figure(ax.figure, Path(out)))


def _build_case(opts: dict[str, Any]) -> Case:
    """The case of ``predict``'s options. The option combinations are checked here; every
    value is validated by the spec models, whose errors are reported by option name."""
    if opts["surface"] is None:
        fail("--surface is required (or --program FILE)")
    from pydantic import ValidationError

    from ftsweep import registry
    from ftsweep.engine.case import Case, Resolution
    from ftsweep.inputs import catalogs
    from ftsweep.inputs.catalogs import CatalogError

    surface, layout = opts["surface"], opts["layout"]
    try:
        spec = catalogs.entry("surfaces", surface)
        kind = layout or spec.layout
        machine = opts["machine"] or registry.kind(kind).machine
        cutting = opts["cutting"] or registry.kind(kind).cutting
        catalogs.entry("machines", machine)
        catalogs.entry("cutting", cutting)
    except CatalogError as exc:
        raise click.ClickException(str(exc)) from None
    try:
        request, notices = registry.request_from_options(kind, opts)
    except ValueError as exc:
        fail(str(exc))
    own = registry.kind(kind).pitches if registry.kind(kind).aspect_range is not None else ()
    try:
        # validated as part of the case, so that an error's location names the option
        case = Case(
            surface=surface,
            layout=request,  # type: ignore[arg-type]
            machine=machine,
            cutting=cutting,
            feed_um=opts["feed_um"],
            nose_radius_um=opts["nose_radius_um"],
            compensation=opts["compensation"],
            layers=opts["layers"],
            z_error_um=opts["z_error_um"],
            layer_change_s=opts["layer_change_s"],
            resolution=Resolution(
                samples_per_cell=opts["samples_per_cell"],
                points_per_feed=opts["points_per_feed"],
                n_theta=opts["n_theta"],
                interp_error=opts["interp_error"],
            ),
        )
    except ValidationError as exc:
        raise click.UsageError(_option_errors(exc, own)) from None
    for notice in notices:
        click.echo(notice, err=True)
    return case


def _option_errors(exc: ValidationError, pitch_names: tuple[str, ...]) -> str:
    """A spec model's validation errors, each named by the option that gave the value
    (``layout.pitch.0`` is the first pitch option, ``resolution.n_theta`` is --n-theta)."""
    from ftsweep import registry
    from ftsweep.inputs import catalogs

    parts = []
    for e in exc.errors():
        loc = [str(p) for p in e["loc"]]
        if loc[:1] == ["layout"] and len(loc) > 1 and loc[1] in registry.kinds():
            del loc[1]  # the request model's tag (its kind)
        if loc[:2] == ["layout", "pitch"] and len(loc) > 2:
            name = pitch_names[int(loc[2])]
        elif loc and loc[0] in ("layout", "resolution") and len(loc) > 1:
            name = loc[1]
        else:
            name = loc[-1] if loc else ""
        text = f"{catalogs.error_text(e)} (got {catalogs.short_repr(e.get('input'))})"
        parts.append(f"{flag(name)}: {text}" if name else text)
    return "; ".join(dict.fromkeys(parts))


def _causes(r: dict[str, Any]) -> list[str]:
    """The form error's causes beside the P-V (model §6): for a program read from a file its
    departure from the design-compensated tool path and the interpolation between its blocks;
    for a planned program the interpolation alone (its points are the design's)."""
    if not math.isfinite(r["pv_interp_nm"]):
        return ["interp. P-V  not simulated (--no-interp-error)"]
    interp = f"interp. P-V  {r['pv_interp_nm']:.2f} nm   "
    if "pv_departure_nm" not in r:
        return [interp + "(interpolation alone)"]
    return [
        f"departure    {r['pv_departure_nm']:.2f} nm   (the program's Z against the design-compensated "
        "tool path at its own points, model §4)",
        interp
        + "(between blocks: the design-compensated path at the program's points against the exact one)",
    ]


def summary_text(r: dict[str, Any]) -> str:
    from ftsweep import registry

    lines = [
        f"surface      {r['surface']}",
        *registry.kind(r["layout"]).describe(r),
        f"cutting      feed {r['feed_um']:g} µm/rev, nose radius {r['nose_radius_um']:g} µm, "
        f"compensation {r['compensation']}",
        f"resolution   {r['n_theta']:,} angles × {r['points_per_feed']} points/feed "
        f"({r['n_eval']:,} evaluation points)",
        "",
        f"P-V          {r['pv_nm']:.2f} nm   "
        f"(inner zone {r['pv_inner_nm']:.2f} nm, outer zone {r['pv_outer_nm']:.2f} nm)",
        f"RMS          {r['rms_nm']:.2f} nm",
        f"error range  {r['error_min_nm']:.2f} … {r['error_max_nm']:.2f} nm",
        *_causes(r),
        f"feed cusp    {r['cusp_nm']:.2f} nm   (F²/8Rc)",
    ]
    if "pv_centre_nm" in r:
        lines.append(
            f"centre       P-V {r['pv_centre_nm']:.2f} nm within {r['centre_radius_mm']:.4g} mm of the axis "
            f"(inside the innermost pass and one band beyond it), {r['pv_beyond_centre_nm']:.2f} nm beyond it"
        )
    if "w_freq_max_hz" in r:  # the W motion of a spindle program (a D path describes its own)
        verdict = "feasible" if r["feasible"] else f"INFEASIBLE: {r['infeasible_reason']}"
        content = (
            f"content up to {r['w_freq_max_hz']:.0f} Hz"
            if math.isfinite(r["w_freq_max_hz"])
            else "no spectrum (a program's own block times)"
        )
        lines.append(
            f"W motion     stroke {r['stroke_um']:.3g} µm, "
            f"peak velocity {r['w_velocity_peak_mm_s']:.3g} mm/s, "
            f"peak acceleration {r['w_accel_peak_m_s2']:.3g} m/s² (RMS {r['w_accel_rms_m_s2']:.3g}), "
            f"{content}: {verdict}"
        )
    if r.get("layers"):
        lay = r["layers"]
        starts = ", ".join(f"{v:.1f}" for v in lay["start_radius_um"])
        lines += [
            f"layers       {lay['n_layers']} zones of {lay['zone_um']:.4g} µm ({r['layer_segments']:,} "
            f"segments), stroke extended {lay['stroke_extension']:.3g}×, Z error "
            f"{lay['z_error_um']:.3g} µm per retraction",
            f"             offsets {', '.join(f'{v:.4g}' for v in lay['offset_um'])} µm; "
            f"start radii {starts} µm",
            f"machining    {r['machining_s']:.0f} s in layers ({r['layer_change_share']:.0%} of it changing "
            f"segments at {r['layer_change_s']:g} s each), {r['single_pass_s']:.0f} s for one pass",
        ]
    if r["gouge_points"]:
        lines.append(
            f"gouge        {r['gouge_points']:,} control points where the concave radius is below Rc"
        )
    lines.append(
        f"time         {r['seconds']:.2f} s wall  (stages summed over the threads that ran them: "
        f"compensation {r['seconds_compensation']:.2f}, sampling "
        f"{r['seconds_sampling']:.2f}, interpolation {r['seconds_interpolation']:.2f}, envelope "
        f"{r['seconds_envelope']:.2f}, metrics {r['seconds_metrics']:.2f})"
    )
    return "\n".join(lines)
