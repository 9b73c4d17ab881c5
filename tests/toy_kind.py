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
from typing import Any, Literal

import click
import numpy as np
from pydantic import PositiveFloat

from ftsweep.engine import result
from ftsweep.engine.case import Case, Request
from ftsweep.engine.contract import Axis, Planning, ProgramKind
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
    case: Case, specs: tuple[Any, Any, Any], chosen: dict[str, Any], extra: dict[str, Any], created: str
) -> tuple[list[str], files.DataLines, dict[str, Any]]:
    rcase = resolve_case(case, specs=specs)
    layout = rcase.layout
    table, _ = control_table(case, layout, specs[0], rcase.nose_radius_um)
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
def _format() -> files.FileFormat:
    return files.FileFormat(
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


SQUARE = ProgramKind(
    name=NAME,
    noun="square mesh",
    request=SquareRequest,
    axes=(Axis("pitch_um", "um", "pitch of the square mesh"),),
    fields=(
        *result.TABLE,
        result.number("pitch_actual_um", "um", "realised pitch of the square mesh"),
        result.aspect_actual("1"),
        *result.SPINDLE,
    ),
    pitches=("pitch_actual_um", "pitch_actual_um"),
    file_format=_format,
    request_at=lambda spec, value: SquareRequest(kind=NAME, pitch_um=value["pitch_um"]),
    feed=lambda case, cutting, rc, surface, folder, program: case.feed_of(cutting),
    plan=_plan,
    record_fields=lambda rcase: {
        "table_rows": rcase.layout.shape[0],
        "table_cols": rcase.layout.shape[1],
        "pitch_actual_um": rcase.layout.pitch[0],
    },
    cost=_cost,
    simulation=LineSimulation,
    pitch_text=lambda r: f"Δx = Δy = {r['pitch_actual_um']:.4g} µm",
    point_text=lambda layout, flat: f"point {flat}",
    angular_cells=_cells,
    warm_request=lambda: SquareRequest(kind=NAME, pitch_um=50.0),
    sweeps="square-mesh sweeps",
    options=("square_pitch_um",),
    click_options=square_options,
    from_options=_from_options,
)
