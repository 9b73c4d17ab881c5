"""The ``ftsweep`` command line."""

from __future__ import annotations

import math
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Optional

import click
import numpy as np
from pydantic import ValidationError

from ftsweep import __version__, catalogs, result
from ftsweep.case import LINE_CACHE_MB, MAX_NODES, SPIRAL_FIELDS, Case, CaseError, Resolution, run_case
from ftsweep.catalogs import CatalogError
from ftsweep.io import dumps_json
from ftsweep.sweep import MAX_CASES
from ftsweep.usersurfaces import SurfaceLoadError

_RING_PITCH = result.pitch_names("ring")
_MESH_PITCH = result.pitch_names("mesh")


class FiniteRange(click.FloatRange):
    """A finite float within a range; click refuses anything else naming the option."""

    def convert(self, value: Any, param: Optional[click.Parameter], ctx: Optional[click.Context]) -> Any:
        number = super().convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{number} is not a finite number", param, ctx)
        return number


FINITE = FiniteRange()
POSITIVE = FiniteRange(min=0.0, min_open=True)
NON_NEGATIVE = FiniteRange(min=0.0)
COUNT = click.IntRange(min=1)

# exported files and cubes are data: the plug-ins they name run only from the local catalog
TRUST_PLUGINS = click.option(
    "--trust-plugins",
    is_flag=True,
    help="Run a plug-in surface the file names even if the local catalog does not declare it "
    "(plug-ins are code: only for files you trust; README 'Trust').",
)


def _fail(message: str) -> None:
    raise click.UsageError(message)


MESSAGE_LIMIT = 1500


def one_line(text: str, limit: int = MESSAGE_LIMIT) -> str:
    """A message on one line: its lines joined with "; ", whitespace collapsed and the whole
    cut at ``limit`` characters, so no input, however large, is echoed in full."""
    parts = [" ".join(line.split()) for line in str(text).splitlines()]
    joined = "; ".join(p for p in parts if p).replace(":; ", ": ")
    return joined if len(joined) <= limit else joined[: limit - 1] + "…"


# errors a user can cause: shown as one line, exit 1, no traceback
USER_ERRORS: tuple[type[BaseException], ...] = (
    ValueError,
    OSError,
    RuntimeError,
    MemoryError,
    RecursionError,
)


class _Group(click.Group):
    """Turns every error into a one-line message and a non-zero exit (no traceback); set
    FTSWEEP_DEBUG=1 to see the traceback of an unexpected one."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except click.UsageError as exc:
            raise click.UsageError(one_line(exc.format_message()), exc.ctx) from None
        except click.ClickException as exc:
            raise click.ClickException(one_line(exc.format_message())) from None
        except (click.exceptions.Exit, click.Abort, KeyboardInterrupt, SystemExit):
            raise
        except BrokenPipeError:
            # the reader went away (e.g. `| head`): stop quietly, as other command-line tools do
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            sys.exit(1)
        except Exception as exc:
            if os.environ.get("FTSWEEP_DEBUG"):
                raise
            known = isinstance(exc, USER_ERRORS)
            hint = "" if known else " (an unexpected error: set FTSWEEP_DEBUG=1 for the traceback)"
            text = str(exc) if known and str(exc) else f"{type(exc).__name__}: {exc}"
            raise click.ClickException(one_line(text, MESSAGE_LIMIT - len(hint)) + hint) from None


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="ftsweep")
def main() -> None:
    """Control-point layouts for fast-tool-servo (FTS) diamond turning.

    An FTS controller moves the tool by bilinear interpolation in a table of control
    points (rings in polar coordinates or a Cartesian mesh). ftsweep predicts the form
    error a layout leaves on the machined part, including tool-nose compensation and the
    tool-arc envelope (the model is in the README, section "The model").

    \b
    Units: lengths µm, errors nm, angles degrees, feed µm/rev.
    Catalogs (surfaces, machines, cutting conditions) are YAML files in catalogs/ or in
    the folder named by $FTSWEEP_CATALOGS; `ftsweep catalogs` lists them.
    """
    from ftsweep import allocator

    allocator.tune()  # large batch temporaries reused, not page-faulted afresh (see the module)


@main.command("catalogs")
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object on stdout.")
def list_catalogs(as_json: bool) -> None:
    """List the surfaces, machines, cutting conditions and sweeps the catalogs define.

    Descriptions are printed whole, wrapped to the terminal. With --json, one object maps
    each kind to its entries (every field, units in the field names) and the sweep names.
    """
    import shutil
    import textwrap

    from ftsweep.sweep import sweep_dir

    kinds = ("surfaces", "machines", "cutting")
    found = {kind: catalogs.entries(kind) for kind in kinds}
    sweeps = sorted(p.stem for p in sweep_dir().glob("*.yaml"))
    if as_json:
        data: dict[str, Any] = {
            kind: {name: spec.model_dump(mode="json") for name, spec in entries.items()}
            for kind, entries in found.items()
        }
        data["sweeps"] = sweeps
        data["catalog_dir"] = str(catalogs.catalog_dir())
        _echo_json(data)
        return
    width = max(40, min(shutil.get_terminal_size((100, 24)).columns, 120))
    for kind in kinds:
        click.echo(f"{kind} ({catalogs.catalog_dir() / (kind + '.yaml')}):")
        for name, spec in found[kind].items():
            extra = f" [{spec.family}, {spec.layout} layout]" if kind == "surfaces" else ""
            desc = " ".join(spec.description.split())
            click.echo(
                textwrap.fill(
                    f"{name}{extra}: {desc}",
                    width=width,
                    initial_indent="  ",
                    subsequent_indent="      ",
                    break_on_hyphens=False,  # keep "Noll-indexed", "off-axis" whole
                )
            )
    click.echo(f"sweeps ({sweep_dir()}):")
    for name in sweeps:
        click.echo(f"  {name}")


@main.command()
@click.option("--surface", required=True, metavar="NAME", help="Surface from catalogs/surfaces.yaml.")
@click.option(
    "--layout",
    type=click.Choice(["ring", "mesh", "spiral"]),
    default=None,
    help="Program: a ring (polar grid) or mesh (Cartesian grid) table for an independent FTS "
    "controller, or a spiral path program (points along the tool path, linear between them). "
    "Default: the surface's table method.",
)
@click.option("--drho-um", type=FINITE, help="Ring pitch Δρ [µm] (ring layout).")
@click.option(
    "--dtheta-deg",
    type=FINITE,
    help="Angular pitch Δθ [deg] (ring); rounded to the nearest 360/Np with a notice unless --strict.",
)
@click.option("--dx-um", type=FINITE, help="Mesh pitch Δx [µm] (mesh layout).")
@click.option("--dy-um", type=FINITE, help="Mesh pitch Δy [µm] (mesh layout).")
@click.option("--points", type=FINITE, help="Target number of control points N (with --aspect).")
@click.option("--aspect", type=FINITE, help="Target aspect ratio α: Δρ/Δθ [µm/deg] (ring) or Δx/Δy (mesh).")
@click.option("--points-per-rev", type=int, help="Spiral: constant-angle rule, points per revolution.")
@click.option("--arc-um", type=FINITE, help="Spiral: constant-arc rule, path length between points [µm].")
@click.option(
    "--chord-um", type=FINITE, help="Spiral: chord-error budget Δcho [µm] that places each next point."
)
@click.option(
    "--residual-um",
    type=FINITE,
    help="Spiral: residual (cusp) budget Δres [µm]; the feed is the largest that keeps every cusp "
    "within it, from each radial section's curvature (instead of --feed-um).",
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
@click.option("--machine", default="fts-1m", show_default=True, help="Machine from catalogs/machines.yaml.")
@click.option("--cutting", default="reference", show_default=True, help="Entry of catalogs/cutting.yaml.")
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
    "--samples-per-cell",
    type=int,
    default=Resolution().samples_per_cell,
    show_default=True,
    help="Spindle angles simulated per table cell along the outer circumference.",
)
@click.option(
    "--points-per-feed",
    type=int,
    default=Resolution().points_per_feed,
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
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object on stdout.")
def predict(**opts: Any) -> None:
    """Predict the form error one program leaves on the machined surface.

    Give a table either by explicit pitches (--drho-um and --dtheta-deg for rings,
    --dx-um and --dy-um for meshes) or by a target point count and aspect ratio
    (--points and --aspect); the actual point count and pitches are reported.

    Commands spanning more than the machine's travel are cut in layers (--layers auto, [3]):
    stroke zones of the travel less the machine's margin, one Z offset each; the JSON's
    "layers" holds the schedule (offsets, start radii, strokes, lengths, times per layer).

    A spiral program (--layout spiral) places its points along the tool path by one rule:
    --points-per-rev (constant angle), --arc-um (constant path length) or --chord-um (each
    chord within the budget of the compensated path, [4]); its feed is --feed-um, the
    cutting entry's, or the largest the residual budget --residual-um allows.

    \b
    Examples:
      ftsweep predict --surface sinewave2d --layout ring --drho-um 2 --dtheta-deg 0.5
      ftsweep predict --surface lens_array --layout mesh --dx-um 4 --dy-um 4 --json
      ftsweep predict --surface sinewave2d --points 500000 --aspect 8
      ftsweep predict --surface sinewave2d --layout spiral --points-per-rev 500
      ftsweep predict --surface sinusoidal_mesh --layout spiral --chord-um 0.5 --residual-um 0.5 \\
          --cutting seed003 --machine sts-nanoform
      ftsweep predict --surface microprism --machine fts-5um --cutting microprism --points 250000 \\
          --aspect 1 --z-error-um 0.1
    """
    case = _build_case(opts)
    as_json = opts["as_json"]
    progress = _progress("simulating", as_json)
    try:
        record = run_case(case, progress=progress, max_nodes=opts["max_nodes"])
    except (CaseError, CatalogError, SurfaceLoadError) as exc:
        raise click.ClickException(str(exc)) from None
    finally:
        _progress_done(progress)
    if as_json:
        _echo_json(record)
    else:
        click.echo(_summary(record))


@main.command()
@click.argument("sweep_name", metavar="NAME|PATH")
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    help="Cube to write (a Zarr folder). Default: outputs/<sweep>.zarr.",
)
@click.option(
    "--scheduler",
    metavar="ADDRESS",
    help="Address of a running dask scheduler (tcp://host:port); also read from "
    "$DASK_SCHEDULER_ADDRESS. 'synchronous' runs in this process. Default: a local cluster.",
)
@click.option("--workers", type=COUNT, help="Worker processes of the local cluster. Default: one per core.")
@click.option(
    "--restart",
    is_flag=True,
    help="Discard an existing cube and start over (required when the spec changed).",
)
@click.option("--retry-failed", is_flag=True, help="Also recompute cases recorded as failed.")
@click.option(
    "--max-cases",
    type=COUNT,
    default=MAX_CASES,
    show_default=True,
    help="Refuse sweeps of more cases than this (each takes seconds of a core).",
)
@click.option(
    "--prune",
    type=FiniteRange(min=1.0, min_open=True),
    metavar="FACTOR",
    help="Leave out cases whose estimated P-V (`ftsweep estimate`) exceeds FACTOR times the best "
    "estimate of their point count; they are marked pruned, and a run without --prune computes "
    "them. The estimate was within 0.62-1.23 of the simulation on the reference sweeps, so 3 is safe.",
)
@click.option(
    "--line-cache-mb",
    type=NON_NEGATIVE,
    default=LINE_CACHE_MB,
    show_default=True,
    help="Memory [MiB] each worker may keep of the lines (surface samples, exact commands and "
    "their envelope) that cases on the same angular sampling share; 0 computes every case on its "
    "own. Results are the same either way. resolution.angular_ladder in the spec makes cases share.",
)
def sweep(
    sweep_name: str,
    out: Optional[Path],
    scheduler: Optional[str],
    workers: Optional[int],
    restart: bool,
    retry_failed: bool,
    max_cases: int,
    prune: Optional[float],
    line_cache_mb: float,
) -> None:
    """Run a sweep of point counts and aspect ratios into a Zarr result cube.

    NAME is a spec in catalogs/sweeps/ (e.g. sinewave-ring, lens-array-mesh), or give a
    path to a YAML file. Every case is written into its own region of the cube as soon as
    it finishes. Re-running the same command computes only what is missing, so an
    interrupted or killed run loses nothing already written; done cases whose data files are
    missing or unreadable are recomputed. A cube made from a different spec is refused unless
    --restart, which discards the cube and starts over. One process writes a cube at a time:
    a second sweep on the same cube (also with --restart) is refused while the first runs.

    \b
    Examples:
      ftsweep sweep sinewave-ring
      ftsweep sweep my-sweep.yaml --out outputs/my.zarr --workers 2
      ftsweep sweep lens-array-mesh --scheduler tcp://127.0.0.1:8786
    """
    from ftsweep.cube import CubeError
    from ftsweep.executor import ExecutorError
    from ftsweep.lock import LockError
    from ftsweep.run import axis_summary, run_sweep
    from ftsweep.sweep import load_sweep

    try:
        name, spec = load_sweep(sweep_name)
    except CatalogError as exc:
        raise click.ClickException(str(exc)) from None
    click.echo(f"sweep {name}: {spec.surface}, {spec.layout} layouts, {axis_summary(spec)}", err=True)
    progress = _sweep_progress(time.perf_counter())

    try:
        report = run_sweep(
            sweep_name,
            out,
            scheduler,
            workers,
            restart,
            retry_failed,
            progress=progress,
            max_cases=max_cases,
            prune=prune,
            line_cache_mb=line_cache_mb,
        )
    except (CatalogError, CubeError, CaseError, LockError, ExecutorError) as exc:
        raise click.ClickException(str(exc)) from None
    for index, reason in sorted(report.damaged.items())[:5]:
        click.echo(f"recomputed   case {index}: it was done but {reason}", err=True)
    errors = [r for r in report.rows if r["status"] == "error"]
    if errors:
        first = errors[0]
        raise click.ClickException(
            f"{len(errors)} case(s) could not be run and stay pending; first: {_case_label(first)}: "
            f"{first['message']}"
        )
    counts = _print_sweep_summary(report)
    if counts["pending"] or counts["failed"]:
        sys.exit(1)


def _case_label(row: dict[str, Any]) -> str:
    if row.get("points") is None or row.get("aspect") is None:
        return f"case {row['index']}"  # a spiral case: no target count and aspect
    return f"case {row['index']} (N≈{row['points']:,.0f} α={row['aspect']:.3g})"


def _sweep_progress(started: float) -> Callable[[Any, list[dict]], None]:
    """A progress line on stderr per finished task: cases done, failures, time, ETA, last case."""

    def progress(report: Any, rows: list[dict]) -> None:
        total_now = report.queued
        done = len(report.rows)
        elapsed = time.perf_counter() - started
        eta = _eta_text(report, rows_all=report.rows, remaining=total_now - done)
        last = rows[-1]
        what = f"{_case_label(last)}: " + (
            f"P-V {last['pv_nm']:.2f} nm" if last["status"] == "done" else one_line(last["message"], 300)
        )
        click.echo(
            f"[{done:>{len(str(total_now))}}/{total_now}] {report.failed} failed | {elapsed:6.1f} s, "
            f"{eta} | {what}",
            err=True,
        )

    return progress


def _eta_text(report: Any, rows_all: list[dict], remaining: int) -> str:
    """The time left, from the measured times of the cases finished so far (their summed
    case seconds over the workers), not from the wall time, which holds the cluster's start
    and the kernels' compilation; none until two cases have finished."""
    times = [r.get("seconds", 0.0) for r in rows_all if r.get("seconds")]
    if len(times) < 2 or remaining <= 0:
        return "ETA –" if remaining > 0 else "ETA 0 s"
    per_case = sum(times) / len(times)
    return f"ETA {per_case * remaining / max(report.workers, 1):6.0f} s"


def _print_sweep_summary(report: Any) -> dict[str, int]:
    """The end-of-run summary on stdout: counts, throughput, failures, best per point count."""
    from ftsweep.run import best_per_point_count, cube_counts

    counts = cube_counts(report.cube)
    click.echo(f"cube         {report.cube}")
    click.echo(
        f"cases        {report.total} in all: {counts['done']} done, {counts['failed']} failed, "
        f"{counts['pending']} pending, {counts['pruned']} pruned ({report.skipped} were done already, "
        f"{len(report.rows)} run now)"
    )
    busy = sum(r.get("seconds", 0.0) for r in report.rows)
    rate = len(report.rows) / report.wall_s if report.wall_s > 0 else float("nan")
    click.echo(
        f"wall time    {report.wall_s:.1f} s with {report.workers} worker(s): {rate:.3g} cases/s; "
        f"summed case time {busy:.1f} s"
    )
    reused = [r.get("reused_batches", 0) for r in report.rows if r["status"] == "done"]
    if any(reused):
        click.echo(
            f"shared lines {sum(1 for n in reused if n)} case(s) reused {sum(reused):,} batches of lines "
            "computed by an earlier case on the same worker"
        )
    for r in [r for r in report.rows if r["status"] != "done"][:5]:
        click.echo(f"failed       {_case_label(r)}: {one_line(r['message'], 300)}")
    click.echo("best P-V per point count (among the cases select may choose):")
    rows = best_per_point_count(report.cube)
    # tables are swept over aspect ratios; a path program's best is named by its case
    tables = any(r["table"] for r in rows)
    third = "best α" if tables else "case"
    click.echo(f"  {'target':>10s} {'actual N':>10s} {third:>8s} {'P-V nm':>9s}")
    for row in rows:
        if row["pv_nm"] is None:
            click.echo(f"  {row['points']:10,.0f} {'–':>10s} {'–':>8s} {'–':>9s}")
            continue
        which = f"{row['aspect']:8.3g}" if tables else f"{row['index']:8d}"
        click.echo(f"  {row['points']:10,.0f} {row['n_points']:10,d} {which} {row['pv_nm']:9.2f}")
    return counts


def _target_text(value: float) -> str:
    """A sweep axis value: whole counts with thousands separators, others to 4 digits."""
    return f"{value:,.0f}" if value == round(value) and abs(value) >= 1000 else f"{value:.4g}"


def _selection_text(chosen: dict[str, Any]) -> str:
    if chosen["layout"] in ("spiral", "dpath"):
        pitch = f"mean Δφ = {chosen['dphi_deg']:.4g}°, mean Δs = {chosen['ds_um']:.4g} µm"
    elif chosen["layout"] == "ring":
        pitch = f"Δρ = {chosen['drho_um']:.4g} µm, Δθ = {chosen['dtheta_deg']:.4g}°"
    else:
        pitch = f"Δx = {chosen['dx_um']:.4g} µm, Δy = {chosen['dy_um']:.4g} µm"
    interp = (
        f"interpolation alone {chosen['pv_interp_nm']:.2f} nm"
        if math.isfinite(chosen["pv_interp_nm"])
        else "interpolation alone not simulated"
    )
    targets = ", ".join(
        f"{name[: -len('_target')]} {_target_text(value)}"
        for name, value in chosen.items()
        if name.endswith("_target")
    )
    return "\n".join(
        [
            f"rule         {chosen['rule']}",
            f"case         {chosen['index']} ({targets})",
            f"layout       {chosen['layout']}: {chosen['n_points']:,} points, {pitch} "
            f"(α = {chosen['aspect_actual']:.4g})",
            f"P-V          {chosen['pv_nm']:.2f} nm (RMS {chosen['rms_nm']:.2f} nm, {interp})",
        ]
    )


@main.command()
@click.argument("cube_path", metavar="CUBE", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--budget-points", type=COUNT, help="Best aspect ratio at or under this many points.")
@click.option("--tolerance-nm", type=POSITIVE, help="Fewest points whose P-V meets this tolerance [nm].")
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object on stdout.")
def select(
    cube_path: Path, budget_points: Optional[int], tolerance_nm: Optional[float], as_json: bool
) -> None:
    """Choose the layout for production from a sweep's cube.

    Only computed, feasible cases within the controller's capacity are ever chosen. With
    --budget-points: the lowest P-V at or under that many points. With --tolerance-nm: the
    smallest layout that meets the tolerance; when none does, say so and show the best.
    """
    from ftsweep.cube import CubeError
    from ftsweep.select import SelectError, choose, open_cube

    try:
        chosen = choose(open_cube(cube_path), budget_points, tolerance_nm)
    except (SelectError, CubeError) as exc:
        raise click.ClickException(str(exc)) from None
    if as_json:
        _echo_json(chosen)
    else:
        click.echo(_selection_text(chosen))
    if chosen.get("met") is False:
        click.echo(f"tolerance    not met: no case reaches {tolerance_nm:g} nm", err=True)
        sys.exit(1)


@main.command()
@click.argument("cube_path", metavar="CUBE", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--budget-points", type=COUNT, help="Export the best layout at or under this many points.")
@click.option("--tolerance-nm", type=POSITIVE, help="Export the smallest layout meeting this P-V [nm].")
@click.option("--case", "index", type=int, help="Export the case at this flat index of the cube.")
@click.option(
    "-o",
    "--output",
    "out",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Header file to write (FILE.h); the sidecar FILE.json is written beside it.",
)
@click.option("--name", help="Prefix of the C identifiers. Default: the file name.")
@click.option("--force", is_flag=True, help="Replace an existing header and sidecar.")
@TRUST_PLUGINS
def export(
    cube_path: Path,
    budget_points: Optional[int],
    tolerance_nm: Optional[float],
    index: Optional[int],
    out: Path,
    name: Optional[str],
    force: bool,
    trust_plugins: bool,
) -> None:
    """Export the chosen case of a cube: a ring or mesh table (layered or not) as a C header
    for the FTS controller (-o FILE.h), a spiral program (layered or not) as plain-text lines
    C [deg] X [mm] Z [mm], or a D-path program as lines t [s] C [deg] X [mm] Z [mm] (-o
    FILE.txt), each under a header of units, surface, tool, budgets and predicted P-V. Fresnel
    programs are exported by `ftsweep fresnel -o FILE.txt`; `ftsweep verify FILE` checks any.

    The table is stored as fixed-point integers (unit and type from the machine catalog) in
    the order the controller indexes it, with macros for the layout, pitches, origin, units,
    surface, cutting conditions, predicted P-V, generator and a CRC-32 of the table. A JSON
    sidecar holds the same metadata and the full case spec. Both are written atomically.
    Failed, pending, infeasible and over-capacity cases are refused.
    """
    from ftsweep import export as exp
    from ftsweep.cube import CubeError
    from ftsweep.select import SelectError

    try:
        meta = exp.export(cube_path, out, budget_points, tolerance_nm, index, force, name, trust_plugins)
    except (exp.ExportError, SelectError, CubeError) as exc:
        raise click.ClickException(str(exc)) from None
    click.echo(_selection_text(meta["selection"]))
    for line in exp.format_of_file(out).exported(out, meta):
        click.echo(line)
    click.echo(f"sidecar      {exp.sidecar_path(out)}")


@main.command()
@click.argument("header", metavar="FILE", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option(
    "--pv-tolerance-nm",
    type=NON_NEGATIVE,
    help="Largest allowed |re-simulated − predicted| P-V [nm]. Default: a table's unit (the "
    "quantisation bound) + 0.1 % of the P-V; a program's 0.01 nm + 0.1 %.",
)
@TRUST_PLUGINS
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object on stdout.")
def verify(header: Path, pv_tolerance_nm: Optional[float], trust_plugins: bool, as_json: bool) -> None:
    """Check an exported file as the machine will read it, against the program its sidecar's
    case plans: a controller header (ring or mesh table, layered or not: FILE.h) or a path
    program (spiral, layered spiral, D path, Fresnel: FILE.txt).

    \b
    Exit 0 only if everything the machine will use checks out:
    - the CRC-32 over every line the machine reads, the sidecar's SHA-256 of the file and
      the file's SHA-256 of the sidecar;
    - the file is exactly what export writes for the recorded case: every macro value (no
      comment or expression inside one), every header and layer/segment line; every table
      cell within one unit of the re-planned table, every program line (t, C, X, Y, Z)
      within 1 µs, 1e-6° and 1 nm of the re-planned one;
    - a D-path or Fresnel program: every line within the machine's axis limits;
    - a table or spiral/D-path program: the P-V re-simulated from the file as stored within
      the tolerance of the P-V predicted at export.
    Otherwise exit 1 naming the first difference: do not load that file. Files are data: a
    plug-in surface they name runs only if the local catalog declares it (--trust-plugins).
    """
    from ftsweep import export as exp

    progress = _progress("re-simulating", as_json)
    try:
        record = exp.verify(header, progress, pv_tolerance_nm, trust_plugins)
    except (exp.ExportError, CaseError, CatalogError) as exc:
        raise click.ClickException(str(exc)) from None
    finally:
        _progress_done(progress)
    if as_json:
        _echo_json(record)
        return
    for line in exp.format_of_file(header).verified(record):
        click.echo(line)


@main.command()
@click.argument("surface", required=False)
@click.option(
    "--sweep",
    "sweep_name",
    metavar="NAME|PATH",
    help="Take surface, layout, machine, cutting and resolution from a sweep spec.",
)
@click.option("--layout", type=click.Choice(["ring", "mesh"]), help="Layout method. Default: the surface's.")
@click.option("--tolerance-nm", type=POSITIVE, required=True, help="P-V the part must meet [nm].")
@click.option(
    "--start-points",
    type=FINITE,
    default=50_000,
    show_default=True,
    help="Point count of the first, coarse round.",
)
@click.option("--machine", default="fts-1m", show_default=True, help="Machine from catalogs/machines.yaml.")
@click.option("--cutting", default="reference", show_default=True, help="Entry of catalogs/cutting.yaml.")
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    help="Cube recording every evaluation. Default: outputs/optimize-<surface>-<layout>.zarr.",
)
@click.option(
    "--restart",
    is_flag=True,
    help="Discard the evaluation cube and start over (required when the search changed); without "
    "it, re-running the same search resumes, reusing every finished evaluation.",
)
@click.option(
    "--seed",
    type=click.Choice(["scan", "estimate"]),
    default="scan",
    show_default=True,
    help="Where the search starts: a scan of nine aspect ratios at --start-points, or the point "
    "count and aspect ratio `ftsweep estimate` predicts for the tolerance (fewer evaluations).",
)
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object on stdout.")
def optimize(
    surface: Optional[str],
    sweep_name: Optional[str],
    layout: Optional[str],
    tolerance_nm: float,
    start_points: float,
    machine: str,
    cutting: str,
    out: Optional[Path],
    restart: bool,
    seed: str,
    as_json: bool,
) -> None:
    """Find the smallest layout that meets a P-V tolerance (the shop's tolerance loop).

    Starts coarse (a scan of aspect ratios at --start-points), refines around the best
    aspect ratio, then raises (or lowers) the point count using P-V ∝ 1/N until the
    tolerance is met with as few points as possible or the controller's capacity is
    reached. Every evaluation is recorded in a cube as soon as it finishes (the store
    protocol of sweeps), so an interrupted search resumes where it stopped.

    \b
    Examples:
      ftsweep optimize sinewave2d --layout ring --tolerance-nm 20
      ftsweep optimize --sweep lens-array-mesh --tolerance-nm 30
    """
    from ftsweep.cube import CubeError
    from ftsweep.optimize import optimize as run_optimize
    from ftsweep.sweep import load_sweep

    resolution = None
    compensation = "exact"
    try:
        if sweep_name:
            _, spec = load_sweep(sweep_name)
            surface, layout, machine, cutting = spec.surface, spec.layout, spec.machine, spec.cutting
            resolution, compensation = spec.resolution, spec.compensation
        if not surface:
            _fail("give a SURFACE or --sweep")
        assert surface is not None

        def report(rec: dict[str, Any]) -> None:
            pv = f"P-V {rec['pv_nm']:.2f} nm" if rec["status"] == "done" else rec["message"]
            mark = "meets" if rec["status"] == "done" and rec["pv_nm"] <= tolerance_nm else ""
            click.echo(
                f"[{rec['stage']:>6s}] N≈{rec['points_target']:>9,.0f} α={rec['aspect_target']:<8.4g} "
                f"{pv} {mark}",
                err=True,
            )

        result = run_optimize(
            surface,
            layout,
            tolerance_nm,
            out,
            start_points,
            machine,
            cutting,
            compensation,
            resolution,
            restart,
            on_eval=report,
            seed=seed,
        )
    except (CatalogError, CubeError, ValueError) as exc:
        raise click.ClickException(str(exc)) from None
    if as_json:
        _echo_json(result)
    else:
        ans = result["answer"]
        verdict = "met" if result["met"] else "NOT met (best found below)"
        click.echo(
            f"tolerance    {tolerance_nm:g} nm: {verdict}; {result['evaluations']} evaluations "
            f"({result['reused']} reused) in {result['cube']}"
        )
        if ans is not None:
            click.echo(_summary(ans))
    if not result["met"]:
        sys.exit(1)


@main.command()
@click.argument("cube_path", metavar="CUBE", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option(
    "--out",
    "out_dir",
    type=click.Path(file_okay=False, path_type=Path),
    help="Folder for the figures and index.html. Default: <cube>-report beside the cube.",
)
@click.option(
    "--case",
    "index",
    type=int,
    help="Case (flat index) for the error map and spectrum. Default: the best at the largest budget.",
)
@click.option(
    "--map-bins",
    type=click.IntRange(min=8),
    default=160,
    show_default=True,
    help="Bins per side of the error map.",
)
@TRUST_PLUGINS
def report(
    cube_path: Path, out_dir: Optional[Path], index: Optional[int], map_bins: int, trust_plugins: bool
) -> None:
    """Figures of a sweep's cube and one HTML page that shows them with its metadata.

    P-V against point count and against aspect ratio (optimum marked), a heat map of P-V,
    the error map of the chosen case over the part and its W command spectrum with the servo
    bandwidth. The error map needs a re-simulation of that case, which shows progress.
    """
    from ftsweep.cube import CubeError
    from ftsweep.report import make_report
    from ftsweep.select import SelectError

    progress = _progress("error map")
    click.echo("plotting the cube; re-simulating the chosen case for its error map ...", err=True)
    try:
        paths = make_report(cube_path, out_dir, index, map_bins, progress, trust_plugins)
    except (CubeError, SelectError, CaseError) as exc:
        raise click.ClickException(str(exc)) from None
    finally:
        _progress_done(progress)
    for name, path in paths.items():
        click.echo(f"{name:14s} {path}")


@main.command()
@click.argument("sweep_name", metavar="SWEEP")
@click.option(
    "--compare",
    "cube_path",
    type=click.Path(path_type=Path),
    help="A simulated cube of this sweep: also print how the estimate agrees with it.",
)
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object on stdout.")
def estimate(sweep_name: str, cube_path: Optional[Path], as_json: bool) -> None:
    """Estimate the P-V of every layout of a sweep in milliseconds, without simulating.

    The first-order bilinear error ⅛·(Δ₁²·∂₁₁f + Δ₂²·∂₂₂f) per cell (model §3), from the
    surface's sampled second derivatives and each layout's pitches, spanned over the part,
    plus the feed cusp F²/8Rc (model §5). It locates the aspect optimum and the hopeless
    corners of a sweep plane; the simulation decides. With --compare CUBE it states its
    measured agreement with a simulated cube of the same sweep.

    \b
    Examples:
      ftsweep estimate sinewave-ring
      ftsweep estimate lens-array-mesh --compare outputs/lens-array-mesh.zarr --json
    """
    from ftsweep.cube import CubeError
    from ftsweep.estimate import agreement, best_aspect, estimate_sweep
    from ftsweep.select import open_cube
    from ftsweep.sweep import load_sweep

    try:
        name, spec = load_sweep(sweep_name)
    except CatalogError as exc:
        raise click.ClickException(str(exc)) from None
    started = time.perf_counter()
    ds = estimate_sweep(spec)
    seconds = time.perf_counter() - started
    pv = ds["pv_estimate_nm"]
    while pv.ndim > 2:  # optional feed/nose-radius axes: their first values
        pv = pv.isel({pv.dims[-1]: 0})
    best = best_aspect(pv)
    out: dict[str, Any] = {
        "sweep": name,
        "layouts": int(ds["interp_estimate_nm"].size),
        "seconds": seconds,
        "best": [
            {"points": float(n), "aspect": float(a), "pv_estimate_nm": float(pv.sel(points=n, aspect=a))}
            for n, a in zip(best["points"].values, best.values, strict=True)
            if np.isfinite(a)
        ],
    }
    if cube_path is not None:
        try:
            out["agreement"] = agreement(ds, open_cube(cube_path))
        except (CubeError, OSError, KeyError, ValueError) as exc:
            raise click.ClickException(f"{cube_path}: cannot compare: {exc}") from None
    if as_json:
        _echo_json(out)
        return
    click.echo(f"estimated {out['layouts']} layouts of sweep '{name}' in {seconds * 1e3:.0f} ms")
    unit = "µm/deg" if spec.layout == "ring" else ""
    click.echo(f"{'points':>12}  {'best aspect':>12}  {'P-V estimate':>14}")
    for row in out["best"]:
        click.echo(
            f"{row['points']:>12,.0f}  {row['aspect']:>8.4g} {unit:<6} {row['pv_estimate_nm']:>9.2f} nm"
        )
    if "agreement" in out:
        a = out["agreement"]
        click.echo(
            f"against {a['cases']} simulated cases: estimate/simulated P-V {a['pv_ratio_min']:.2f} … "
            f"{a['pv_ratio_max']:.2f} (median {a['pv_ratio_median']:.2f}; "
            f"{100 * a['within_factor_2']:.0f} % within a factor 2); aspect optimum within a factor "
            f"{a['optimum_aspect_factor_max']:.2f} of the simulated one"
        )


@main.command()
@click.option("--case", "names", multiple=True, metavar="NAME", help="Only this case (repeatable).")
@click.option("--repeat", type=int, default=1, show_default=True, help="Runs per case; the fastest counts.")
@click.option(
    "--json",
    "json_path",
    type=click.Path(dir_okay=False, writable=True),
    default="outputs/bench.json",
    show_default=True,
    help="Also write the figures to this JSON file.",
)
@click.option(
    "--sweep",
    "sweep_name",
    metavar="SWEEP",
    help="Also run this sweep on a local cluster (e.g. sinewave-ring, ~4 min) and report cases/s.",
)
@click.option("--workers", type=COUNT, default=2, show_default=True, help="Worker processes for --sweep.")
def bench(
    names: tuple[str, ...], repeat: int, json_path: str, sweep_name: Optional[str], workers: int
) -> None:
    """Time the case runner on the published reference cases and two 10⁶-point layouts.

    Prints the seconds per case split into compensation, surface sampling, interpolation,
    envelope and metrics, after a warm-up that pays numba's compile cost. Kernels are
    single-threaded, so the figures are for one core. With --sweep, also the throughput of a
    whole sweep on --workers processes. Nothing is asserted about time.
    """
    from ftsweep.bench import format_table, run_benchmark, sweep_throughput
    from ftsweep.io import write_json_atomic

    try:
        result = run_benchmark(list(names) or None, repeat=repeat)
    except ValueError as exc:
        raise click.ClickException(str(exc)) from None
    click.echo(format_table(result))
    if sweep_name is not None:
        click.echo(f"running sweep {sweep_name} on {workers} worker(s) ...", err=True)
        sweep = sweep_throughput(sweep_name, workers)
        result["sweep"] = sweep
        click.echo(
            f"sweep {sweep['sweep']}: {sweep['cases']} cases in {sweep['wall_s']:.1f} s wall on "
            f"{sweep['workers']} worker(s): {sweep['cases_per_s']:.3f} cases/s "
            f"(summed case time {sweep['summed_case_s']:.1f} s)"
        )
    write_json_atomic(json_path, result)
    click.echo(f"wrote {json_path}")


def _nan_safe(value: Any) -> Any:  # pragma: no cover - only non-JSON types reach here
    return str(value)


def _echo_json(value: Any) -> None:
    """Exactly one strict JSON document on stdout."""
    click.echo(dumps_json(value, default=_nan_safe))


def _progress(label: str, quiet: bool = False) -> Any:
    """Progress on stderr (:mod:`ftsweep.progress`): a bar on a terminal, plain lines in a log."""
    from ftsweep import progress

    return progress.progress(label, quiet)


def _progress_done(bar: Any) -> None:
    from ftsweep import progress

    progress.done(bar)


def _build_case(opts: dict[str, Any]) -> Case:
    """The case of ``predict``'s options. The option combinations are checked here; every
    value is validated by the spec models, whose errors are reported by option name."""
    surface, layout, machine, cutting = opts["surface"], opts["layout"], opts["machine"], opts["cutting"]
    try:
        spec = catalogs.entry("surfaces", surface)
        catalogs.entry("machines", machine)
        catalogs.entry("cutting", cutting)
    except CatalogError as exc:
        raise click.ClickException(str(exc)) from None
    kind = layout or spec.layout
    own = _RING_PITCH if kind == "ring" else _MESH_PITCH
    given = {k: opts[k] for k in (*_RING_PITCH, *_MESH_PITCH)}
    spiral_given = {k: opts[k] for k in SPIRAL_FIELDS if opts[k] is not None}
    if kind == "spiral":
        table_given = [
            k for k, v in {**given, "points": opts["points"], "aspect": opts["aspect"]}.items() if v
        ]
        if table_given:
            _fail(
                f"{_flag(table_given[0])} belongs to tables; a spiral takes --points-per-rev, --arc-um "
                "or --chord-um"
            )
        request: dict[str, Any] = {"kind": kind, **spiral_given}
        pitch_given = False
    else:
        if spiral_given:
            _fail(f"{_flag(next(iter(spiral_given)))} belongs to spiral programs (--layout spiral)")
        pitch_given = _check_layout_options(kind, given, opts["points"], opts["aspect"])
        request = {
            "kind": kind,
            "pitch": (given[own[0]], given[own[1]]) if pitch_given else None,
            "points": opts["points"],
            "aspect": opts["aspect"],
        }
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
            resolution=Resolution(
                samples_per_cell=opts["samples_per_cell"],
                points_per_feed=opts["points_per_feed"],
                n_theta=opts["n_theta"],
                interp_error=opts["interp_error"],
            ),
        )
    except ValidationError as exc:
        raise click.UsageError(_option_errors(exc, own)) from None
    if kind == "ring" and pitch_given and not opts["strict"]:
        drho, dtheta = given[own[0]], _realisable_dtheta(given[own[1]])
        case = case.model_copy(update={"layout": case.layout.model_copy(update={"pitch": (drho, dtheta)})})
    return case


def _option_errors(exc: ValidationError, pitch_names: tuple[str, ...]) -> str:
    """A spec model's validation errors, each named by the option that gave the value
    (``layout.pitch.0`` is the first pitch option, ``resolution.n_theta`` is --n-theta)."""
    parts = []
    for e in exc.errors():
        loc = [str(p) for p in e["loc"]]
        if loc[:2] == ["layout", "pitch"] and len(loc) > 2:
            name = pitch_names[int(loc[2])]
        elif loc and loc[0] in ("layout", "resolution") and len(loc) > 1:
            name = loc[1]
        else:
            name = loc[-1] if loc else ""
        text = f"{catalogs.error_text(e)} (got {catalogs.short_repr(e.get('input'))})"
        parts.append(f"{_flag(name)}: {text}" if name else text)
    return "; ".join(dict.fromkeys(parts))


def _realisable_dtheta(dtheta_deg: float) -> float:
    """The nearest Δθ that divides 360° (a ring holds a whole number of points), with a notice
    on stderr when it differs from the one asked for."""
    from ftsweep.stages.layouts import nearest_ring_dtheta

    realised, n_per_ring = nearest_ring_dtheta(dtheta_deg)
    # the notice prints Δθ to 7 digits: that printed value, given back, is taken silently
    if not math.isclose(realised, dtheta_deg, rel_tol=1e-6):
        click.echo(
            f"notice: Δθ = {dtheta_deg:g}° does not divide 360°; using the nearest realisable "
            f"Δθ = {realised:.7g}° ({n_per_ring} points per ring; --strict refuses instead)",
            err=True,
        )
    return realised


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def _check_layout_options(kind: str, given: dict[str, Any], points: Any, aspect: Any) -> bool:
    """Refuse pitches of the other layout kind, pitches mixed with a target, one pitch alone,
    or no layout at all; returns whether explicit pitches were given."""
    own, other = (_RING_PITCH, _MESH_PITCH) if kind == "ring" else (_MESH_PITCH, _RING_PITCH)
    wrong = [k for k in other if given[k] is not None]
    if wrong:
        _fail(
            f"{_flag(wrong[0])} belongs to the {'mesh' if kind == 'ring' else 'ring'} layout; "
            f"for a {kind} layout give {_flag(own[0])} and {_flag(own[1])}"
        )
    pitch_given = [k for k in own if given[k] is not None]
    if pitch_given and (points is not None or aspect is not None):
        _fail("give either explicit pitches or --points with --aspect, not both")
    if len(pitch_given) == 1:
        missing = [k for k in own if given[k] is None][0]
        _fail(f"{_flag(missing)} is missing: a {kind} layout needs both pitches")
    if not pitch_given and (points is None or aspect is None):
        _fail(f"give the layout: {_flag(own[0])} and {_flag(own[1])}, or --points N with --aspect A")
    return bool(pitch_given)


def _program_lines(r: dict[str, Any]) -> list[str]:
    """The summary lines that describe the program: its points and pitches (or steps)."""
    if r["layout"] == "spiral":
        rule = {
            "angle": f"{r['points_per_rev']:g} points per revolution",
            "arc": f"a point every {r['arc_um']:g} µm of path",
            "chord": f"chord budget {r['chord_um']:g} µm (largest chord error {r['chord_error_nm']:.1f} nm)",
        }[r["spiral_rule"]]
        budget = (
            f"from the residual budget {r['residual_um']:g} µm"
            if math.isfinite(r["residual_um"])
            else "given"
        )
        return [
            f"program      spiral: {r['n_points']:,} points, {rule}",
            f"steps        mean Δφ = {r['dphi_deg']:.4g}°, mean Δs = {r['ds_um']:.4g} µm along the path, "
            f"{r['revolutions']:.4g} revolutions  (α = {r['aspect_actual']:.4g} µm/deg)",
            f"feed         {r['feed_um']:.4g} µm/rev ({budget}); largest residual (cusp) "
            f"{r['residual_error_nm']:.1f} nm from the section curvature",
        ]
    if r["layout"] == "ring":
        pitches = (
            f"Δρ = {r['drho_um']:.4g} µm, Δθ = {r['dtheta_deg']:.7g}°  (α = {r['aspect_actual']:.4g} µm/deg)"
        )
    else:
        pitches = f"Δx = {r['dx_um']:.4g} µm, Δy = {r['dy_um']:.4g} µm  (α = {r['aspect_actual']:.4g})"
    shape = f"{r['table_rows']} × {r['table_cols']}"
    return [
        f"layout       {r['layout']}: {r['n_points']:,} control points ({shape})",
        f"pitches      {pitches}",
    ]


def _summary(r: dict[str, Any]) -> str:
    lines = [
        f"surface      {r['surface']}",
        *_program_lines(r),
        f"cutting      feed {r['feed_um']:g} µm/rev, nose radius {r['nose_radius_um']:g} µm, "
        f"compensation {r['compensation']}",
        f"resolution   {r['n_theta']:,} angles × {r['points_per_feed']} points/feed "
        f"({r['n_eval']:,} evaluation points)",
        "",
        f"P-V          {r['pv_nm']:.2f} nm   "
        f"(inner zone {r['pv_inner_nm']:.2f} nm, outer zone {r['pv_outer_nm']:.2f} nm)",
        f"RMS          {r['rms_nm']:.2f} nm",
        f"error range  {r['error_min_nm']:.2f} … {r['error_max_nm']:.2f} nm",
        f"interp. P-V  {r['pv_interp_nm']:.2f} nm   (interpolation alone)"
        if math.isfinite(r["pv_interp_nm"])
        else "interp. P-V  not simulated (--no-interp-error)",
        f"feed cusp    {r['cusp_nm']:.2f} nm   (F²/8Rc)",
    ]
    if "stroke_um" in r:
        verdict = "feasible" if r["feasible"] else f"INFEASIBLE: {r['infeasible_reason']}"
        lines.append(
            f"W motion     stroke {r['stroke_um']:.3g} µm, "
            f"peak velocity {r['w_velocity_peak_mm_s']:.3g} mm/s, "
            f"peak acceleration {r['w_accel_peak_m_s2']:.3g} m/s² (RMS {r['w_accel_rms_m_s2']:.3g}), "
            f"content up to {r['w_freq_max_hz']:.0f} Hz: {verdict}"
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
            f"machining    {r['machining_s']:.0f} s in layers, {r['single_pass_s']:.0f} s for one pass",
        ]
    if r["gouge_points"]:
        lines.append(
            f"gouge        {r['gouge_points']:,} control points where the concave radius is below Rc"
        )
    lines.append(
        f"time         {r['seconds']:.2f} s  (compensation {r['seconds_compensation']:.2f}, sampling "
        f"{r['seconds_sampling']:.2f}, interpolation {r['seconds_interpolation']:.2f}, envelope "
        f"{r['seconds_envelope']:.2f}, metrics {r['seconds_metrics']:.2f})"
    )
    return "\n".join(lines)


@main.command()
@click.argument(
    "cubes",
    nargs=-1,
    required=True,
    metavar="CUBE...",
    type=click.Path(exists=True, file_okay=False, path_type=Path),
)
@click.option(
    "-o",
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write the plot of P-V against point count here (PNG). Default: no plot.",
)
@click.option(
    "--allow-different",
    is_flag=True,
    help="List cubes made under different conditions (surface, nose radius, feed, machine, "
    "compensation) instead of refusing them; the differences are flagged.",
)
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object (the rows) on stdout.")
def compare(cubes: tuple[Path, ...], out: Optional[Path], allow_different: bool, as_json: bool) -> None:
    """Compare program kinds on one part: tables (ring, mesh), spiral and D-path programs.

    Give the cubes of sweeps on the same part under the same conditions, e.g. a ring sweep
    and a spiral sweep: cubes whose surface, nose radius, feed (a swept feed or D-path
    spacing by its values), machine or compensation differ are refused, naming the
    difference (--allow-different lists them, flagged). Each cube's conditions are shown;
    for each point count of each cube (target N of a table sweep, the rule axis of a path
    sweep) its best feasible case is listed with its realised N and P-V, one block per
    program; -o draws P-V against point count, one line per program.

    \b
    Example:
      ftsweep sweep sinewave-ring && ftsweep sweep sinewave-spiral
      ftsweep compare outputs/sinewave-ring.zarr outputs/sinewave-spiral.zarr -o outputs/compare.png
    """
    from ftsweep.compare import CONDITIONS, compare_rows, differing, plot_compare
    from ftsweep.cube import CubeError
    from ftsweep.io import save_figure
    from ftsweep.select import SelectError

    try:
        rows, per_cube = compare_rows(list(cubes), allow_different)
    except (SelectError, CubeError) as exc:
        raise click.ClickException(str(exc)) from None
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        save_figure(plot_compare(rows).figure, out)
    differ = differing(per_cube)
    if as_json:
        _echo_json(
            {"rows": rows, "conditions": per_cube, "different": differ, "plot": str(out) if out else None}
        )
        return
    for label, cond in per_cube.items():
        shown = "; ".join(f"{c} {cond[c]}" + (" (differs)" if c in differ else "") for c in CONDITIONS)
        click.echo(f"conditions   {label}: {shown}")
    head = f"  {'program':<40s} {'target':>10s} {'actual N':>10s} {'P-V nm':>9s} {'RMS nm':>8s}"
    click.echo(head + f" {'interp nm':>9s}")
    for r in rows:
        click.echo(
            f"  {r['program']:<40s} {r['target']:10,.4g} {r['n_points']:10,d} {r['pv_nm']:9.2f} "
            f"{r['rms_nm']:8.2f} {r['pv_interp_nm']:9.2f}"
        )
    if out is not None:
        click.echo(f"plot         {out}")


@main.command("dpath")
@click.option(
    "--surface", default="concave_sphere", show_default=True, help="Surface catalog entry (the part)."
)
@click.option(
    "--machine", default="sts-xzc", show_default=True, help="Machine entry with X, Z, C axis limits."
)
@click.option(
    "--cutting", default="dpath-finish", show_default=True, help="Cutting entry (nose radius, rpm)."
)
@click.option(
    "--spacing-um",
    type=POSITIVE,
    help="Spacing h between cuts [µm]. Default: the cutting entry's feed.",
)  # noqa: E501
@click.option("--points-per-cut", type=click.IntRange(min=2), help="Points on every cut. Default: 201.")
@click.option("--zones", type=click.Choice(["1", "2", "4"]), help="Cutting zones per revolution. Default: 1.")
@click.option(
    "--offaxis-mm",
    type=POSITIVE,
    help="Distance of the part's centre from the C axis [mm]. Default: 30.",
)  # noqa: E501
@click.option(
    "--cut-angle-deg",
    type=FINITE,
    help="Direction of the cuts in the part's frame [deg from +x]. Default: 90 (along y).",
)  # noqa: E501
@click.option(
    "--transition-step-deg",
    type=POSITIVE,
    help="Largest C step in a transition [deg]. Default: 1.",
)  # noqa: E501
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
    from ftsweep import dstudy

    options = {
        "spacing_um": opts["spacing_um"],
        "points_per_cut": opts["points_per_cut"],
        "zones": int(opts["zones"]) if opts["zones"] else None,
        "offaxis_um": opts["offaxis_mm"] * 1e3 if opts["offaxis_mm"] else None,
        "cut_angle_deg": opts["cut_angle_deg"],
        "transition_step_deg": opts["transition_step_deg"],
    }
    _check_overwrite(opts["out"], opts["force"])
    progress = _progress("dpath", opts["as_json"])
    try:
        base = dstudy.default_case(opts["surface"], opts["machine"], opts["cutting"], options)
        summary = dstudy.study(base, opts["feed_mm_min"], not opts["no_spiral"], progress)
    except (CaseError, CatalogError, ValidationError, ValueError) as exc:
        raise click.ClickException(one_line(str(exc))) from None
    finally:
        _progress_done(progress)
    rpm = summary["optimised"]["spindle_rpm"]
    folder = opts["plot_dir"]
    folder.mkdir(parents=True, exist_ok=True)
    plots = [str(dstudy.plot_x_motion(summary["_programs"], rpm, folder / f"dpath-{base.surface}-x.png"))]
    if "_spiral_motion" in summary:
        out_z = folder / f"dpath-{base.surface}-z.png"
        plots.append(
            str(
                dstudy.plot_z_motion(summary["_spiral_motion"], summary["_programs"]["optimised"], rpm, out_z)
            )
        )  # noqa: E501
    result = dstudy.public(summary)
    result["plots"] = plots
    if opts["out"] is not None:
        result["program"] = _export_dpath(base, summary["optimised"], opts["out"], opts["force"])
    if opts["as_json"]:
        _echo_json(result)
        return
    for line in dstudy.text_lines(summary):
        click.echo(line)
    click.echo(f"plots        {', '.join(plots)}")
    if opts["out"] is not None:
        click.echo(f"program      {result['program']['path']} ({result['program']['lines']:,} lines t C X Z)")


def _check_overwrite(out: Optional[Path], force: bool) -> None:
    """Refuse, before any work, to replace an existing program or its sidecar without --force."""
    from ftsweep.files import ExportError, check_overwrite, sidecar_path

    if out is not None:
        try:
            check_overwrite((out, sidecar_path(out)), force)
        except ExportError as exc:
            raise click.ClickException(str(exc)) from None


def _export_dpath(base: Case, record: dict[str, Any], out: Path, force: bool) -> dict[str, Any]:
    """Export the optimised program of ``dpath`` (refusing to replace files without --force)."""
    from ftsweep import dstudy, program
    from ftsweep.case import resolve_specs
    from ftsweep.files import ExportError, check_overwrite, sidecar_path

    side = sidecar_path(out)
    try:
        check_overwrite((out, side), force)
        case = dstudy.d_case(base, "optimised")
        meta = program.export_dpath(out, side, case, resolve_specs(case), record, {})
    except (ExportError, CaseError) as exc:
        raise click.ClickException(str(exc)) from None
    return {"path": str(out), "sidecar": str(side), "lines": meta["n_points"]}


@main.command("fresnel")
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
    from ftsweep import fstudy
    from ftsweep.files import ExportError, sidecar_path

    keys = ("facet_height_um", "points_per_turn", "deviation_deg", "compensation", "scheme", "safety")
    inp = fstudy.inputs(opts["surface"], opts["machine"], opts["cutting"], **{k: opts[k] for k in keys})
    out = opts["out"]
    _check_overwrite(out, opts["force"])
    progress = _progress("timesteps (turns)", opts["as_json"])
    try:
        summary = fstudy.study(inp, progress=progress)
        _progress_done(progress)
        plots = [str(p) for p in fstudy.plot(summary, opts["plot_dir"])]
        if out is not None:
            fstudy.export(summary, out, sidecar_path(out), inp)
    except (CatalogError, ExportError, ValidationError, ValueError) as exc:
        raise click.ClickException(one_line(str(exc))) from None
    finally:
        _progress_done(progress)
    result = fstudy.public(summary)
    result["plots"] = plots
    if out is not None:
        result["program"] = {"path": str(out), "sidecar": str(sidecar_path(out)), "lines": result["n_points"]}
    _print_fresnel(result, fstudy.text_lines(summary), opts["as_json"])


def _print_fresnel(result: dict[str, Any], lines: list[str], as_json: bool) -> None:
    if as_json:
        _echo_json(result)
        return
    for line in lines:
        click.echo(line)
    click.echo(f"plots        {', '.join(result['plots'])}")
    if "program" in result:
        click.echo(f"program      {result['program']['path']} ({result['n_points']:,} lines t C X Y Z)")


if __name__ == "__main__":  # pragma: no cover
    main()
