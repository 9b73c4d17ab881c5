"""The command-line options of a Fresnel program ([2]), declared with its kind: ``ftsweep
predict --layout fresnel`` takes them."""

from __future__ import annotations

from typing import Any

import click

from ftsweep.options import FINITE, POSITIVE, stack


def fresnel_options(f: Any) -> Any:
    """The options of a Fresnel program ([2]) for ``predict --layout fresnel``."""
    options = [
        click.option("--facet-height-um", type=POSITIVE, help="Fresnel: facet height h [µm]. Default: 10."),
        click.option(
            "--points-per-turn",
            type=click.IntRange(min=8),
            help="Fresnel: control points K per turn. Default: 360.",
        ),
        click.option(
            "--deviation-deg",
            type=FINITE,
            help="Fresnel: rake face from the cutting direction [deg]. Default: 0.",
        ),
        click.option(
            "--safety", type=FINITE, help="Fresnel: safety factor K_s on the axis limits. Default: 1.25."
        ),
        click.option(
            "--control-points",
            type=click.Choice(["auto", "polar", "arc"]),
            help="Fresnel: control points polar about centroids (eqs. 5-6), by arc length (A.3), auto.",
        ),
        click.option(
            "--timing",
            type=click.Choice(["optimal", "paper", "constant"]),
            help="Fresnel: timesteps: least time under the limits (optimal), [2]'s eqs. 15-16 (paper), "
            "one constant step. Default: optimal.",
        ),
    ]
    return stack(options)(f)
