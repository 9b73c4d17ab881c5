"""Spiral path programs ([4]): points along the tool's spiral from an error budget.

:class:`SpiralKind` is the kind's class (entry point ``spiral`` of group ``ftsweep.kinds``);
this face loads no kernel: each method imports what it runs (:mod:`ftsweep.kinds.spiral.kind`
and the modules named there) when first called.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Optional

from ftsweep.engine.contract import (
    Axis,
    BenchRow,
    Decorator,
    FileFormat,
    Planning,
    ProgramKind,
    Simulating,
    Simulation,
    SweepView,
)
from ftsweep.kinds.spiral.names import AXES

if TYPE_CHECKING:
    from ftsweep.engine.case import Case, Request
    from ftsweep.engine.planning import ResolvedCase
    from ftsweep.engine.record import Timer
    from ftsweep.engine.result import Quantity

__all__ = ["SpiralKind"]

# its whole-process benchmark: a chord-budget program of about a million points
_CHORD_1M = ("predict", "--surface", "sinewave2d", "--layout", "spiral", "--chord-um", "0.0013")


class SpiralKind(ProgramKind):
    """A spiral program: points along the tool's spiral placed by a constant angle, a constant
    arc length or a chord-error budget, the feed set by the case or a residual budget ([4])."""

    name: ClassVar[str] = "spiral"
    noun: ClassVar[str] = "spiral program"
    sweeps: ClassVar[str] = "spiral sweeps"
    axes: ClassVar[tuple[Axis, ...]] = (
        Axis("points_per_rev", "1", "points per revolution of the spiral", count=True),
        Axis("arc_um", "um", "path length between the spiral's points"),
        Axis("chord_um", "um", "chord-error budget of the spiral"),
        Axis("residual_um", "um", "residual (cusp) budget that sets the feed", feed="sets"),
    )
    pitches: ClassVar[tuple[str, str]] = ("dphi_deg", "ds_um")
    options: ClassVar[tuple[str, ...]] = AXES
    machine: ClassVar[str] = "fts-1m"
    cutting: ClassVar[str] = "reference"
    aspect_units: ClassVar[str] = "um/deg"
    samples_spindle_angles: ClassVar[bool] = True
    description: ClassVar[str] = (
        "a path program: points along the tool path, linear (or PVT, SPLINE1 cubics) between them"
    )
    exports_as: ClassVar[str] = (
        "plain-text lines C [deg] X [mm] Z [mm] (FILE.txt), layered or not, or a controller's "
        "dialect (--dialect)"
    )
    predict_help: ClassVar[str] = (
        "A spiral program (--layout spiral) places its points along the tool path by one rule: "
        "--points-per-rev (constant angle), --arc-um (constant path length) or --chord-um (each chord "
        "within the budget of the compensated path, [4]); its feed is --feed-um, the cutting entry's, or "
        "the largest the residual budget --residual-um allows."
    )
    examples: ClassVar[tuple[str, ...]] = (
        "ftsweep predict --surface sinewave2d --layout spiral --points-per-rev 500",
        "ftsweep predict --surface sinusoidal_mesh --layout spiral --chord-um 0.5 --residual-um 0.5 "
        "--cutting seed003 --machine sts-nanoform",
    )
    bench_rows: ClassVar[tuple[BenchRow, ...]] = (
        BenchRow("predict 990k-point chord spiral, 1 thread", (*_CHORD_1M, "--json", "--threads", "1")),
        BenchRow("predict 990k-point chord spiral, all cores", (*_CHORD_1M, "--json")),
    )

    @property
    def request(self) -> type[Request]:
        from ftsweep.kinds.spiral.request import SpiralRequest

        return SpiralRequest

    @property
    def fields(self) -> tuple[Quantity, ...]:
        from ftsweep.kinds.spiral import kind

        return kind.FIELDS

    def file_format(self) -> FileFormat:
        from ftsweep.kinds.spiral.format import spiral_format

        return spiral_format()

    def request_at(self, spec: SweepView, point: Mapping[str, float]) -> Request:
        from ftsweep.kinds.spiral import kind

        return kind.request_at(spec, dict(point))

    def feed(
        self,
        case: Case,
        cutting: Any,
        nose_radius_um: float,
        surface_spec: Any,
        catalog_folder: Optional[Path],
        program: Any,
    ) -> float:
        from ftsweep.kinds.spiral import kind

        return kind.feed(case, cutting, nose_radius_um, surface_spec, catalog_folder, program)

    def plan(self, planning: Planning) -> tuple[Any, dict[str, Any]]:
        from ftsweep.kinds.spiral import kind

        return kind.plan(planning)

    def record_fields(self, rcase: ResolvedCase) -> dict[str, Any]:
        from ftsweep.kinds.spiral import kind

        return kind.record_fields(rcase)

    def cost(
        self, case: Case, surface_spec: Any, catalog_folder: Optional[Path], feed_um: float
    ) -> tuple[float, Hashable]:
        from ftsweep.kinds.spiral import kind

        return kind.cost(case, surface_spec, catalog_folder, feed_um)

    def simulation(self, inputs: Simulating, timer: Timer) -> Simulation:
        from ftsweep.kinds.spiral import kind

        return kind.simulation(inputs, timer)

    def pitch_text(self, record: Mapping[str, Any]) -> str:
        from ftsweep.kinds.spiral import kind

        return kind.pitch_text(dict(record))

    def point_text(self, program: Any, flat: int) -> str:
        from ftsweep.kinds.spiral import kind

        return kind.point_text(program, flat)

    def describe(self, record: Mapping[str, Any]) -> list[str]:
        from ftsweep.kinds.spiral import kind

        return kind.describe(dict(record))

    def check_sweep(self, spec: SweepView) -> None:
        from ftsweep.kinds.spiral import kind

        kind.check_sweep(spec)

    def angular_cells(self, program: Any, rho0_um: float) -> float:
        """The segments of the most densely sampled revolution."""
        return float(program.max_points_per_rev)

    def warm_request(self) -> Request:
        from ftsweep.kinds.spiral.request import SpiralRequest

        return SpiralRequest(kind=self.name, points_per_rev=16)

    def click_options(self) -> Optional[Decorator]:
        from ftsweep.kinds.spiral.options import spiral_options

        return spiral_options
