"""``ftsweep correct``: a measured part back into the next program — registered, explained
against its case's prediction, the unexplained error low-passed into a corrected target, swept
over gains and low-passes into a cube of the trade, and the best exported and signed
(:mod:`ftsweep.tools.correct`)."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path
from typing import Any, Optional

import click

from ftsweep.cli.common import COUNT, CUBE, echo_json, sign_options
from ftsweep.cli.measure import registration_options


@click.command()
@click.argument("measurement", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--cube", type=CUBE, required=True, help="The cube whose case cut the part.")
@click.option("--case", "case_name", required=True, help="That case: its coordinates or number.")
@click.option(
    "--plan-case",
    default=None,
    help="Plan the corrected cut as this case of the cube instead (a finer layout, say): the "
    "machine's error is the same. Default: the case that cut the part.",
)
@registration_options
@click.option(
    "--gain",
    "gains",
    type=click.FloatRange(0.0, 1.5, min_open=True),
    multiple=True,
    help="Gain g of the correction (repeat for a sweep axis). Default: 1.",
)
@click.option(
    "--terms",
    "kept",
    type=click.IntRange(4, 36),
    multiple=True,
    help="Terms of the unexplained error kept, the low-pass: Noll index on a circle, Chebyshev "
    "products by degree on a rectangle (repeat for a sweep axis). Default: 15.",
)
@click.option(
    "--folder",
    type=click.Path(file_okay=False, path_type=Path),
    required=True,
    help="Where the correction goes: catalogs/ with the corrected surface, corrected.yaml, "
    "corrected.zarr (the cube of the trade), registered.nc and the figures.",
)
@click.option(
    "-o",
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Export the best corrected case here (its kind's format), signed when a key is set.",
)
@click.option("--workers", type=COUNT, default=None, help="Worker processes of the local cluster.")
@sign_options
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object on stdout.")
def correct(measurement: Path, **opts: Any) -> None:
    """Plan the corrected cut of a measured part and predict what it leaves.

    The part (cut by case --case of --cube) is registered to its design, and its case's
    predicted error, registered the same way, is subtracted: what is left is the machine's
    share U. The corrected target is the design less g times U's first N terms but piston
    and tilt (a Zernike or Chebyshev low-pass the servo and the layout can follow), a surface
    entry that names the measurement's SHA-256 and the fit. The case is swept over every
    --gain × --terms into a cube on a local Dask cluster; each corrected case's residual
    (its own predicted error, what the target moved, and U) is predicted, and the smallest is
    exported with -o, signed with --sign-key: its sidecar and statement name the measurement.

    \b
    Examples:
      ftsweep correct part.csv --cube outputs/c.zarr --case 12 --rotation --folder outputs/fix
      ftsweep correct part.csv --cube outputs/c.zarr --case 12 --gain 0.5 --gain 1 \\
          --terms 6 --terms 15 --folder outputs/fix -o outputs/fix/corrected.h
    """
    from ftsweep.cli.measure import _measured, _written
    from ftsweep.tools.correct import correction_sweep, trade
    from ftsweep.tools.measure import explain, prediction_of
    from ftsweep.tools.select import open_cube

    gains, terms = list(opts["gains"]) or [1.0], list(opts["kept"]) or [15]
    folder: Path = opts["folder"]
    taken = [name for name in ("catalogs", "corrected.zarr") if (folder / name).exists()]
    if taken:
        raise click.ClickException(
            f"{folder} already holds a correction ({', '.join(taken)}): give another --folder, or remove it"
        )
    surface, record = prediction_of(cube=opts["cube"], case=opts["case_name"], bins=opts["bins"])
    part = _measured(measurement, surface, opts)
    split = explain(part, record)
    folder.mkdir(parents=True, exist_ok=True)
    _written(part, split, folder / "registered.nc", folder)
    out = correction_sweep(
        opts["cube"],
        opts["case_name"],
        folder,
        part,
        split,
        gains,
        terms,
        bins=opts["bins"],
        workers=opts["workers"],
        plan_case=opts["plan_case"],
    )
    found = trade(open_cube(out), part, split)
    _trade_written(found, folder)
    best = _best(found)
    summary: dict[str, Any] = {
        "measurement_sha256": part.summary["sha256"],
        "cube": str(out),
        "explained_share": split.summary["explained_share"],
        "uncorrected_rms_nm": found.attrs["uncorrected_rms_nm"],
        "trade": [
            {k: (float(v) if k != "correction_terms" else int(v)) for k, v in row.items()}
            for row in found.to_dataframe()
            .reset_index()[["correction_gain", "correction_terms", "residual_rms_nm", "residual_pv_nm"]]
            .to_dict("records")
        ],
        "best": best,
    }
    if opts["out"] is not None:
        summary["exported"] = _export(out, opts["out"], best, opts["sign_key"], opts["expires"])
    if opts["as_json"]:
        echo_json(summary)
        return
    for line in correct_lines(summary):
        click.echo(line)


def _trade_written(found: Any, folder: Path) -> None:
    """The trade as ``trade.nc`` (NetCDF, atomically) and ``trade.png`` in ``folder``."""
    from ftsweep.store.io import write_texts_atomic
    from ftsweep.tools.measureviews import plot_trade

    write_texts_atomic({folder / "trade.nc": bytes(found.to_netcdf())})
    plot_trade(found, folder / "trade.png")


def _best(found: Any) -> dict[str, Any]:
    """The corrected case of the smallest predicted residual RMS: its gain, terms and figures."""
    table = found.to_dataframe().reset_index().dropna(subset=["residual_rms_nm"])
    if table.empty:
        raise click.ClickException("no corrected case was computed: see `ftsweep status` of the cube")
    row = table.loc[table["residual_rms_nm"].idxmin()]
    return {
        "correction_gain": float(row["correction_gain"]),
        "correction_terms": int(row["correction_terms"]),
        "residual_rms_nm": float(row["residual_rms_nm"]),
        "residual_pv_nm": float(row["residual_pv_nm"]),
    }


def _export(
    cube: Path, out: Path, best: dict[str, Any], sign_key: Optional[str], expires: Optional[datetime]
) -> str:
    """Export (and sign) the best corrected case of the correction cube, named by its coordinates."""
    from ftsweep.tools.export import export
    from ftsweep.tools.query import coordinates_of
    from ftsweep.tools.select import open_cube

    ds = open_cube(cube)
    wanted = (best["correction_gain"], best["correction_terms"])
    for flat in range(int(ds["status"].size)):
        at = coordinates_of(ds, flat)
        if (at["correction_gain"], at["correction_terms"]) == wanted:
            named = " ".join(f"{axis}={value}" for axis, value in at.items())
            export(cube, out, index=named, sign_key=sign_key, expires=expires)
            return str(out)
    raise click.ClickException(f"the cube {cube} has no case of gain {wanted[0]:g} and {wanted[1]} terms")


def correct_lines(s: dict[str, Any]) -> list[str]:
    """The correction as lines: the measurement, the share explained, the trade, the best."""
    lines = [
        f"measurement  sha256 {s['measurement_sha256'][:16]}…; the prediction explains "
        f"{100 * s['explained_share']:.0f} % of its form error",
        f"uncorrected  residual RMS {s['uncorrected_rms_nm']:.2f} nm",
        f"trade        {s['cube']}:",
        "  gain  terms  residual RMS [nm]  P-V [nm]",
    ]
    for row in s["trade"]:
        lines.append(
            f"  {row['correction_gain']:4.2f}  {row['correction_terms']:5d}  "
            f"{row['residual_rms_nm']:17.2f}  {row['residual_pv_nm']:8.1f}"
        )
    b = s["best"]
    lines.append(
        f"best         gain {b['correction_gain']:g}, {b['correction_terms']} terms: "
        f"residual RMS {b['residual_rms_nm']:.2f} nm predicted"
    )
    if "exported" in s:
        lines.append(f"exported     {s['exported']}")
    return lines
