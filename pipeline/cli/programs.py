"""The path-program studies of the seeds: ``dpath`` (D-shaped slow-tool-servo paths, [5])
and ``fresnel`` (freeform Fresnel optics on a 4-axis lathe, [2])."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Optional

import click

from ftsweep.cli.common import (
    FINITE,
    POSITIVE,
    FiniteRange,
    echo_json,
    one_line,
    progress_done,
    sign_options,
    stderr_progress,
    threads_option,
)

if TYPE_CHECKING:  # annotations only: the commands import what they run when they run
    from ftsweep.engine.case import Case
    from ftsweep.kinds.dpath.figures import Plots
from ftsweep.kinds.dpath.options import dpath_options


@click.command("dpath")
@click.option(
    "--surface", default="concave_sphere", show_default=True, help="Surface catalog entry (the part)."
)
@click.option(
    "--machine", default="sts-xzc", show_default=True, help="Machine entry with X, Z, C axis limits."
)
@click.option(
    "--cutting", default="dpath-finish", show_default=True, help="Cutting entry (nose radius, rpm)."
)
@dpath_options
@click.option(
    "--feed-mm-min",
    type=POSITIVE,
    default=2000.0,
    show_default=True,
    help="Feed of the constant-feed XZC mode [mm/min].",
)  # noqa: E501
@click.option("--no-spiral", is_flag=True, help="Skip the spiral on the same part.")
@click.option(
    "--plots",
    "plot_dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("outputs"),
    show_default=True,
    help="Folder for the plots (dpath-<surface>-x.png, -z.png).",
)  # noqa: E501
@click.option(
    "-o",
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Export the optimised program here (t C X Z lines + FILE.json sidecar).",
)  # noqa: E501
@click.option("--force", is_flag=True, help="Replace an existing program.")
@sign_options
@threads_option
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object on stdout.")
def dpath_command(**opts: Any) -> None:
    """Plan, predict, plot and export D-shaped slow-tool-servo paths ([5]) for an off-axis part.

    Plans the traditional (arc) and the optimised (quintic) path on the part, reports their
    X range, feed and acceleration at constant spindle speed, the junctions' continuity,
    the constant-feed XZC mode (time, C speed), and the form error of each through the
    envelope; then the Archimedean spiral on the same part (centred, feed = spacing) for
    Z motion, time and P-V. With no options it runs the example of [5]: a 20 mm square
    zone 30 mm off-axis at 40 rpm, on its concave R 300 mm sphere, 10 µm spacing.

    \b
    Examples:
      ftsweep dpath
      ftsweep dpath --surface integral_mirror --json
      ftsweep dpath --spacing-um 20 -o outputs/sphere-dpath.txt --force
    """
    from ftsweep.kinds.dpath.figures import Plots

    _check_overwrite(opts["out"], opts["force"])
    try:
        drawn = Plots(opts["plot_dir"], opts["surface"])
    except OSError as exc:
        raise click.ClickException(f"--plots {opts['plot_dir']}: cannot write plots there ({exc})") from None
    # the plots' process is started first: its imports overlap the study's
    with drawn:
        summary, base = _dpath_study(opts, drawn)
        try:
            plots = [str(p) for p in drawn.paths()]
        except (OSError, RuntimeError) as exc:  # a full disk, a lost drawing process
            raise click.ClickException(f"the D-path plots: {one_line(str(exc))}") from None
    from ftsweep.kinds.dpath import study as dstudy

    result = dstudy.public(summary)
    result["plots"] = plots
    if opts["out"] is not None:
        planned = summary["_resolved"]["optimised"]
        result["program"] = _export_dpath(base, summary["optimised"], opts, planned)
    if opts["as_json"]:
        echo_json(result)
        return
    for line in dstudy.text_lines(summary):
        click.echo(line)
    click.echo(f"plots        {', '.join(plots)}")
    if opts["out"] is not None:
        click.echo(f"program      {result['program']['path']} ({result['program']['lines']:,} lines t C X Z)")


def _dpath_study(opts: dict[str, Any], plots: Plots) -> tuple[dict[str, Any], Case]:
    """``dpath``'s study (:func:`ftsweep.kinds.dpath.study.study`) of the command's options, its
    figures drawn by ``plots`` (:class:`ftsweep.kinds.dpath.figures.Plots`), and the case it started
    from; bad options and entries are the command's errors."""
    from pydantic import ValidationError

    from ftsweep.engine.case import CaseError
    from ftsweep.inputs.catalogs import CatalogError
    from ftsweep.kinds.dpath import kind as dpath_kind
    from ftsweep.kinds.dpath import study as dstudy

    options = dpath_kind.request_options(opts)
    progress = stderr_progress("dpath", opts["as_json"])
    try:
        base = dstudy.default_case(opts["surface"], opts["machine"], opts["cutting"], options)
        summary = dstudy.study(base, opts["feed_mm_min"], not opts["no_spiral"], progress, plots=plots)
    except (CaseError, CatalogError, ValidationError, ValueError) as exc:
        raise click.ClickException(one_line(str(exc))) from None
    finally:
        progress_done(progress)
    return summary, base


def _check_overwrite(out: Optional[Path], force: bool) -> None:
    """Refuse, before any work, to replace an existing program or its sidecar without --force."""
    from ftsweep.store.io import ExportError, check_overwrite, sidecar_path

    if out is not None:
        try:
            check_overwrite((out, sidecar_path(out)), force)
        except ExportError as exc:
            raise click.ClickException(str(exc)) from None


def _export_dpath(base: Case, record: dict[str, Any], opts: dict[str, Any], planned: Any) -> dict[str, Any]:
    """Export the optimised program of ``dpath`` to ``opts["out"]`` (refusing to replace files
    without --force; signed with --sign-key), as the study planned it (``planned``, from the
    same entries)."""
    from ftsweep.engine.case import CaseError
    from ftsweep.engine.planning import resolve_specs
    from ftsweep.exports.export import signed
    from ftsweep.exports.fingerprint import fingerprint
    from ftsweep.exports.origin import signature_path, signing_key
    from ftsweep.kinds import path_programs as program
    from ftsweep.kinds.dpath import study as dstudy
    from ftsweep.store.io import ExportError, check_overwrite, sidecar_path

    out = opts["out"]
    side = sidecar_path(out)
    try:
        check_overwrite((out, side, signature_path(out)), opts["force"])
        case = dstudy.d_case(base, "optimised")
        here = {"platform": fingerprint()}  # verify finds every number exactly as re-planned here
        meta = program.export_dpath(out, side, case, resolve_specs(case), record, here, planned)
        signed(out, signing_key(opts["sign_key"]), meta, opts["expires"])
    except (ExportError, CaseError) as exc:
        raise click.ClickException(str(exc)) from None
    return {"path": str(out), "sidecar": str(side), "lines": meta["n_points"]}


@click.command("fresnel")
@click.option("--surface", default="chebyshev_example", show_default=True, help="Surface catalog entry.")
@click.option(
    "--facet-height-um",
    type=POSITIVE,
    default=10.0,
    show_default=True,
    help="Height h of every Fresnel facet [µm] ([2] eq. 3).",
)
@click.option(
    "--machine", default="xyzc-nanoform", show_default=True, help="Machine entry with X, Y, Z, C limits."
)
@click.option(
    "--cutting",
    default="fresnel-finish",
    show_default=True,
    help="Cutting entry: nose radius, feed Δr per turn, rpm (sets T0).",
)
@click.option(
    "--points-per-turn", type=click.IntRange(min=8), help="Control points K per edge. Default: 360."
)
@click.option("--deviation-deg", type=FINITE, help="Rake-face deviation Δφ [deg] ([2] eq. 9). Default: 0.")
@click.option(
    "--compensation",
    type=click.Choice(["exact", "straight", "none"]),
    help="Tool-edge compensation: eq. 10 (exact), eq. 12 (straight) or none. Default: exact.",
)
@click.option(
    "--control",
    "scheme",
    type=click.Choice(["auto", "polar", "arc"]),
    help="Control points: polar about centroids (eqs. 5-6), arc length (appendix A.3), auto. Default: auto.",
)
@click.option(
    "--safety", type=FiniteRange(min=1.0), help="Safety factor K_s on every axis limit. Default: 1.25."
)
@click.option(
    "--plots",
    "plot_dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("outputs"),
    show_default=True,
    help="Folder for the plots (fresnel-<surface>-path.png, -axes.png, -timesteps.png).",
)
@click.option(
    "-o",
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Export the program (t C X Y Z lines).",
)
@click.option("--force", is_flag=True, help="Replace an existing program.")
@sign_options
@threads_option
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object on stdout.")
def fresnel_command(**opts: Any) -> None:
    """Plan a freeform Fresnel program for an X-Y-Z-C lathe ([2]) and time it adaptively.

    Slices the surface along its contour lines into facets of the given height, plans the
    quasi-spiral path along the facets' edges (feed Δr per turn from the cutting entry),
    the 4-axis trajectory that keeps the rake face on the cutting direction, the tool-edge
    compensation (eq. 10 and eq. 12, both reported), and the timesteps: per turn optimised
    (scipy L-BFGS-B) to level the axes' relative accelerations, then scaled by K_s; the
    machining time is compared with one constant timestep at the global acceleration limit.
    Progress on stderr; plots in --plots; with -o the program and a JSON sidecar
    (check it with `ftsweep verify FILE`).

    \b
    Examples:
      ftsweep fresnel
      ftsweep fresnel --surface chebyshev_example --facet-height-um 10 --json
      ftsweep fresnel -o outputs/fresnel.txt --force
    """
    from pydantic import ValidationError

    from ftsweep.exports.export import signed
    from ftsweep.exports.files import ExportError, sidecar_path
    from ftsweep.exports.origin import signing_key
    from ftsweep.inputs.catalogs import CatalogError
    from ftsweep.kinds.fresnel import study as fstudy

    keys = ("facet_height_um", "points_per_turn", "deviation_deg", "compensation", "scheme", "safety")
    inp = fstudy.inputs(opts["surface"], opts["machine"], opts["cutting"], **{k: opts[k] for k in keys})
    out = opts["out"]
    _check_overwrite(out, opts["force"])
    progress = stderr_progress("timesteps (turns)", opts["as_json"])
    try:
        summary = fstudy.study(inp, progress=progress)
        progress_done(progress)
        plots = [str(p) for p in fstudy.plot(summary, opts["plot_dir"])]
        if out is not None:
            meta = fstudy.export(summary, out, sidecar_path(out), inp)
            signed(out, signing_key(opts["sign_key"]), meta, opts["expires"])
    except (CatalogError, ExportError, ValidationError, ValueError) as exc:
        raise click.ClickException(one_line(str(exc))) from None
    finally:
        progress_done(progress)
    result = fstudy.public(summary)
    result["plots"] = plots
    if out is not None:
        result["program"] = {"path": str(out), "sidecar": str(sidecar_path(out)), "lines": result["n_points"]}
    _print_fresnel(result, fstudy.text_lines(summary), opts["as_json"])


def _print_fresnel(result: dict[str, Any], lines: list[str], as_json: bool) -> None:
    if as_json:
        echo_json(result)
        return
    for line in lines:
        click.echo(line)
    click.echo(f"plots        {', '.join(result['plots'])}")
    if "program" in result:
        click.echo(f"program      {result['program']['path']} ({result['n_points']:,} lines t C X Y Z)")
