"""``ftsweep measure``: a measured part registered to its catalog design, its set-up terms with
their uncertainties and its form error (:mod:`ftsweep.tools.measure`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Optional

import click

from ftsweep.cli.common import CUBE, POSITIVE, echo_json


def registration_options(command: Any) -> Any:
    """The options that read a measurement and choose the set-up terms fitted."""
    for option in reversed(
        [
            click.option(
                "--units",
                default=None,
                help="Unit of the file's numbers where it does not state one: nm, um, mm or m "
                "(a point cloud may say '# units: mm' itself; an .npy map never does).",
            ),
            click.option(
                "--pixel-um", type=POSITIVE, default=None, help="Pixel pitch of an .npy height map [µm]."
            ),
            click.option("--no-decentre", is_flag=True, help="Fit no decentre (on a sphere it is a tilt)."),
            click.option(
                "--rotation", is_flag=True, help="Fit a rotation about the axis too (a freeform's)."
            ),
            click.option("--power", is_flag=True, help="Fit power (a radius error of the set-up) too."),
            click.option(
                "--bins",
                type=click.IntRange(8, 256),
                default=32,
                show_default=True,
                help="Error-map bins a side of the prediction (its resolution on the part).",
            ),
        ]
    ):
        command = option(command)
    return command


@click.command()
@click.argument("measurement", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--surface", default=None, help="The catalog surface the part was cut to (its design and aperture)."
)
@click.option("--cube", type=CUBE, default=None, help="The cube whose case cut the part (with --case).")
@click.option("--case", "case_name", default=None, help="That case: its coordinates or number.")
@click.option(
    "--program",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Or the program that cut it, in any dialect (as ftsweep predict --program reads it).",
)
@click.option("--machine", default=None, help="The program's machine (default: the one it names).")
@click.option("--cutting", default=None, help="The program's cutting entry (its tool).")
@registration_options
@click.option("--terms", type=click.IntRange(1, 66), default=15, show_default=True, help="Zernike terms.")
@click.option(
    "-o",
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Write the registered measurement here (NetCDF, .nc): the maps and the summary.",
)
@click.option(
    "--plots",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Write the maps (one colour scale) and the breakdown's bar chart here (PNG).",
)
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object on stdout.")
def measure(measurement: Path, **opts: Any) -> None:
    """Register a measured part to its design and say its form error.

    The measurement (a point cloud .csv/.txt/.xyz, an .npy, NetCDF, ISO 25178-72 X3P or Zygo
    .datx height map) is fitted over the surface's aperture by least squares: piston, tilt
    and decentre, and on request rotation and power, each with its standard error. What is
    left is the part's form error: its P-V and RMS and its breakdown into Zernike terms (a
    circle) or Chebyshev products (a rectangle), in nm. Missing heights stay missing.

    Given what cut the part (--cube and --case, or --program), its predicted error is
    registered the same way and subtracted: the summary says the share of the form error the
    prediction explains, and what is left, term by term: the machine's share, which
    `ftsweep correct` takes out of the next cut.

    \b
    Examples:
      ftsweep measure part.csv --surface zernike_example --rotation
      ftsweep measure part.csv --cube outputs/c.zarr --case 12 --rotation --plots outputs/part
      ftsweep measure map.npy --units nm --pixel-um 5 --surface concave_sphere --no-decentre --power
    """
    from ftsweep.tools.measure import explain, prediction_of

    record = None
    surface = opts["surface"]
    if opts["cube"] is not None or opts["program"] is not None:
        surface, record = prediction_of(
            cube=opts["cube"],
            case=opts["case_name"],
            program=opts["program"],
            surface=surface,
            machine=opts["machine"],
            cutting=opts["cutting"],
            bins=opts["bins"],
        )
    if surface is None:
        raise click.UsageError("give the part's --surface, or what cut it (--cube and --case, or --program)")
    part = _measured(measurement, surface, opts)
    split = None if record is None else explain(part, record, terms=opts["terms"])
    _written(part, split, opts["out"], opts["plots"])
    summary = part.summary if split is None else {**part.summary, "explained": split.summary}
    if opts["as_json"]:
        echo_json(summary)
        return
    for line in measure_lines(part.summary) + ([] if split is None else explain_lines(split.summary)):
        click.echo(line)


def _measured(measurement: Path, surface: str, opts: dict[str, Any]) -> Any:
    from ftsweep.tools.measure import measure_part

    return measure_part(
        measurement,
        surface,
        units=opts["units"],
        pixel_um=opts["pixel_um"],
        decentre=not opts["no_decentre"],
        rotation=opts["rotation"],
        power=opts["power"],
        terms=opts.get("terms", 15),
    )


def _written(part: Any, split: Any, out: Optional[Path], plots: Optional[Path]) -> None:
    """The registered measurement to ``out`` (NetCDF, atomically) and its figures to ``plots``."""
    if out is None and plots is None:
        return
    from ftsweep.tools.measureviews import plot_maps, plot_terms, registered_dataset

    ds = registered_dataset(part, split)
    if out is not None:
        from ftsweep.store.io import write_texts_atomic

        write_texts_atomic({out: bytes(ds.to_netcdf())})
    if plots is not None:
        plots.mkdir(parents=True, exist_ok=True)
        plot_maps(ds, plots / "maps.png")
        plot_terms(ds, plots / "terms.png")


def measure_lines(s: dict[str, Any]) -> list[str]:
    """The registration as lines of text: the set-up terms ± their standard errors, the form
    error, and its five largest terms."""
    lines = [
        f"measurement  {s['measurement']} (sha256 {s['sha256'][:16]}…, units {s['units']})",
        f"surface      {s['surface']}: {s['points']:,} points in its aperture",
    ]
    for name, value in s["terms"].items():
        lines.append(f"{name:<14s} {value: .6g} ± {s['sigma'][name]:.2g}")
    lines.append(f"form error   P-V {s['pv_nm']:.1f} nm, RMS {s['rms_nm']:.1f} nm")
    largest = sorted(s["breakdown"], key=lambda t: -abs(t["nm"]))[:5]
    lines += [f"  {t['term']:<16s} {t['nm']: .1f} nm" for t in largest]
    for name, share in s.get("alike", {}).items():
        if share > ALIKE_WARNING:
            lines.append(
                f"warning      {name} is {100 * share:.0f} % a low-order form error on this design: "
                "the fit cannot tell them apart (fix it by a fiducial, or leave it out)"
            )
    return lines


# the share of a set-up term's column a low-order form error reproduces, above which it is said
ALIKE_WARNING = 0.9


def explain_lines(s: dict[str, Any]) -> list[str]:
    """What the prediction explains, as lines: the share, both RMS, the largest terms left."""
    lines = [
        f"explained    {100 * s['explained_share']:.0f} % of the form error's variance by the prediction "
        f"(RMS {s['explained_rms_nm']:.1f} nm), {100 * s['unexplained_share']:.0f} % left, "
        f"{100 * (1 - s['explained_share'] - s['unexplained_share']):.0f} % their covariance",
        f"unexplained  P-V {s['unexplained_pv_nm']:.1f} nm, RMS {s['unexplained_rms_nm']:.1f} nm "
        "(the machine's share)",
    ]
    largest = sorted(s["unexplained_terms"], key=lambda t: -abs(t["nm"]))[:5]
    return lines + [f"  {t['term']:<16s} {t['nm']: .1f} nm" for t in largest]
