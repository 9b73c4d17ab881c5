"""``ftsweep dpath``: the D-path study of the seed ([5]), a command the D-path kind adds
(:meth:`ftsweep.kinds.dpath.DPathKind.commands`): both transitions of the optimised program and
the spiral beside it on the same part, its plots, and its export with ``-o``."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from ftsweep.options import (
    POSITIVE,
    echo_json,
    one_line,
    progress_done,
    refuse_overwrite,
    sign_options,
    stderr_progress,
    threads_option,
)

if TYPE_CHECKING:  # annotations only: the command imports what it runs when it runs
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

    refuse_overwrite(opts["out"], opts["force"])
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
    from ftsweep.inputs.yamlfiles import CatalogError
    from ftsweep.kinds.dpath import study as dstudy
    from ftsweep.kinds.dpath.names import request_options

    options = request_options(opts)
    progress = stderr_progress("dpath", opts["as_json"])
    try:
        base = dstudy.default_case(opts["surface"], opts["machine"], opts["cutting"], options)
        summary = dstudy.study(base, opts["feed_mm_min"], not opts["no_spiral"], progress, plots=plots)
    except (CaseError, CatalogError, ValidationError, ValueError) as exc:
        raise click.ClickException(one_line(str(exc))) from None
    finally:
        progress_done(progress)
    return summary, base


def _export_dpath(base: Case, record: dict[str, Any], opts: dict[str, Any], planned: Any) -> dict[str, Any]:
    """Export the optimised program of ``dpath`` to ``opts["out"]`` (refusing to replace files
    without --force; signed with --sign-key), as the study planned it (``planned``, from the
    same entries)."""
    from ftsweep.engine.case import CaseError
    from ftsweep.engine.planning import resolve_specs
    from ftsweep.errors import ExportError
    from ftsweep.exports.fingerprint import fingerprint
    from ftsweep.exports.origin import signature_path, signed, signing_key
    from ftsweep.kinds.dpath import format as program
    from ftsweep.kinds.dpath import study as dstudy
    from ftsweep.store.io import check_overwrite, sidecar_path

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
