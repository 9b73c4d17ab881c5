"""The planning tools: ``optimize`` (the tolerance loop), ``estimate`` (predicted P-V of a
sweep's cases without simulating them) and ``bench`` (timings)."""

from __future__ import annotations

import functools
import shlex
import sys
import time
from pathlib import Path
from typing import Any, Optional

import click

from ftsweep.cli.common import COUNT, FINITE, POSITIVE, KindChoice, echo_json, fail


@click.command()
@click.argument("surface", required=False)
@click.option(
    "--sweep",
    "sweep_name",
    metavar="NAME|PATH",
    help="Take surface, layout, machine, cutting and resolution from a sweep spec.",
)
@click.option(
    "--layout",
    type=KindChoice(),
    help="Program kind. Default: the surface's table method. The search spans aspect ratios, so "
    "it takes tables; a path program is refused saying so.",
)
@click.option("--tolerance-nm", type=POSITIVE, required=True, help="P-V the part must meet [nm].")
@click.option(
    "--start-points",
    type=FINITE,
    default=50_000,
    show_default=True,
    help="Point count of the first, coarse round.",
)
@click.option(
    "--machine", default="fts-1m", show_default=True, help="Machine of the catalog (`ftsweep catalogs`)."
)
@click.option(
    "--cutting",
    default="reference",
    show_default=True,
    help="Cutting entry of the catalog (`ftsweep catalogs`).",
)
@click.option(
    "-o",
    "--out",
    type=click.Path(file_okay=False),
    help="Cube recording every evaluation (a folder, or an fsspec URL with storage options from "
    "fsspec's configuration). Default: outputs/optimize-<surface>-<layout>.zarr.",
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
    out: Optional[str],
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
      ftsweep optimize sinewave2d --tolerance-nm 20
      ftsweep optimize --sweep lens-array-mesh --tolerance-nm 30
    """
    from ftsweep.tools.optimize import optimize as run_optimize

    resolution = None
    compensation = "exact"
    try:
        if sweep_name:
            surface, layout, machine, cutting, resolution, compensation = _of_sweep(sweep_name)
        if not surface:
            fail("give a SURFACE or --sweep")
        assert surface is not None

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
            on_eval=functools.partial(_print_evaluation, tolerance_nm),
            seed=seed,
        )
    except ValueError as exc:  # catalog and cube errors are ValueErrors
        raise click.ClickException(str(exc)) from None
    if as_json:
        echo_json(result)
    else:
        _print_optimum(result, tolerance_nm)
    if not result["met"]:
        sys.exit(1)


def _of_sweep(sweep_name: str) -> tuple[Any, ...]:
    """Surface, layout, machine, cutting, resolution and compensation of a sweep spec."""
    from ftsweep.sweeps.spec import load_sweep

    _, spec = load_sweep(sweep_name)
    return spec.surface, spec.layout, spec.machine, spec.cutting, spec.resolution, spec.compensation


def _print_evaluation(tolerance_nm: float, rec: dict[str, Any]) -> None:
    """One line on stderr per evaluation of the tolerance loop."""
    pv = f"P-V {rec['pv_nm']:.2f} nm" if rec["status"] == "done" else rec["message"]
    mark = "meets" if rec["status"] == "done" and rec["pv_nm"] <= tolerance_nm else ""
    click.echo(
        f"[{rec['stage']:>6s}] N≈{rec['points_target']:>9,.0f} α={rec['aspect_target']:<8.4g} {pv} {mark}",
        err=True,
    )


def _print_optimum(result: dict[str, Any], tolerance_nm: float) -> None:
    """The loop's verdict and the layout it found."""
    from ftsweep.cli.predict import summary_text

    verdict = "met" if result["met"] else "NOT met (best found below)"
    click.echo(
        f"tolerance    {tolerance_nm:g} nm: {verdict}; {result['evaluations']} evaluations "
        f"({result['reused']} reused) in {result['cube']}"
    )
    if result["answer"] is not None:
        click.echo(summary_text(result["answer"]))


@click.command()
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
    import numpy as np

    from ftsweep import registry
    from ftsweep.inputs.catalogs import CatalogError
    from ftsweep.store.cube import CubeError
    from ftsweep.sweeps.spec import coordinates, load_sweep
    from ftsweep.tools.query import agreement, best_aspect
    from ftsweep.tools.select import open_cube

    try:
        name, spec = load_sweep(sweep_name)
    except CatalogError as exc:
        raise click.ClickException(str(exc)) from None
    own = registry.kind(spec.layout)
    if not own.estimates:
        raise click.ClickException(
            f"ftsweep estimate needs a first-order estimate of the P-V (tables have one); a {spec.layout} "
            "sweep has none: run it (ftsweep sweep) or predict a case"
        )
    started = time.perf_counter()
    ds = own.estimate(spec, coordinates(spec), None)
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
        echo_json(out)
        return
    _print_estimate(out, name, registry.kind(spec.layout).aspect_units.replace("um", "µm").replace("1", ""))


def _print_estimate(out: dict[str, Any], name: str, unit: str) -> None:
    """The estimate's best aspect per point count, and its agreement with a simulated cube."""
    click.echo(f"estimated {out['layouts']} layouts of sweep '{name}' in {out['seconds'] * 1e3:.0f} ms")
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


@click.command()
@click.option("--case", "names", multiple=True, metavar="NAME", help="Only this case (repeatable).")
@click.option("--repeat", type=int, default=1, show_default=True, help="Runs per case; the fastest counts.")
@click.option(
    "-o",
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
    help="Also run this sweep (e.g. sinewave-ring, ~30 s on 2 workers) and report cases/s and the "
    "efficiency (summed case time over wall time × workers); then its 5 costliest cases again in "
    "this process, their seconds in the sweep beside alone.",
)
@click.option(
    "--workers",
    type=COUNT,
    multiple=True,
    help="Worker processes for --sweep on a local cluster; repeat for one run each "
    "(e.g. --workers 1 --workers 2). Default: 2.",
)
@click.option(
    "--scheduler",
    metavar="ADDRESS",
    help="Also run --sweep on the cluster of this Dask scheduler (e.g. tcp://127.0.0.1:8786), "
    "with the workers it has.",
)
@click.option(
    "--threads",
    type=COUNT,
    help="Threads for the '×N' rows of the 10⁶-point cases (a single case on N threads, as "
    "`predict --threads N`). Default: every usable core; 1 leaves those rows out.",
)
@click.option(
    "--cube-cases",
    type=COUNT,
    help="Also build a synthetic cube of this many cases (e.g. 100000: ~10 s) in a temporary "
    "folder and report its objects, and the seconds to open it and to select from it.",
)
@click.option(
    "--simulate-workers",
    "simulated",
    type=COUNT,
    multiple=True,
    help="With --sweep: replay the case times the run recorded through the same scheduling "
    "policy (tasks planned for N threads, longest first; each free thread takes the next) and "
    "print the predicted wall time and efficiency on N threads (repeatable, e.g. "
    "--simulate-workers 16 --simulate-workers 64); the measured run's own count is replayed too.",
)
@click.option(
    "--documented",
    is_flag=True,
    help="Only this: run what each time the README documents describes (the quickstart's "
    "lines, a first predict with and without numba's cache) as on a fresh install, and print "
    "the written figure beside the measured one (about 80 s on 2 cores).",
)
@click.option(
    "--reference",
    is_flag=True,
    help="Only this: the ~10⁶-point case a kind with a brute-force reference names, as a whole "
    "`predict` process on one thread, beside that reference's evaluation of the same case (straight "
    "from the model: every node against every arc within Rc), their P-V and how many times the "
    "whole predict the reference takes (about 100 s on 2 cores).",
)
def bench(
    names: tuple[str, ...],
    repeat: int,
    json_path: str,
    sweep_name: Optional[str],
    workers: tuple[int, ...],
    scheduler: Optional[str],
    threads: Optional[int],
    cube_cases: Optional[int],
    simulated: tuple[int, ...],
    documented: bool,
    reference: bool,
) -> None:
    """Time whole commands, the case runner per stage, and optionally a sweep.

    Prints the seconds of whole commands, each its own process (start-up, imports, kernel
    loading and exit included: what a user waits for): the help, then every kind's own rows
    (its predicts of about 5k and 10⁶ points on one thread and all cores, its programs
    exported and verified, its commands). Then the seconds per case of the published
    reference cases and every kind's 10⁶-point layouts split by stage, after a
    warm-up that pays numba's compile cost, on one thread (the 10⁶-point ones also on
    --threads). --sweep: a whole sweep's throughput on each --workers count and --scheduler;
    --cube-cases: a synthetic cube's objects and open and select times. Only --documented:
    the README's times beside their measurements; only --reference: the 950k-point predict
    beside a brute-force evaluation of its case. Nothing is asserted about time (about 3
    minutes without --sweep).

    \b
    Examples:
      ftsweep bench
      ftsweep bench --case ring-1M-a8 --repeat 3 --threads 1
      ftsweep bench --documented
      ftsweep bench --reference
    """
    if documented or reference:
        _bench_documented(json_path) if documented else _bench_reference(json_path, repeat)
        return
    if simulated and sweep_name is None:
        raise click.UsageError("--simulate-workers replays a run's case times: give --sweep too")
    from ftsweep.defaults import usable_cores
    from ftsweep.store.io import write_json_atomic
    from ftsweep.tools.bench import format_table, format_whole_process, run_benchmark, whole_process

    try:
        # whole processes first, while this one is small: after the in-process cases it keeps ~1 GB
        # (engine.allocator), and a child's fresh pages came ~30 % slower (chord spiral 3.0 -> 3.9 s)
        rows = whole_process(max(repeat, 3)) if not names else []
        result = run_benchmark(list(names) or None, repeat=repeat, threads=threads or usable_cores())
        result["whole_process"] = rows
    except ValueError as exc:
        raise click.ClickException(str(exc)) from None
    if result["whole_process"]:
        click.echo(format_whole_process(result["whole_process"]))
    click.echo(format_table(result))
    if sweep_name is not None:
        result.update(_bench_sweep(sweep_name, workers, scheduler, simulated))
    if cube_cases:
        result["cube_scale"] = _bench_cube_scale(cube_cases)
    write_json_atomic(json_path, result)
    click.echo(f"wrote {json_path}")


def _bench_cube_scale(cases: int) -> dict[str, Any]:
    """``bench --cube-cases``: a synthetic cube's objects and open and select times, printed."""
    from ftsweep.tools.cubescale import cube_scale, format_cube_scale

    scale = cube_scale(cases)
    click.echo(format_cube_scale(scale))
    return scale


def _bench_documented(json_path: str) -> None:
    """``bench --documented``: the README's times beside their measurements."""
    from ftsweep.store.io import write_json_atomic
    from ftsweep.tools.bench import ftsweep_command
    from ftsweep.tools.documented import documented_times, format_documented, measure, readme_text

    try:
        readme, where = readme_text()
        rows = documented_times(readme)
        click.echo(
            f"running the README's timed commands (README: {where}) in a fresh folder, "
            "numba's cache empty ...",
            err=True,
        )
        measured = measure(rows, shlex.join(ftsweep_command()))
    except ValueError as exc:
        raise click.ClickException(str(exc)) from None
    click.echo(format_documented(measured))
    write_json_atomic(json_path, {"documented": measured})
    click.echo(f"wrote {json_path}")


def _bench_reference(json_path: str, repeat: int) -> None:
    """``bench --reference``: the whole 950k-point predict beside the brute-force reference model."""
    from ftsweep.store.io import write_json_atomic
    from ftsweep.tools.bench import against_reference, format_against_reference

    click.echo(
        "timing the 950k-point predict, then the brute-force reference model on its case ...", err=True
    )
    try:
        row = against_reference(max(repeat, 3))
    except ValueError as exc:
        raise click.ClickException(str(exc)) from None
    click.echo(format_against_reference(row))
    write_json_atomic(json_path, {"against_reference": row})
    click.echo(f"wrote {json_path}")


def _replays(sweep_name: str, measured: dict[str, Any], simulated: tuple[int, ...]) -> list[dict[str, Any]]:
    """The last measured run's case times replayed on its own thread count and on each of
    ``simulated`` (:mod:`ftsweep.sweeps.replay`), printed."""
    from ftsweep.sweeps.replay import format_replay, replay

    counts = [measured["workers"], *(n for n in simulated if n != measured["workers"])]
    rows = replay(sweep_name, measured["case_seconds"], counts)
    click.echo(format_replay(rows))
    click.echo(
        f"measured on {measured['workers']} worker(s): wall {measured['wall_s']:.1f} s, efficiency "
        f"{measured['efficiency']:.2f} (the replay leaves out round trips and the cluster's start)"
    )
    return rows


def _side_by_side(sweep_name: str, measured: dict[str, Any]) -> list[dict[str, Any]]:
    """The costliest cases of the last measured run, in the sweep and alone, printed."""
    from ftsweep.tools.bench import format_side_by_side, side_by_side

    click.echo(f"running the 5 costliest cases of {sweep_name} again in this process ...", err=True)
    rows = side_by_side(sweep_name, measured["case_seconds"])
    click.echo(format_side_by_side(rows))
    return rows


def _bench_sweep(
    sweep_name: str, workers: tuple[int, ...], scheduler: Optional[str], simulated: tuple[int, ...]
) -> dict[str, Any]:
    """``bench --sweep``: the sweep on each worker count (and --scheduler), printed; the last
    run's case times replayed on the --simulate-workers counts, and its costliest cases alone."""
    from ftsweep.tools.bench import format_sweep, sweep_throughput

    runs = [(n, None) for n in (workers or (2,))] + ([(0, scheduler)] if scheduler else [])
    out: dict[str, Any] = {"sweeps": []}
    for n, address in runs:
        click.echo(f"running sweep {sweep_name} on {address or f'{n} local worker(s)'} ...", err=True)
        out["sweeps"].append(sweep_throughput(sweep_name, n, address))
        click.echo(format_sweep(out["sweeps"][-1]))
    if simulated:
        out["replays"] = _replays(sweep_name, out["sweeps"][-1], simulated)
    out["side_by_side"] = _side_by_side(sweep_name, out["sweeps"][-1])
    return out
