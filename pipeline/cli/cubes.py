"""The commands on cubes and exported files: ``select``, ``export``, ``verify``, ``report`` and
``compare`` (the signing keys they use: :mod:`ftsweep.cli.keys`)."""

from __future__ import annotations

import math
import sys
from datetime import datetime
from pathlib import Path
from typing import Any, Optional

import click

from ftsweep.cli.common import (
    ALLOW_INCOMPLETE,
    COUNT,
    CUBE,
    NON_NEGATIVE,
    POSITIVE,
    STORAGE_OPTIONS,
    TRUST_PLUGINS,
    DialectChoice,
    KindsHelp,
    cube_place,
    echo_json,
    guard_complete,
    local_output,
    progress_done,
    reported_errors,
    sign_options,
    stderr_progress,
    threads_option,
)


def _one_criterion(**options: Any) -> None:
    """Refuse, before any cube is opened, a command given no selection rule or more than
    one (each keyword is an option's parameter, named as the command line spells it)."""
    given = [f"--{name.replace('_', '-')}" for name, value in options.items() if value is not None]
    if len(given) != 1:
        names = [f"--{name.replace('_', '-')}" for name in options]
        got = f"got {' and '.join(given)}" if given else "got none"
        raise click.UsageError(f"give exactly one of {', '.join(names[:-1])} or {names[-1]} ({got})")


def _selection_text(chosen: dict[str, Any]) -> str:
    from ftsweep import registry

    pitch = registry.kind(chosen["layout"]).pitch_text(chosen)
    interp = (
        f"interpolation alone {chosen['pv_interp_nm']:.2f} nm"
        if math.isfinite(chosen["pv_interp_nm"])
        else "interpolation alone not simulated"
    )
    aspect = chosen.get("aspect_actual", math.nan)
    # path programs off the spindle's spiral (D paths, Fresnel) have no aspect ratio
    alpha = f" (α = {aspect:.4g})" if math.isfinite(aspect) else ""
    return "\n".join(
        [
            f"rule         {chosen['rule']}",
            f"case         {chosen['name']} (case number {chosen['index']})",
            f"layout       {chosen['layout']}: {chosen['n_points']:,} points, {pitch}{alpha}",
            f"P-V          {chosen['pv_nm']:.2f} nm (RMS {chosen['rms_nm']:.2f} nm, {interp})",
        ]
    )


@click.command()
@click.argument("cube_path", metavar="CUBE", type=CUBE)
@click.option("--budget-points", type=COUNT, help="Best aspect ratio at or under this many points.")
@click.option("--tolerance-nm", type=POSITIVE, help="Fewest points whose P-V meets this tolerance [nm].")
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object on stdout.")
@ALLOW_INCOMPLETE
@STORAGE_OPTIONS
def select(
    cube_path: str,
    budget_points: Optional[int],
    tolerance_nm: Optional[float],
    as_json: bool,
    allow_incomplete: bool,
    storage_options: tuple[str, ...],
) -> None:
    """Choose the layout for production from a sweep's cube (a folder or a URL).

    Only computed, feasible cases within the controller's capacity are ever chosen. With
    --budget-points: the lowest P-V at or under that many points. With --tolerance-nm: the
    smallest layout that meets the tolerance; when none does, say so and show the best.
    """
    _one_criterion(budget_points=budget_points, tolerance_nm=tolerance_nm)
    from ftsweep.store.cube import CubeError
    from ftsweep.tools.select import SelectError, choose, open_cube

    try:
        ds = open_cube(cube_place(cube_path, storage_options))
        guard_complete(ds["status"].values, allow_incomplete)
        chosen = choose(ds, budget_points, tolerance_nm)
    except (SelectError, CubeError) as exc:
        raise click.ClickException(str(exc)) from None
    if as_json:
        echo_json(chosen)
    else:
        click.echo(_selection_text(chosen))
    if chosen.get("met") is False:
        click.echo(f"tolerance    not met: no case reaches {tolerance_nm:g} nm", err=True)
        sys.exit(1)


@click.command(cls=KindsHelp)
@click.argument("cube_path", metavar="CUBE", type=CUBE)
@click.option("--budget-points", type=COUNT, help="Export the best layout at or under this many points.")
@click.option("--tolerance-nm", type=POSITIVE, help="Export the smallest layout meeting this P-V [nm].")
@click.option(
    "--case",
    "index",
    metavar="COORDINATES|NUMBER",
    help="Export this case: its coordinates, every axis of the cube ('points=950000,aspect=16', as "
    "select prints them), or its case number (the same case however the cube grows).",
)
@click.option(
    "-o",
    "--output",
    "out",
    required=True,
    type=click.Path(dir_okay=False),
    help="Header file to write (FILE.h, a local path); the sidecar FILE.json is written beside it.",
)
@click.option("--name", help="Prefix of the C identifiers. Default: the file name.")
@click.option(
    "--dialect",
    type=DialectChoice(),
    help="Language of a path program whose kind writes controllers' dialects: ftsweep's text lines, "
    "ISO STS G-code (Moore Nanotech), LinuxCNC G-code, Delta Tau PMAC PVT or SPLINE1 "
    "(docs/controllers.md). Default: the machine's controller entry's dialect (text when it "
    "declares none).",
)
@click.option(
    "--machine",
    metavar="NAME",
    help="Plan the chosen case for this catalog machine instead of the one the cube was swept for (its "
    "controller, capacity, units and limits), predict it there and state that P-V; refused, naming why, "
    "where the machine cannot run it. `ftsweep catalogs` lists the machines and their dialects.",
)
@click.option("--force", is_flag=True, help="Replace an existing header and sidecar.")
@sign_options
@TRUST_PLUGINS
@ALLOW_INCOMPLETE
@STORAGE_OPTIONS
def export(
    cube_path: str,
    budget_points: Optional[int],
    tolerance_nm: Optional[float],
    index: Optional[str],
    out: str,
    name: Optional[str],
    dialect: Optional[str],
    machine: Optional[str],
    force: bool,
    sign_key: Optional[str],
    expires: Optional[datetime],
    trust_plugins: bool,
    allow_incomplete: bool,
    storage_options: tuple[str, ...],
) -> None:
    """Export the chosen case of a cube as its kind's file (below, "Program kinds"), under a
    header of units, surface, tool, budgets and predicted P-V; `ftsweep verify FILE` checks
    any. A path program can be written in a controller's dialect (--dialect: ISO STS or
    LinuxCNC G-code under G93 inverse time, PMAC PVT or SPLINE1); its sidecar records the P-V
    of the program as written, at the controller's decimals.

    A table is stored as fixed-point integers (unit and type from the machine catalog) in
    the order the controller indexes it, with macros for the layout, pitches, origin, units,
    surface, cutting conditions, predicted P-V, generator and a CRC-32 of the table. A JSON
    sidecar holds the same metadata and the full case spec. Both are written atomically.
    Failed, pending, infeasible and over-capacity cases are refused.
    """
    _one_criterion(budget_points=budget_points, tolerance_nm=tolerance_nm, case=index)
    from ftsweep.store.cube import CubeError
    from ftsweep.tools import export as exp
    from ftsweep.tools.select import SelectError, current_status

    target = local_output(out, "the exported program")
    assert target is not None
    cube = cube_place(cube_path, storage_options)
    try:
        if index is None:  # a case given by its index is the same case whatever else is computed
            guard_complete(current_status(cube), allow_incomplete)
        meta = exp.export(
            cube,
            target,
            budget_points=budget_points,
            tolerance_nm=tolerance_nm,
            index=index,
            force=force,
            name=name,
            trust_plugins=trust_plugins,
            sign_key=sign_key,
            dialect=dialect,
            expires=expires,
            machine=machine,
        )
    except (exp.ExportError, SelectError, CubeError) as exc:
        raise click.ClickException(str(exc)) from None
    click.echo(_selection_text(meta["selection"]))
    moved = meta.get("planned_for")
    if isinstance(moved, dict):
        was = moved["cube"]
        click.echo(
            f"machine      {moved['machine']}: planned and predicted there (the cube's case, for "
            f"{was['machine']}: {was['n_points']:,} points, P-V {was['pv_nm']:.2f} nm)"
        )
    for line in exp.format_of_file(target).exported(target, meta):
        click.echo(line)
    click.echo(f"sidecar      {exp.sidecar_path(target)}")
    if meta.get("signature"):
        click.echo(f"signature    {exp.signature_path(target)} (key {meta['signature']})")


# verify --help's closing paragraphs: the origin, and the export ledger (click prints an
# epilog after the options)
# what verify's progress counts: the simulation runs in batches of spindle angles (each a ray
# of the part, model §5)
RESIMULATING = "re-simulating the file's commands, batches of spindle angles"

VERIFY_EPILOG = """\b
Origin (what the hashes above cannot prove: anyone can re-make them):
- with a trusted key (--trusted-key, or the config file's trusted_keys): the file must
  carry FILE.sig, an ed25519 signature of that key over a statement naming this file
  (name, length, digest), its sidecar's digest, the platform it was planned on, its
  sequence in the cube's export ledger and what it is for, not expired;
- without: the sidecar's recorded surface, machine and cutting entries must equal the
  local catalog's (--accept-recorded verifies against the recorded ones instead).
The output's origin line says which of the two was proved.

\b
Rollback: while the file's cube is reachable, the file must be the latest export of its
name in the cube's export ledger (an older export put back is refused, signed or not);
the output's latest line says so, or why it was not checked.
"""


@click.command(cls=KindsHelp, epilog=VERIFY_EPILOG)
@click.argument("header", metavar="FILE", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option(
    "--pv-tolerance-nm",
    type=NON_NEGATIVE,
    help="Largest allowed |re-simulated − predicted| P-V [nm]. Default: a table's unit (the "
    "quantisation bound) + 0.1 % of the P-V; a program's 0.01 nm + 0.1 %.",
)
@click.option(
    "--trusted-key",
    "trusted",
    multiple=True,
    type=click.Path(dir_okay=False),
    help="A public key (PEM) whose signature the file must carry (repeat for several). Default: "
    "trusted_keys of the config file; none: the recorded entries are compared with the catalog.",
)
@click.option(
    "--accept-recorded",
    is_flag=True,
    help="Without a trusted key, verify against the entries the sidecar recorded even where the "
    "local catalog differs (proves consistency only).",
)
@click.option(
    "--compiled",
    is_flag=True,
    help="Also build ftsweep's C99 reference interpolator with the system's C compiler and check that "
    "it computes the simulator's commands from the file (a header's bilinear lookup, a PMAC PVT or "
    "SPLINE1 program's segments) at 10^5 points or more, to 1e-9 µm (docs/controllers.md).",
)
@click.option(
    "--expect-case",
    metavar="COORDINATES|NUMBER",
    help="Refuse the file unless it is this case of its cube ('points=950000,aspect=16', or its case "
    "number): a swapped file fails.",
)
@click.option("--expect-surface", help="Refuse the file unless it is for this catalog surface (by name).")
@click.option(
    "--across-platforms",
    is_flag=True,
    help="Allow one unit of the last printed digit (a table unit, 1 µs, 1e-6°, 1 nm) where the file was "
    "planned on another platform or records none. Without it (or a trusted key's signature over the "
    "platform) every number must be exactly as re-planned: the file does not choose its rule.",
)
@TRUST_PLUGINS
@threads_option
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object on stdout.")
def verify(
    header: Path,
    pv_tolerance_nm: Optional[float],
    trusted: tuple[str, ...],
    accept_recorded: bool,
    compiled: bool,
    expect_case: Optional[str],
    expect_surface: Optional[str],
    across_platforms: bool,
    trust_plugins: bool,
    as_json: bool,
) -> None:
    """Check an exported file as the machine will read it, against the program its sidecar's
    case plans: a controller header (FILE.h) or a path program (FILE.txt), layered or not, of
    any kind (below, "Program kinds").

    The first lines say what the file is for (cube and case, surface, machine, cutting,
    compensation, dialect, points, predicted P-V; who signed it when, until when);
    --expect-case and --expect-surface refuse another file.

    \b
    Exit 0 only if everything the machine will use checks out:
    - the CRC-32 over every line the machine reads, the sidecar's SHA-256 of the file and
      the file's SHA-256 of the sidecar;
    - the file is exactly what export writes for the recorded case: every macro value (no
      comment or expression inside one), every header and layer/segment line; every table
      cell and every program number equal to the re-planned one; within one table unit and
      1 µs, 1e-6° and 1 nm only where the file was planned on another platform (ftsweep,
      numpy, numba, llvmlite, CPU) or records none and --across-platforms asks for it or a
      trusted key signed that platform (the re-planned line says which rule applied);
    - a program of several axes: every line within the machine's axis limits;
    - a program whose kind re-simulates it: the P-V re-simulated from the file as stored
      within the tolerance of the P-V predicted at export.
    Otherwise exit 1 naming the first difference: do not load that file. Files are data: a
    plug-in surface they name runs only if the local catalog declares it (--trust-plugins).
    """
    from ftsweep.engine.case import CaseError
    from ftsweep.inputs.catalogs import CatalogError
    from ftsweep.tools import export as exp

    expect = {"case": expect_case, "surface": expect_surface}
    progress = stderr_progress(RESIMULATING, as_json)
    with reported_errors(progress, exp.ExportError, CaseError, CatalogError):
        record = exp.verify(
            header,
            progress,
            pv_tolerance_nm,
            trust_plugins,
            trusted,
            accept_recorded,
            compiled,
            expect,
            across_platforms,
        )
    if as_json:
        echo_json(record)
    else:
        _print_verified(header, record, compiled)


def _print_verified(header: Path, record: dict[str, Any], compiled: bool) -> None:
    """verify's lines: what the file is for first, then what was checked, the rule that judged
    its numbers, the compiled reference's agreement and its origin."""
    from ftsweep.tools import export as exp

    for line in [*exp.purpose_lines(record), *exp.format_of_file(header).verified(record)]:
        click.echo(line)
    click.echo(exp.replanned_line(record))
    click.echo(f"latest       {record['latest']}")
    click.echo(f"in cube      {record['in_cube']}")
    if compiled and "compiled_axes" in record:
        # a program: every axis the file moves, C in degrees, lengths in µm
        unit = {"C": (1e-3, "deg")}
        parts = [
            f"{a.replace('_simulated', ' as simulated')} {d * unit.get(a, (1.0, ''))[0]:.2g} "
            f"{unit.get(a, (1.0, 'µm'))[1]}"
            for a, (d, _) in record["compiled_axes"].items()
        ]
        click.echo(
            f"compiled     the C reference reads the file as its controller does and agrees with the "
            f"simulator on every axis at {record['compiled_points']:,} points: largest differences "
            f"{', '.join(parts)}, each within its rounding bound: ok"
        )
    elif compiled:
        click.echo(
            f"compiled     the C reference gives the simulator's commands at {record['compiled_points']:,} "
            f"{record['compiled_what']}: largest difference {record['compiled_max_diff_um']:.3g} µm "
            f"(bound {record['compiled_bound_um']:g} µm) ok"
        )
    click.echo(exp.origin_line(record))


@click.command()
@click.argument("cube_path", metavar="CUBE", type=CUBE)
@click.option(
    "-o",
    "--out",
    "out_dir",
    type=click.Path(file_okay=False),
    help="Folder for the figures and index.html. Default: <cube>-report beside a local cube, "
    "outputs/<cube>-report for a URL.",
)
@click.option(
    "--budget-points",
    type=COUNT,
    help="Map the case export chooses for this budget: the best layout at or under this many points.",
)
@click.option(
    "--tolerance-nm", type=POSITIVE, help="Map the smallest layout meeting this P-V [nm], as export."
)
@click.option(
    "--case",
    "index",
    metavar="COORDINATES|NUMBER",
    help="Case for the error map and spectrum ('points=950000,aspect=16', or its case number). Default "
    "(none of the three): the case last exported from the cube (its export ledger), else the best at "
    "the largest budget.",
)
@click.option(
    "--map-bins",
    type=click.IntRange(min=8),
    default=160,
    show_default=True,
    help="Bins per side of the error map.",
)
@TRUST_PLUGINS
@ALLOW_INCOMPLETE
@STORAGE_OPTIONS
def report(
    cube_path: str,
    out_dir: Optional[str],
    budget_points: Optional[int],
    tolerance_nm: Optional[float],
    index: Optional[str],
    map_bins: int,
    trust_plugins: bool,
    allow_incomplete: bool,
    storage_options: tuple[str, ...],
) -> None:
    """Figures of a sweep's cube and one HTML page that shows them with its metadata.

    P-V against point count and against aspect ratio (optimum marked), a heat map of P-V,
    the error map of the chosen case over the part and its W command spectrum with the servo
    bandwidth. The chosen case is the one export chooses with the same --budget-points,
    --tolerance-nm or --case. The error map needs a re-simulation of that case, which shows
    progress.
    """
    from ftsweep.engine.case import CaseError
    from ftsweep.store.cube import CubeError
    from ftsweep.tools.report import make_report
    from ftsweep.tools.select import SelectError, current_status

    if sum(v is not None for v in (budget_points, tolerance_nm, index)) > 1:
        raise click.UsageError("give at most one of --budget-points, --tolerance-nm and --case")
    try:
        guard_complete(current_status(cube_place(cube_path, storage_options)), allow_incomplete)
    except (CubeError, SelectError) as exc:
        raise click.ClickException(str(exc)) from None
    progress = stderr_progress("error map")
    click.echo("plotting the cube; re-simulating the chosen case for its error map ...", err=True)
    try:
        paths = make_report(
            cube_place(cube_path, storage_options),
            local_output(out_dir, "the report"),
            index,
            map_bins,
            progress,
            trust_plugins,
            budget_points,
            tolerance_nm,
        )
    except (CubeError, SelectError, CaseError) as exc:
        raise click.ClickException(str(exc)) from None
    finally:
        progress_done(progress)
    for name, path in paths.items():
        click.echo(f"{name:14s} {path}")


@click.command(cls=KindsHelp)
@click.argument(
    "cubes",
    nargs=-1,
    required=True,
    metavar="CUBE...",
    type=CUBE,
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
    "compensation, resolution) instead of refusing them; the differences are flagged.",
)
@click.option(
    "--as-recorded",
    is_flag=True,
    help="Show the cubes' P-V as recorded, each kind on its own spindle-angle sampling, instead of "
    "simulating the rows of the kinds that sample by their cells again on the finest sampling among them.",
)
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object (the rows) on stdout.")
@ALLOW_INCOMPLETE
@STORAGE_OPTIONS
def compare(
    cubes: tuple[str, ...],
    out: Optional[Path],
    allow_different: bool,
    as_recorded: bool,
    as_json: bool,
    allow_incomplete: bool,
    storage_options: tuple[str, ...],
) -> None:
    """Compare program kinds on one part (below, "Program kinds").

    Give the cubes of sweeps on the same part under the same conditions: cubes whose
    surface, nose radius, feed (a swept feed or cut spacing by its values), machine or
    compensation differ are refused, naming the difference (--allow-different lists them,
    flagged). Each cube's conditions are shown; for each point count of each cube (target N
    of a sweep over aspect ratios, the rule axis of a path sweep) its best feasible case is
    listed with its realised N and P-V, one block per program; -o draws P-V against point
    count, one line per program.

    The kinds that sample the spindle's angles by their own cells (a table's cells, a path's
    densest revolution) are simulated again on the finest sampling among them (their cube's
    P-V shown as "recorded"; --as-recorded skips this).

    \b
    Example:
      ftsweep sweep sinewave-ring && ftsweep sweep sinewave-spiral
      ftsweep compare outputs/sinewave-ring.zarr outputs/sinewave-spiral.zarr -o outputs/compare.png
    """
    from ftsweep.engine.case import CaseError
    from ftsweep.store.cube import CubeError
    from ftsweep.store.io import save_figure
    from ftsweep.tools.compare import common_sampling, compare_rows, plot_compare
    from ftsweep.tools.select import SelectError, current_status

    progress = stderr_progress("re-simulating the cases at one angular sampling", as_json)
    try:
        for c in cubes:
            guard_complete(current_status(cube_place(c, storage_options)), allow_incomplete)
        rows, per_cube = compare_rows([cube_place(c, storage_options) for c in cubes], allow_different)
        n_theta = None if as_recorded else common_sampling(rows, progress=progress)
    except (SelectError, CubeError, CaseError) as exc:
        raise click.ClickException(str(exc)) from None
    finally:
        progress_done(progress)
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        save_figure(plot_compare(rows).figure, out)
    _print_compare(rows, per_cube, n_theta, out, as_json)


def _print_compare(
    rows: list[dict[str, Any]],
    per_cube: dict[str, Any],
    n_theta: Optional[int],
    out: Optional[Path],
    as_json: bool,
) -> None:
    from ftsweep.tools.compare import CONDITIONS, differing

    differ = differing(per_cube)
    if as_json:
        echo_json(
            {
                "rows": rows,
                "conditions": per_cube,
                "different": differ,
                "common_n_theta": n_theta,
                "plot": str(out) if out else None,
            }
        )
        return
    for label, cond in per_cube.items():
        shown = "; ".join(f"{c} {cond[c]}" + (" (differs)" if c in differ else "") for c in CONDITIONS)
        click.echo(f"conditions   {label}: {shown}")
    if n_theta is not None:
        click.echo(
            f"sampling     tables and spirals simulated on {n_theta:,} spindle angles (the finest of theirs)"
        )
    head = (
        f"  {'program':<40s} {'target':>10s} {'actual N':>10s} {'P-V nm':>9s} {'recorded':>9s} {'RMS nm':>8s}"
    )
    click.echo(head + f" {'interp nm':>9s} {'angles':>7s}")
    for r in rows:
        recorded = r.get("pv_recorded_nm")
        click.echo(
            f"  {r['program']:<40s} {r['target']:10,.4g} {r['n_points']:10,d} {r['pv_nm']:9.2f} "
            + (f"{recorded:9.2f} " if recorded is not None else f"{'–':>9s} ")
            + f"{r['rms_nm']:8.2f} {r['pv_interp_nm']:9.2f} "
            + (f"{r['n_theta']:7,d}" if r["n_theta"] is not None else f"{'–':>7s}")
        )
    if out is not None:
        click.echo(f"plot         {out}")
