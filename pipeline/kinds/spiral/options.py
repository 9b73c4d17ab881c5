"""The command-line options of a spiral program ([4]), declared with its kind: ``ftsweep
predict --layout spiral`` takes them."""

from __future__ import annotations

from typing import Any

import click

from ftsweep.options import FINITE, stack


def spiral_options(f: Any) -> Any:
    """The sampling rule and residual budget of a spiral program for ``predict``."""
    options = [
        click.option(
            "--points-per-rev", type=int, help="Spiral: constant-angle rule, points per revolution."
        ),
        click.option(
            "--arc-um", type=FINITE, help="Spiral: constant-arc rule, path length between points [µm]."
        ),
        click.option(
            "--chord-um",
            type=FINITE,
            help="Spiral: chord-error budget Δcho [µm] that places each next point.",
        ),
        click.option(
            "--residual-um",
            type=FINITE,
            help="Spiral: residual (cusp) budget Δres [µm]; the feed is the largest that keeps every cusp "
            "within it, from each radial section's curvature (instead of --feed-um).",
        ),
    ]
    return stack(options)(f)
