"""Tables (model §2): ring and mesh layouts, their controller header, its C view, and the
first-order estimate of a sweep plane.

:class:`RingKind` and :class:`MeshKind` are the kinds' classes (entry points ``ring`` and
``mesh`` of group ``ftsweep.kinds``); this face loads no kernel: each method imports what it
runs (:mod:`ftsweep.kinds.table.kind` and the modules named there) when first called.
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
    ReferenceBench,
    Simulating,
    Simulation,
    SweepView,
)
from ftsweep.kinds.table.names import NOUNS, PITCHES

if TYPE_CHECKING:
    import xarray

    from ftsweep.engine.case import Case, Request
    from ftsweep.engine.planning import ResolvedCase
    from ftsweep.engine.record import Timer
    from ftsweep.engine.result import Quantity

__all__ = ["MeshKind", "RingKind"]

# whole-process benchmark rows: a small and a ~950k-point ring predict, and the header of a
# ~950k-point case swept and exported, then verified. The 950k predict's surface and pitches
# (Δρ [µm], Δθ [deg]) are the case the brute-force reference is timed on beside it
_RING_950K_SURFACE, _RING_950K_PITCH = "sinewave2d", (3.04, 0.125)
_RING_5K = ("predict", "--surface", "sinewave2d", "--points", "5000", "--aspect", "8", "--json")
_RING_950K = (
    "predict",
    "--surface",
    _RING_950K_SURFACE,
    "--drho-um",
    str(_RING_950K_PITCH[0]),
    "--dtheta-deg",
    str(_RING_950K_PITCH[1]),
    "--json",
)
_RING_950K_1 = "predict 950k-point ring, 1 thread"
_RING_SWEEP = "sweep one 950k-point ring case (synchronous)"
_RING_EXPORT = "export its header"
_RING_ROWS = (
    BenchRow("predict 5k-point ring", _RING_5K, 3),
    BenchRow(_RING_950K_1, (*_RING_950K, "--threads", "1"), 3),
    BenchRow("predict 950k-point ring, all cores", _RING_950K, 3),
    BenchRow(
        _RING_SWEEP,
        (
            "sweep",
            "sinewave-ring-950k",
            "--out",
            "{dir}/ring.zarr",
            "--scheduler",
            "synchronous",
            "--restart",
        ),
    ),
    BenchRow(
        _RING_EXPORT,
        ("export", "{dir}/ring.zarr", "--case", "0", "-o", "{dir}/ring.h", "--force"),
        1,
        _RING_SWEEP,
    ),
    BenchRow("verify 950k-point ring header", ("verify", "{dir}/r.h", "--json"), 3, needs=_RING_EXPORT),
)

_POINTS = Axis("points", "1", "target number of control points", dumped_unset=True, count=True)


class RingKind(ProgramKind):
    """Rings in polar coordinates: Np points on every ring of pitch Δρ, Δθ = 360°/Np apart,
    planned from a target point count N and aspect ratio α = Δρ/Δθ, or from the pitches."""

    name: ClassVar[str] = "ring"
    noun: ClassVar[str] = NOUNS["ring"]
    sweeps: ClassVar[str] = "table sweeps"
    axes: ClassVar[tuple[Axis, ...]] = (
        _POINTS,
        Axis("aspect", "um/deg", "target aspect ratio Δρ/Δθ of the pitches", dumped_unset=True),
    )
    pitches: ClassVar[tuple[str, str]] = PITCHES["ring"]
    options: ClassVar[tuple[str, ...]] = ("drho_um", "dtheta_deg", "points", "aspect")
    machine: ClassVar[str] = "fts-1m"
    cutting: ClassVar[str] = "reference"
    aspect_units: ClassVar[str] = "um/deg"
    aspect_range: ClassVar[Optional[tuple[float, float]]] = (0.3, 400.0)
    samples_spindle_angles: ClassVar[bool] = True
    estimates: ClassVar[bool] = True
    has_reference: ClassVar[bool] = True
    bench_rows: ClassVar[tuple[BenchRow, ...]] = _RING_ROWS
    description: ClassVar[str] = "a table of rings in polar coordinates (Δρ, Δθ) for an FTS's own controller"
    exports_as: ClassVar[str] = "a C header of the table for the FTS controller (FILE.h), layered or not"
    predict_help: ClassVar[str] = (
        "A table (ring or mesh) is given by its pitches (--drho-um and --dtheta-deg for rings, --dx-um "
        "and --dy-um for meshes) or by a target point count and aspect ratio (--points, --aspect)."
    )
    examples: ClassVar[tuple[str, ...]] = (
        "ftsweep predict --surface sinewave2d --layout ring --drho-um 2 --dtheta-deg 0.5",
    )
    # the in-process benchmark case: its surface, points and aspect ratio
    _bench: ClassVar[tuple[str, str, float]] = ("ring-1M-a8", "sinewave2d", 8.0)
    _coarse_pitch: ClassVar[tuple[float, float]] = (50.0, 10.0)

    @property
    def request(self) -> type[Request]:
        from ftsweep.kinds.table.request import TableRequest

        return TableRequest

    @property
    def fields(self) -> tuple[Quantity, ...]:
        from ftsweep.engine import result

        first, second = self.pitches
        own = {"drho_um": ("um", "ring pitch Δρ"), "dtheta_deg": ("deg", "angular pitch Δθ")}
        own |= {"dx_um": ("um", "mesh pitch Δx"), "dy_um": ("um", "mesh pitch Δy")}
        return (
            *result.TABLE,
            result.number(first, *own[first]),
            result.number(second, *own[second]),
            result.aspect_actual(self.aspect_units),
            *result.SPINDLE,
        )

    def file_format(self) -> FileFormat:
        from ftsweep.kinds.table.verify import header_format

        return header_format()

    def request_at(self, spec: SweepView, point: Mapping[str, float]) -> Request:
        from ftsweep.kinds.table import kind

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
        return case.feed_of(cutting)

    def plan(self, planning: Planning) -> tuple[Any, dict[str, Any]]:
        from ftsweep.kinds.table import kind

        return kind.plan(planning)

    def record_fields(self, rcase: ResolvedCase) -> dict[str, Any]:
        from ftsweep.kinds.table import kind

        return kind.record_fields(rcase)

    def cost(
        self, case: Case, surface_spec: Any, catalog_folder: Optional[Path], feed_um: float
    ) -> tuple[float, Hashable]:
        from ftsweep.kinds.table import kind

        return kind.cost(case, surface_spec, catalog_folder, feed_um)

    def simulation(self, inputs: Simulating, timer: Timer) -> Simulation:
        from ftsweep.engine.lines import LineSimulation

        return LineSimulation(inputs, timer)

    def pitch_text(self, record: Mapping[str, Any]) -> str:
        return f"Δρ = {record['drho_um']:.4g} µm, Δθ = {record['dtheta_deg']:.4g}°"

    def point_text(self, program: Any, flat: int) -> str:
        from ftsweep.kinds.table import kind

        return kind.ring_point(program, flat)

    def angular_cells(self, program: Any, rho0_um: float) -> float:
        from ftsweep.kinds.table import kind

        return kind.ring_cells(program, rho0_um)

    def warm_request(self) -> Request:
        from ftsweep.kinds.table.request import TableRequest

        return TableRequest(kind=self.name, pitch=self._coarse_pitch)

    def describe(self, record: Mapping[str, Any]) -> list[str]:
        from ftsweep.kinds.table import kind

        return kind.describe(dict(record))

    def check_sweep(self, spec: SweepView) -> None:
        from ftsweep.kinds.table import kind

        kind.check_sweep(spec)

    def from_options(self, options: Mapping[str, Any]) -> tuple[dict[str, Any], list[str]]:
        from ftsweep.kinds.table import kind

        return kind.table_from_options(self.name, dict(options))

    def click_options(self) -> Optional[Decorator]:
        from ftsweep.kinds.table.options import table_options

        return table_options

    def bench_cases(self) -> dict[str, tuple[str, Request]]:
        from ftsweep.kinds.table.request import TableRequest

        label, surface, aspect = self._bench
        return {label: (surface, TableRequest(kind=self.name, points=1_000_000, aspect=aspect))}

    def estimate(
        self, spec: SweepView, coords: Mapping[str, Any], catalog_folder: Optional[Path]
    ) -> xarray.Dataset:
        from ftsweep.kinds.table.sweep_estimate import estimate_sweep

        return estimate_sweep(spec, coords, catalog_folder)

    def seed(
        self,
        surface_spec: Any,
        tolerance_nm: float,
        capacity: int,
        cusp_nm: float,
        aspect_range: tuple[float, float],
        catalog_folder: Optional[Path],
    ) -> tuple[float, float, float]:
        from ftsweep.kinds.table.sweep_estimate import seed_layout

        return seed_layout(
            surface_spec, self.name, tolerance_nm, capacity, cusp_nm, aspect_range, catalog_folder
        )

    def reference(self, rcase: ResolvedCase) -> dict[str, Any]:
        """The brute-force evaluation of a table case (:mod:`ftsweep.kinds.table.reference`),
        imported when asked for: a case does not load it."""
        from ftsweep.kinds.table.reference import reference_case

        return reference_case(rcase)

    def reference_bench(self) -> ReferenceBench:
        """The ~950k-point ring predict on one thread, and the case it simulates."""
        from ftsweep.engine.case import Case, program_request

        layout = program_request(kind=self.name, pitch=_RING_950K_PITCH)
        return ReferenceBench(_RING_950K_1, Case(surface=_RING_950K_SURFACE, layout=layout))


class MeshKind(RingKind):
    """A Cartesian mesh of pitches Δx, Δy: a ring's kind in Cartesian coordinates, with its own
    names, points, cells and options."""

    name: ClassVar[str] = "mesh"
    noun: ClassVar[str] = NOUNS["mesh"]
    axes: ClassVar[tuple[Axis, ...]] = (
        _POINTS,
        Axis("aspect", "1", "target aspect ratio Δx/Δy of the pitches", dumped_unset=True),
    )
    pitches: ClassVar[tuple[str, str]] = PITCHES["mesh"]
    options: ClassVar[tuple[str, ...]] = ("dx_um", "dy_um", "points", "aspect")
    aspect_units: ClassVar[str] = "1"
    aspect_range: ClassVar[Optional[tuple[float, float]]] = (0.08, 16.0)
    _bench: ClassVar[tuple[str, str, float]] = ("mesh-1M-a1", "lens_array", 1.0)
    _coarse_pitch: ClassVar[tuple[float, float]] = (50.0, 50.0)
    bench_rows: ClassVar[tuple[BenchRow, ...]] = ()  # the ring's rows time the tables' commands
    description: ClassVar[str] = "a table on a Cartesian mesh (Δx, Δy) for an FTS's own controller"
    predict_help: ClassVar[str] = ""  # the ring's paragraph covers both tables
    examples: ClassVar[tuple[str, ...]] = (
        "ftsweep predict --surface lens_array --layout mesh --dx-um 4 --dy-um 4 --json",
    )

    def pitch_text(self, record: Mapping[str, Any]) -> str:
        return f"Δx = {record['dx_um']:.4g} µm, Δy = {record['dy_um']:.4g} µm"

    def reference_bench(self) -> ReferenceBench:
        raise NotImplementedError("the mesh's reference is timed beside the ring's row")

    def point_text(self, program: Any, flat: int) -> str:
        from ftsweep.kinds.table import kind

        return kind.mesh_point(program, flat)

    def angular_cells(self, program: Any, rho0_um: float) -> float:
        from ftsweep.kinds.table import kind

        return kind.mesh_cells(program, rho0_um)
