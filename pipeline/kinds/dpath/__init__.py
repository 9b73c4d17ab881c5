"""D-shaped slow-tool-servo paths ([5]): the kind, its planner and simulation, its study and
figures.

:class:`DPathKind` is the kind's class (entry point ``dpath`` of group ``ftsweep.kinds``); this
face loads no kernel: each method imports what it runs (:mod:`ftsweep.kinds.dpath.kind` and
the modules named there) when first called, and its ``ftsweep dpath`` command
(:mod:`ftsweep.kinds.dpath.command`) imports its study when it runs.
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
from ftsweep.kinds.dpath.names import OPTIONS

if TYPE_CHECKING:
    from ftsweep.engine.case import Case, Request
    from ftsweep.engine.planning import ResolvedCase
    from ftsweep.engine.record import Timer
    from ftsweep.engine.result import Quantity

__all__ = ["DPathKind"]

# its whole-process benchmark: the seed example, then its exported program ([5]) verified
_DPATH_OUT = ("dpath", "-o", "{dir}/d.txt")
_DPATH_OUT_LABEL = "ftsweep dpath -o (+ its 1M-line program)"


class DPathKind(ProgramKind):
    """A D-shaped slow-tool-servo program ([5]): straight parallel cuts over an off-axis part,
    one per revolution, joined by transitions outside it."""

    name: ClassVar[str] = "dpath"
    noun: ClassVar[str] = "D-path program"
    sweeps: ClassVar[str] = "D-path sweeps"
    axes: ClassVar[tuple[Axis, ...]] = (
        Axis("spacing_um", "um", "spacing between the D path's cuts", feed="is"),
        Axis("points_per_cut", "1", "points on every cut of the D path", count=True),
    )
    pitches: ClassVar[tuple[str, str]] = ("dphi_deg", "ds_um")
    options: ClassVar[tuple[str, ...]] = OPTIONS
    machine: ClassVar[str] = "sts-xzc"
    cutting: ClassVar[str] = "dpath-finish"
    aspect_units: ClassVar[str] = "um/deg"
    options_key: ClassVar[Optional[str]] = "dpath"
    options_dumped_unset: ClassVar[bool] = True
    description: ClassVar[str] = "a D-path program ([5]): straight cuts over an off-axis part"
    exports_as: ClassVar[str] = (
        "lines t [s] C [deg] X [mm] Z [mm] (FILE.txt), or a controller's dialect (--dialect)"
    )
    predict_help: ClassVar[str] = (
        "A D-path program (--layout dpath, [5]) cuts the off-axis part along straight lines "
        "--spacing-um apart, --points-per-cut each, joined by quintic transitions outside it; give a "
        "machine with X, Z and C limits and its cutting entry (e.g. --machine sts-xzc --cutting "
        "dpath-finish). `ftsweep dpath` studies both transitions and the spiral beside it."
    )
    examples: ClassVar[tuple[str, ...]] = (
        "ftsweep predict --surface concave_sphere --layout dpath --spacing-um 20 --machine sts-xzc "
        "--cutting dpath-finish",
    )
    bench_rows: ClassVar[tuple[BenchRow, ...]] = (
        BenchRow("ftsweep dpath (seed example)", ("dpath", "--json", "--plots", "{dir}")),
        BenchRow(_DPATH_OUT_LABEL, (*_DPATH_OUT, "--json", "--plots", "{dir}", "--force")),
        BenchRow(
            "verify 1M-line D-path program", ("verify", "{dir}/d.txt", "--json"), 3, needs=_DPATH_OUT_LABEL
        ),
    )

    @property
    def request(self) -> type[Request]:
        from ftsweep.kinds.dpath.request import DPathRequest

        return DPathRequest

    @property
    def fields(self) -> tuple[Quantity, ...]:
        from ftsweep.kinds.dpath import kind

        return kind.FIELDS

    def file_format(self) -> FileFormat:
        from ftsweep.kinds.dpath.format import dpath_format

        return dpath_format()

    def request_at(self, spec: SweepView, point: Mapping[str, float]) -> Request:
        from ftsweep.kinds.dpath import kind

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
        from ftsweep.kinds.dpath import kind

        return kind.feed(case, cutting, nose_radius_um, surface_spec, catalog_folder, program)

    def plan(self, planning: Planning) -> tuple[Any, dict[str, Any]]:
        from ftsweep.kinds.dpath import kind

        return kind.plan(planning)

    def record_fields(self, rcase: ResolvedCase) -> dict[str, Any]:
        from ftsweep.kinds.dpath import kind

        return kind.record_fields(rcase)

    def cost(
        self, case: Case, surface_spec: Any, catalog_folder: Optional[Path], feed_um: float
    ) -> tuple[float, Hashable]:
        from ftsweep.kinds.dpath import kind

        return kind.cost(case, surface_spec, catalog_folder, feed_um)

    def simulation(self, inputs: Simulating, timer: Timer) -> Simulation:
        # the D-path engine (ftsweep.kinds.dpath.program, stages.dpath) is imported where a D
        # path is simulated, not by every command that lists the kinds
        from ftsweep.kinds.dpath.program import DPathSimulation

        return DPathSimulation(inputs, timer)

    def pitch_text(self, record: Mapping[str, Any]) -> str:
        from ftsweep.kinds.dpath import kind

        return kind.pitch_text(dict(record))

    def point_text(self, program: Any, flat: int) -> str:
        from ftsweep.kinds.dpath import kind

        return kind.point_text(program, flat)

    def describe(self, record: Mapping[str, Any]) -> list[str]:
        from ftsweep.kinds.dpath import kind

        return kind.describe(dict(record))

    def check_sweep(self, spec: SweepView) -> None:
        from ftsweep.kinds.dpath import kind

        kind.check_sweep(spec)

    def warm_request(self) -> Request:
        from ftsweep.kinds.dpath.request import DPathRequest

        return DPathRequest(kind=self.name, spacing_um=2000.0, points_per_cut=11)

    def from_options(self, options: Mapping[str, Any]) -> tuple[dict[str, Any], list[str]]:
        from ftsweep.kinds.dpath.names import request_options

        return {"kind": self.name, **request_options(options)}, []

    def click_options(self) -> Optional[Decorator]:
        from ftsweep.kinds.dpath.options import dpath_options

        return dpath_options

    def commands(self) -> tuple[Any, ...]:
        from ftsweep.kinds.dpath.command import dpath_command

        return (dpath_command,)
