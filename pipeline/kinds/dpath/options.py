"""The command-line options of a D-path program ([5]), declared with its kind: ``ftsweep dpath``
and ``ftsweep predict --layout dpath`` take them."""

from __future__ import annotations

from typing import Any

import click

from ftsweep.options import FINITE, POSITIVE, stack


def dpath_options(f: Any) -> Any:
    """The options of a D-path program ([5]) shared by ``dpath`` and ``predict --layout dpath``."""
    options = [
        click.option(
            "--spacing-um", type=POSITIVE, help="D path: spacing h between cuts [µm]. Default: the feed."
        ),
        click.option(
            "--points-per-cut", type=click.IntRange(min=2), help="D path: points on every cut. Default: 201."
        ),
        click.option(
            "--zones", type=click.Choice(["1", "2", "4"]), help="D path: zones per revolution. Default: 1."
        ),
        click.option(
            "--offaxis-mm",
            type=POSITIVE,
            help="D path: distance of the part's centre from the C axis [mm]. Default: 30.",
        ),
        click.option(
            "--cut-angle-deg",
            type=FINITE,
            help="D path: direction of the cuts [deg from +x]. Default: 90 (along y).",
        ),
        click.option(
            "--transition-step-deg",
            type=POSITIVE,
            help="D path: largest C step in a transition [deg]. Default: 1.",
        ),
    ]
    return stack(options)(f)
