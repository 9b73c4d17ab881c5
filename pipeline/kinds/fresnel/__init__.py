"""Freeform Fresnel programs on an X-Y-Z-C lathe ([2]): the kind, its planner, its form simulation
and study.

:class:`FresnelKind` is the kind's class (entry point ``fresnel`` of group ``ftsweep.kinds``);
this face loads no kernel: each method imports what it runs (:mod:`ftsweep.kinds.fresnel.kind`
and the modules named there) when first called, and its ``ftsweep fresnel`` command
(:mod:`ftsweep.kinds.fresnel.command`) imports its study when it runs.
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
from ftsweep.kinds.fresnel.names import FRESNEL_FIELDS

if TYPE_CHECKING:
    from ftsweep.engine.case import Case, Request
    from ftsweep.engine.planning import ResolvedCase
    from ftsweep.engine.record import Timer
    from ftsweep.engine.result import Quantity

__all__ = ["FresnelKind"]


class FresnelKind(ProgramKind):
    """A freeform Fresnel program ([2]): the surface sliced into facets cut along a quasi-spiral
    on an X-Y-Z-C lathe."""

    name: ClassVar[str] = "fresnel"
    noun: ClassVar[str] = "Fresnel program"
    sweeps: ClassVar[str] = "Fresnel sweeps"
    axes: ClassVar[tuple[Axis, ...]] = (
        Axis("facet_height_um", "um", "height of every Fresnel facet"),
        Axis("points_per_turn", "1", "control points on every turn of the quasi-spiral", count=True),
        Axis("deviation_deg", "deg", "rake face turned from the cutting direction", signed=True),
    )
    pitches: ClassVar[tuple[str, str]] = ("dphi_deg", "ds_um")
    options: ClassVar[tuple[str, ...]] = FRESNEL_FIELDS
    machine: ClassVar[str] = "xyzc-nanoform"
    cutting: ClassVar[str] = "fresnel-finish"
    aspect_units: ClassVar[str] = "um/deg"
    options_key: ClassVar[Optional[str]] = "fresnel"
    options_dumped_unset: ClassVar[bool] = True
    bench_rows: ClassVar[tuple[BenchRow, ...]] = (
        BenchRow("ftsweep fresnel (chebyshev_example)", ("fresnel", "--json", "--plots", "{dir}")),
    )
    description: ClassVar[str] = (
        "a freeform Fresnel program ([2]): 4 axes, the surface's facets cut along a quasi-spiral"
    )
    exports_as: ClassVar[str] = "nothing: `ftsweep fresnel -o FILE.txt` writes its program"
    predict_help: ClassVar[str] = (
        "A Fresnel program (--layout fresnel, [2]) slices the surface into facets --facet-height-um "
        "high and cuts them along a quasi-spiral, --points-per-turn per turn, feed Δr per turn the "
        "--feed-um; its timesteps are optimised for the machine's X, Y, Z, C limits (e.g. --machine "
        "xyzc-nanoform --cutting fresnel-finish). P-V and RMS are the facets' (walls excluded); "
        "--compensation selects [2]'s exact (eq. 10), slope (eq. 12) or none."
    )
    examples: ClassVar[tuple[str, ...]] = (
        "ftsweep predict --surface chebyshev_example --layout fresnel --facet-height-um 10 "
        "--machine xyzc-nanoform --cutting fresnel-finish",
    )

    @property
    def request(self) -> type[Request]:
        from ftsweep.kinds.fresnel.request import FresnelRequest

        return FresnelRequest

    @property
    def fields(self) -> tuple[Quantity, ...]:
        from ftsweep.kinds.fresnel import kind

        return kind.FIELDS

    def file_format(self) -> FileFormat:
        from ftsweep.kinds.fresnel.format import fresnel_format

        return fresnel_format()

    def request_at(self, spec: SweepView, point: Mapping[str, float]) -> Request:
        from ftsweep.kinds.fresnel import kind

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
        from ftsweep.kinds.fresnel import kind

        return kind.feed(case, cutting, nose_radius_um, surface_spec, catalog_folder, program)

    def plan(self, planning: Planning) -> tuple[Any, dict[str, Any]]:
        from ftsweep.kinds.fresnel import kind

        return kind.plan(planning)

    def record_fields(self, rcase: ResolvedCase) -> dict[str, Any]:
        return {}  # the Fresnel simulation writes its own fields (ftsweep.kinds.fresnel.form)

    def cost(
        self, case: Case, surface_spec: Any, catalog_folder: Optional[Path], feed_um: float
    ) -> tuple[float, Hashable]:
        from ftsweep.kinds.fresnel import kind

        return kind.cost(case, surface_spec, catalog_folder, feed_um)

    def simulation(self, inputs: Simulating, timer: Timer) -> Simulation:
        from ftsweep.kinds.fresnel.form import FresnelSimulation

        return FresnelSimulation(inputs, timer)

    def pitch_text(self, record: Mapping[str, Any]) -> str:
        from ftsweep.kinds.fresnel import kind

        return kind.pitch_text(dict(record))

    def point_text(self, program: Any, flat: int) -> str:
        from ftsweep.kinds.fresnel import kind

        return kind.point_text(program, flat)

    def describe(self, record: Mapping[str, Any]) -> list[str]:
        from ftsweep.kinds.fresnel import kind

        return kind.describe(dict(record))

    def check_sweep(self, spec: SweepView) -> None:
        from ftsweep.kinds.fresnel import kind

        kind.check_sweep(spec)

    def warm_request(self) -> Request:
        from ftsweep.kinds.fresnel.request import FresnelRequest

        return FresnelRequest(kind=self.name, points_per_turn=16, facet_height_um=50.0)

    def click_options(self) -> Optional[Decorator]:
        from ftsweep.kinds.fresnel.options import fresnel_options

        return fresnel_options

    def commands(self) -> tuple[Any, ...]:
        from ftsweep.kinds.fresnel.command import fresnel_command

        return (fresnel_command,)
