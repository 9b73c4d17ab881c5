"""``ftsweep measure``: a measured part registered to its catalog design, its set-up terms with
their uncertainties and its form error (:mod:`ftsweep.tools.measure`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Optional

import click

from ftsweep.cli.common import POSITIVE, echo_json


@click.command()
@click.argument("measurement", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--surface", required=True, help="The catalog surface the part was cut to (its design and aperture)."
)
@click.option(
    "--units",
    default=None,
    help="Unit of the file's numbers where it does not state one: nm, um, mm or m "
    "(a point cloud may say '# units: mm' itself; an .npy map never does).",
)
@click.option("--pixel-um", type=POSITIVE, default=None, help="Pixel pitch of an .npy height map [µm].")
@click.option("--no-decentre", is_flag=True, help="Fit no decentre (on a sphere it is a tilt).")
@click.option("--rotation", is_flag=True, help="Fit a rotation about the axis too (a freeform's).")
@click.option("--power", is_flag=True, help="Fit power (a radius error of the set-up) too.")
@click.option("--terms", type=click.IntRange(1, 66), default=15, show_default=True, help="Zernike terms.")
@click.option("--json", "as_json", is_flag=True, help="Print exactly one JSON object on stdout.")
def measure(
    measurement: Path,
    surface: str,
    units: Optional[str],
    pixel_um: Optional[float],
    no_decentre: bool,
    rotation: bool,
    power: bool,
    terms: int,
    as_json: bool,
) -> None:
    """Register a measured part to its design and say its form error.

    The measurement (a point cloud .csv/.txt/.xyz, an .npy, NetCDF or ISO 25178-72 X3P height
    map) is fitted over the surface's aperture by least squares: piston, tilt and decentre,
    and on request rotation and power, each with its standard error. What is left is the
    part's form error: its P-V and RMS and its breakdown into Zernike terms (a circle) or
    Chebyshev products (a rectangle), in nm. Missing heights stay missing.

    \b
    Examples:
      ftsweep measure part.csv --surface zernike_example --rotation
      ftsweep measure map.npy --units nm --pixel-um 5 --surface concave_sphere --no-decentre --power
    """
    from ftsweep.tools.measure import measure_part

    part = measure_part(
        measurement,
        surface,
        units=units,
        pixel_um=pixel_um,
        decentre=not no_decentre,
        rotation=rotation,
        power=power,
        terms=terms,
    )
    if as_json:
        echo_json(part.summary)
        return
    for line in measure_lines(part.summary):
        click.echo(line)


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
    return lines
