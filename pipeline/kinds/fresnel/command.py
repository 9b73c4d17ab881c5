"""``ftsweep fresnel``: the freeform Fresnel study of the seed ([2]), a command the Fresnel
kind adds (:meth:`ftsweep.kinds.fresnel.FresnelKind.commands`): the quasi-spiral program of the part
timed under the machine's limits, its figures, and its export with ``-o``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from ftsweep.options import (
    FINITE,
    POSITIVE,
    FiniteRange,
    echo_json,
    one_line,
    progress_done,
    refuse_overwrite,
    sign_options,
    stderr_progress,
    threads_option,
)


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
    "--timing",
    type=click.Choice(["optimal", "paper", "constant"]),
    help="Timesteps: the least time every axis's limits allow, certified by a lower bound (optimal); "
    "[2]'s eqs. 15-16 turn by turn (paper); one constant step (constant). Default: optimal.",
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
    """Plan a freeform Fresnel program for an X-Y-Z-C lathe ([2]) and time it.

    Slices the surface along its contour lines into facets of the given height, plans the
    quasi-spiral path along the facets' edges (feed Δr per turn from the cutting entry),
    the 4-axis trajectory that keeps the rake face on the cutting direction, the tool-edge
    compensation (eq. 10 and eq. 12, both reported), and the timesteps: by default the least
    time in which every axis stays within 1/K_s of its velocity and acceleration limits
    ([2]'s eq. 14 at every point), with a lower bound no program through the same points
    within the same limits can beat, in all and per facet (docs/kinds.md, "Time-optimal timing");
    --timing paper times each turn by [2]'s eqs. 15-16 instead. The machining time is
    compared with one constant timestep at the global acceleration limit.
    Progress on stderr; plots in --plots; with -o the program and a JSON sidecar
    (check it with `ftsweep verify FILE`).

    \b
    Examples:
      ftsweep fresnel
      ftsweep fresnel --surface chebyshev_example --facet-height-um 10 --json
      ftsweep fresnel --timing paper          # [2]'s timesteps, to compare
      ftsweep fresnel -o outputs/fresnel.txt --force
    """
    from pydantic import ValidationError

    from ftsweep.errors import ExportError
    from ftsweep.exports.origin import signed, signing_key
    from ftsweep.inputs.yamlfiles import CatalogError
    from ftsweep.kinds.fresnel import figures
    from ftsweep.kinds.fresnel import study as fstudy
    from ftsweep.store.io import sidecar_path

    keys = (
        "facet_height_um",
        "points_per_turn",
        "deviation_deg",
        "compensation",
        "scheme",
        "safety",
        "timing",
    )
    inp = fstudy.inputs(opts["surface"], opts["machine"], opts["cutting"], **{k: opts[k] for k in keys})
    out = opts["out"]
    refuse_overwrite(out, opts["force"])
    progress = stderr_progress("timesteps (turns)", opts["as_json"])
    try:
        summary = fstudy.study(inp, progress=progress)
        progress_done(progress)
        plots = [str(p) for p in figures.plot(summary, opts["plot_dir"])]
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
