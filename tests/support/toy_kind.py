"""A program kind defined outside the package, as a plug-in would define one: a square mesh
(equal pitches Δx = Δy) swept over its one pitch, exported as a plain-text program of its
compensated table (X, Y, Z per control point). It touches no module of ftsweep and adds its
own ``predict`` option (``--square-pitch-um``): the registry takes it through
:func:`ftsweep.registry.register` (an installed plug-in would declare an entry point of group
``ftsweep.kinds`` instead)."""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Any, ClassVar, Literal

import click
import numpy as np
from pydantic import PositiveFloat

from ftsweep.engine import result
from ftsweep.engine.case import Case, Request
from ftsweep.engine.contract import Axis, FileFormat, Planning, ProgramKind
from ftsweep.engine.cost import angular_samples
from ftsweep.engine.lines import LineSimulation
from ftsweep.engine.planning import control_table
from ftsweep.exports import files
from ftsweep.inputs import catalogs
from ftsweep.options import POSITIVE
from ftsweep.simulate import resolve_case, run_case
from ftsweep.stages.layouts import grids as layouts
from ftsweep.stages.layouts.grids import Layout
from ftsweep.store.io import sidecar_path

NAME = "square"
MAGIC = "# toy square-mesh program"
COLUMNS = "X_mm Y_mm Z_mm"


class SquareRequest(Request):
    """A square mesh of pitch ``pitch_um`` [µm] in x and y."""

    kind: Literal["square"]
    pitch_um: PositiveFloat


def _layout(surface_spec: Any, pitch: float) -> Layout:
    half_w, half_h = catalogs.aperture_of(surface_spec).half_extent_um
    return layouts.mesh_layout(2.0 * half_w, 2.0 * half_h, pitch, pitch)._replace(kind=NAME)


def _plan(p: Planning) -> tuple[Layout, dict[str, Any]]:
    return _layout(p.surface_spec, p.case.layout.pitch_um), {}


def _cells(layout: Layout, rho0_um: float) -> float:
    return math.ceil(2.0 * math.pi * rho0_um / layout.pitch[0])


def _cost(case: Case, surface: Any, folder: Any, feed: float) -> tuple[float, Any]:
    layout = _layout(surface, case.layout.pitch_um)
    rho0 = catalogs.aperture_of(surface).outer_radius_um
    n_theta = angular_samples(_cells, layout, rho0, case.resolution)
    return 8.0 * layout.n_points + n_theta * rho0 / feed * case.resolution.points_per_feed, None


def _document(
    case: Case, specs: Any, chosen: dict[str, Any], extra: dict[str, Any], created: str
) -> tuple[list[str], files.DataLines, dict[str, Any]]:
    rcase = resolve_case(case, specs=specs)
    layout = rcase.layout
    table, _ = control_table(case, layout, specs.surface, rcase.nose_radius_um)
    x = layout.origin[0] + layout.pitch[0] * np.arange(layout.shape[0])
    y = layout.origin[1] + layout.pitch[1] * np.arange(layout.shape[1])
    gx, gy = np.meshgrid(x, y, indexing="ij")
    lines = files.DataLines.of(gx.ravel() * 1e-3, gy.ravel() * 1e-3, table.ravel() * 1e-3)
    meta = {
        "generator": "toy",
        "created": created,
        "layout": NAME,
        "n_points": layout.n_points,
        "shape": list(layout.shape),
        "pv_nm": chosen["pv_nm"],
        **extra,
        "selection": chosen,
        "case": case.model_dump(mode="json"),
        "catalog_entries": files.recorded_entries(specs),
    }
    head = [f"{MAGIC} (bilinear in X and Y)", f"# points: {layout.n_points}"]
    return head, lines, meta


def _export(
    out: Path,
    side: Path,
    case: Case,
    specs: Any,
    chosen: dict[str, Any],
    extra: dict[str, Any],
    name: Any = None,
) -> dict[str, Any]:
    head, lines, meta = _document(case, specs, chosen, extra, files.now())
    return files.write_program(out, side, head, COLUMNS, lines, meta)


def _verify(path: Path, progress: Any, pv_tolerance_nm: Any, trust_plugins: bool) -> dict[str, Any]:
    doc = files.read_program_file(path, MAGIC, COLUMNS)
    meta = files.checked_sidecar(path, doc)
    case, specs = files.recorded_case_of(meta, sidecar_path(path), trust_plugins)
    planned = _document(case, specs, meta["selection"], files.recorded_extra(meta), meta["created"])
    files.check_document(path, doc, planned, meta, COLUMNS)
    table = doc.data[:, 2].reshape(meta["shape"]) * 1e3
    record = run_case(case, specs=specs, table=table, progress=progress)
    return files.checked_pv(path, meta, record, pv_tolerance_nm)


@functools.cache
def _format() -> FileFormat:
    return FileFormat(
        "square-mesh program",
        MAGIC,
        _export,
        _verify,
        lambda out, meta: [f"program      {out} ({meta['n_points']:,} lines {COLUMNS})"],
        lambda record: [f"program      {record['layout']}: {record['n_points']:,} points as re-planned"],
    )


# its one predict option: `ftsweep predict --layout square --square-pitch-um 5`
square_options = click.option("--square-pitch-um", type=POSITIVE, help="Square mesh: pitch Δx = Δy [µm].")


def _from_options(options: dict[str, Any]) -> tuple[dict[str, Any], list[str]]:
    pitch = options.get("square_pitch_um")
    if pitch is None:
        raise ValueError("a square mesh needs --square-pitch-um")
    return {"kind": NAME, "pitch_um": pitch}, []


class SquareKind(ProgramKind):
    """A square mesh swept over its one pitch."""

    name: ClassVar[str] = NAME
    noun: ClassVar[str] = "square mesh"
    sweeps: ClassVar[str] = "square-mesh sweeps"
    axes: ClassVar[tuple[Axis, ...]] = (Axis("pitch_um", "um", "pitch of the square mesh"),)
    pitches: ClassVar[tuple[str, str]] = ("pitch_actual_um", "pitch_actual_um")
    options: ClassVar[tuple[str, ...]] = ("square_pitch_um",)
    machine: ClassVar[str] = "fts-1m"
    cutting: ClassVar[str] = "reference"
    aspect_units: ClassVar[str] = "1"
    samples_spindle_angles: ClassVar[bool] = True
    description: ClassVar[str] = "a square mesh of one pitch (a test's kind)"
    exports_as: ClassVar[str] = "the tables' C header"

    @property
    def request(self) -> type[Request]:
        return SquareRequest

    @property
    def fields(self) -> tuple[Any, ...]:
        return (
            *result.TABLE,
            result.number("pitch_actual_um", "um", "realised pitch of the square mesh"),
            result.aspect_actual("1"),
            *result.SPINDLE,
        )

    def file_format(self) -> FileFormat:
        return _format()

    def request_at(self, spec: Any, point: Any) -> Request:
        return SquareRequest(kind=NAME, pitch_um=point["pitch_um"])

    def feed(
        self,
        case: Case,
        cutting: Any,
        nose_radius_um: float,
        surface_spec: Any,
        catalog_folder: Any,
        program: Any,
    ) -> float:
        return case.feed_of(cutting)

    def plan(self, planning: Planning) -> tuple[Any, dict[str, Any]]:
        return _plan(planning)

    def record_fields(self, rcase: Any) -> dict[str, Any]:
        layout = rcase.layout
        return {
            "table_rows": layout.shape[0],
            "table_cols": layout.shape[1],
            "pitch_actual_um": layout.pitch[0],
        }

    def cost(self, case: Case, surface_spec: Any, catalog_folder: Any, feed_um: float) -> tuple[float, Any]:
        return _cost(case, surface_spec, catalog_folder, feed_um)

    def simulation(self, inputs: Any, timer: Any) -> Any:
        return LineSimulation(inputs, timer)

    def pitch_text(self, record: Any) -> str:
        return f"Δx = Δy = {record['pitch_actual_um']:.4g} µm"

    def point_text(self, program: Any, flat: int) -> str:
        return f"point {flat}"

    def angular_cells(self, program: Any, rho0_um: float) -> float:
        return _cells(program, rho0_um)

    def warm_request(self) -> Request:
        return SquareRequest(kind=NAME, pitch_um=50.0)

    def click_options(self) -> Any:
        return square_options

    def from_options(self, options: Any) -> tuple[dict[str, Any], list[str]]:
        return _from_options(options)


SQUARE = SquareKind()
