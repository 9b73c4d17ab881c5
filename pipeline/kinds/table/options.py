"""The command-line options of a ring or mesh table (model §2), declared with its kind:
``ftsweep predict`` takes them."""

from __future__ import annotations

from typing import Any

import click

from ftsweep.options import FINITE, stack


def table_options(f: Any) -> Any:
    """The pitches or the target of a ring or mesh table for ``predict``."""
    options = [
        click.option("--drho-um", type=FINITE, help="Ring pitch Δρ [µm] (ring layout)."),
        click.option(
            "--dtheta-deg",
            type=FINITE,
            help="Angular pitch Δθ [deg] (ring); rounded to the nearest 360/Np with a notice unless "
            "--strict.",
        ),
        click.option("--dx-um", type=FINITE, help="Mesh pitch Δx [µm] (mesh layout)."),
        click.option("--dy-um", type=FINITE, help="Mesh pitch Δy [µm] (mesh layout)."),
        click.option("--points", type=FINITE, help="Target number of control points N (with --aspect)."),
        click.option(
            "--aspect", type=FINITE, help="Target aspect ratio α: Δρ/Δθ [µm/deg] (ring) or Δx/Δy (mesh)."
        ),
    ]
    return stack(options)(f)
