"""Sweep specs: which cases a sweep runs, validated from ``catalogs/sweeps/*.yaml``.

A sweep is a surface, a layout method, a machine, cutting conditions, a resolution and the
sweep axes: target point counts and aspect ratios (lists or ranges), optionally feed and
nose radius. Expansion is pure: the cube's dimensions are the axes in a fixed order and the
flat case index is the C-order index into them.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Annotated, Any, Literal, Optional, Union

import numpy as np
from pydantic import (
    Field,
    PositiveFloat,
    PositiveInt,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_serializer,
    model_validator,
)

from ftsweep import registry
from ftsweep.engine.spec import Case, Resolution
from ftsweep.inputs import catalogs
from ftsweep.inputs.catalogs import CatalogError, Strict

MAX_AXIS_VALUES = 100_000


class AxisRange(Strict):
    """``num`` values from ``start`` to ``stop`` inclusive, evenly spaced on a log or linear scale."""

    start: PositiveFloat
    stop: PositiveFloat
    # bounded so that a typo cannot allocate gigabytes before the size check can refuse it
    num: PositiveInt = Field(le=MAX_AXIS_VALUES)
    scale: Literal["log", "linear"] = "log"


AxisSpec = Union[Annotated[list[PositiveFloat], Field(min_length=1)], AxisRange]


class SweepAxes(Strict):
    """The sweep axes: ``points`` and ``aspect`` for tables; for spiral programs exactly one
    rule axis (``points_per_rev``, ``arc_um`` or ``chord_um``) and optionally ``residual_um``;
    ``feed_um`` and ``nose_radius_um`` optional for both."""

    points: Optional[AxisSpec] = Field(None, description="target numbers of control points N (tables)")
    aspect: Optional[AxisSpec] = Field(
        None, description="target aspect ratios α (Δρ/Δθ µm/deg for rings, Δx/Δy for meshes)"
    )
    points_per_rev: Optional[AxisSpec] = Field(None, description="spiral: points per revolution")
    arc_um: Optional[AxisSpec] = Field(None, description="spiral: path length between points [µm]")
    chord_um: Optional[AxisSpec] = Field(None, description="spiral: chord-error budgets [µm]")
    residual_um: Optional[AxisSpec] = Field(
        None, description="spiral: residual budgets that set the feed [µm]"
    )
    spacing_um: Optional[AxisSpec] = Field(None, description="D path: spacing h between cuts [µm]")
    points_per_cut: Optional[AxisSpec] = Field(None, description="D path: points on every cut")
    facet_height_um: Optional[AxisSpec] = Field(None, description="Fresnel: facet heights h [µm]")
    points_per_turn: Optional[AxisSpec] = Field(None, description="Fresnel: control points K per turn")
    deviation_deg: Optional[Annotated[list[float], Field(min_length=1)]] = Field(
        None, description="Fresnel: rake-face deviations Δφ from the cutting direction [deg], a list"
    )
    feed_um: Optional[AxisSpec] = Field(None, description="feeds per revolution [µm/rev]")
    nose_radius_um: Optional[AxisSpec] = Field(None, description="tool nose radii [µm]")
    compensation: Optional[Annotated[list[Literal["exact", "slope", "none"]], Field(min_length=1)]] = Field(
        None, description="tool-nose compensations, a list of exact, slope, none (instead of the sweep's one)"
    )

    def get(self, name: str) -> Any:
        """The spec of axis ``name``, or None where the sweep does not span it."""
        return getattr(self, name, None)

    @model_serializer(mode="wrap")
    def _stable_dump(self, handler: Any) -> Any:
        # table, spiral and D-path sweep specs keep their hashes
        return catalogs.without_defaults(
            handler(self), dict.fromkeys((*SPIRAL_AXES, *DPATH_AXES, *FRESNEL_AXES, "compensation"))
        )


CATALOG_KIND = {"surface": "surfaces", "machine": "machines", "cutting": "cutting"}


def _catalog_folder(info: ValidationInfo) -> tuple[bool, Path | None]:
    """(whether the catalog rules apply, the catalog folder): they apply when the spec is
    validated with a ``{"catalog_folder": ...}`` context, as :func:`load_sweep` does; a spec
    re-read from a cube or a task is already resolved and needs no catalog."""
    context = info.context
    if isinstance(context, dict) and "catalog_folder" in context:
        return True, context["catalog_folder"]
    return False, None


class SweepSpec(Strict):
    """A validated sweep.

    Validated with a ``catalog_folder`` context, every rule is checked here, at load time:
    the named surface, machine and cutting entries exist, ``layout`` defaults to the
    surface's, and no combination of feed and nose radius on the axes has F ≥ 2·Rc.
    """

    description: str = ""
    surface: str
    layout: Optional[Literal["ring", "mesh", "spiral", "dpath", "fresnel"]] = Field(
        None, description="default: the surface's"
    )
    dpath: Optional[dict[str, Any]] = Field(
        None,
        description="D path options for every case (transition, zones, offaxis_um, cut_angle_deg, "
        "transition_step_deg)",
    )
    fresnel: Optional[dict[str, Any]] = Field(
        None, description="Fresnel options for every case (deviation_deg, safety, control_points)"
    )
    machine: str = "fts-1m"
    cutting: str = "reference"
    compensation: Literal["exact", "slope", "none"] = "exact"
    resolution: Resolution = Resolution()
    axes: SweepAxes
    cases_per_task: Optional[PositiveInt] = Field(
        None, description="cases a Dask task runs; default automatic"
    )

    @model_validator(mode="before")
    @classmethod
    def _layout_of_the_surface(cls, data: Any, info: ValidationInfo) -> Any:
        applies, folder = _catalog_folder(info)
        if applies and isinstance(data, dict) and data.get("layout") is None:
            try:
                surface = catalogs.entry("surfaces", data.get("surface"), folder)
            except (CatalogError, TypeError):
                return data  # the field validator names the surface key
            return {**data, "layout": surface.layout}
        return data

    @field_validator("surface", "machine", "cutting")
    @classmethod
    def _in_the_catalog(cls, name: str, info: ValidationInfo) -> str:
        applies, folder = _catalog_folder(info)
        if applies:
            assert info.field_name is not None
            catalogs.entry(CATALOG_KIND[info.field_name], name, folder)
        return name

    @model_validator(mode="after")
    def _feeds_below_twice_the_radii(self, info: ValidationInfo) -> SweepSpec:
        applies, folder = _catalog_folder(info)
        if not applies:
            return self
        cutting = catalogs.entry("cutting", self.cutting, folder)
        feeds = axis_values(self.axes.feed_um) if self.axes.feed_um is not None else [cutting.feed_um]
        radii = (
            axis_values(self.axes.nose_radius_um)
            if self.axes.nose_radius_um is not None
            else [cutting.nose_radius_um]
        )
        try:
            catalogs.check_feed(float(np.max(feeds)), float(np.min(radii)))
        except ValueError as exc:
            keys = [k for k in ("feed_um", "nose_radius_um") if getattr(self.axes, k) is not None]
            where = " and ".join(f"axes.{k}" for k in keys) or f"cutting '{self.cutting}'"
            raise ValueError(f"{where}: {exc}") from None
        return self

    @model_validator(mode="after")
    def _axes_of_the_program(self) -> SweepSpec:
        if self.layout is not None:
            registry.check_sweep_axes(self)  # only its kind's axes, and its kind's rules
        else:
            registry.check_options_keys(self)
        return self

    @model_validator(mode="after")
    def _no_duplicate_values(self) -> SweepSpec:
        for name in AXIS_ORDER:
            spec = getattr(self.axes, name)
            if spec is not None:
                values = axis_values(spec)
                if np.unique(values).size != values.size:
                    raise ValueError(f"axes.{name} repeats a value: {values.tolist()}")
        return self

    def options_of(self, key: str) -> Optional[dict[str, Any]]:
        """The options every case of a kind's sweep takes under ``key`` (``dpath:``), if given."""
        return getattr(self, key, None)

    def spec_hash(self) -> str:
        """Stable hash of the resolved spec: a cube belongs to exactly one spec."""
        text = json.dumps(self.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]


SPIRAL_RULE_AXES = ("points_per_rev", "arc_um", "chord_um")
SPIRAL_AXES = (*SPIRAL_RULE_AXES, "residual_um")
DPATH_AXES = ("spacing_um", "points_per_cut")
FRESNEL_AXES = ("facet_height_um", "points_per_turn", "deviation_deg")
AXIS_ORDER = (
    "points",
    "aspect",
    *SPIRAL_AXES,
    *DPATH_AXES,
    *FRESNEL_AXES,
    "feed_um",
    "nose_radius_um",
    "compensation",
)
# axes whose values are names, not numbers (a cube's coordinate of strings, without units)
NAMED_AXES = ("compensation",)
AXIS_ATTRS = {
    "points": {"units": "1", "long_name": "target number of control points"},
    "points_per_rev": {"units": "1", "long_name": "points per revolution of the spiral"},
    "arc_um": {"units": "um", "long_name": "path length between the spiral's points"},
    "chord_um": {"units": "um", "long_name": "chord-error budget of the spiral"},
    "residual_um": {"units": "um", "long_name": "residual (cusp) budget that sets the feed"},
    "spacing_um": {"units": "um", "long_name": "spacing between the D path's cuts"},
    "points_per_cut": {"units": "1", "long_name": "points on every cut of the D path"},
    "facet_height_um": {"units": "um", "long_name": "height of every Fresnel facet"},
    "points_per_turn": {"units": "1", "long_name": "control points on every turn of the quasi-spiral"},
    "deviation_deg": {"units": "deg", "long_name": "rake face turned from the cutting direction"},
    "compensation": {"long_name": "tool-nose compensation: exact, slope or none"},
    "feed_um": {"units": "um", "long_name": "feed per spindle revolution"},
    "nose_radius_um": {"units": "um", "long_name": "tool nose radius"},
}
ASPECT_ATTRS = {
    "ring": {"units": "um/deg", "long_name": "target aspect ratio Δρ/Δθ of the pitches"},
    "mesh": {"units": "1", "long_name": "target aspect ratio Δx/Δy of the pitches"},
}


def axis_attrs(axis: str, kind: str) -> dict[str, str]:
    """Units (parseable by pint/UDUNITS) and long name of a sweep axis for layout ``kind``."""
    return dict(ASPECT_ATTRS[kind] if axis == "aspect" else AXIS_ATTRS[axis])


def axis_values(spec: Any) -> np.ndarray:
    """The values of one axis spec (a list or an :class:`AxisRange`); names (the
    compensations) as an array of str objects."""
    if isinstance(spec, AxisRange):
        if spec.scale == "log":
            return np.geomspace(spec.start, spec.stop, spec.num)
        return np.linspace(spec.start, spec.stop, spec.num)
    if spec and isinstance(spec[0], str):
        return np.array(spec, dtype=object)
    return np.asarray(spec, dtype=np.float64)


def sweep_dir() -> Path:
    """Folder of the named sweep specs (``catalogs/sweeps``)."""
    return catalogs.catalog_dir() / "sweeps"


def resolve_sweep_path(name_or_path: str) -> Path:
    """A sweep name (``catalogs/sweeps/NAME.yaml``) or a path to a YAML file."""
    candidate = Path(name_or_path)
    if candidate.suffix in (".yaml", ".yml") or candidate.exists():
        if not candidate.is_file():
            raise CatalogError(f"sweep file {candidate} does not exist")
        return candidate
    path = sweep_dir() / f"{name_or_path}.yaml"
    if not path.is_file():
        known = sorted(p.stem for p in sweep_dir().glob("*.yaml"))
        raise CatalogError(f"unknown sweep '{name_or_path}' (no {path}); known: {', '.join(known) or 'none'}")
    return path


def load_sweep(name_or_path: str, catalog_folder: Path | None = None) -> tuple[str, SweepSpec]:
    """Load and validate a sweep; returns its name (the file stem) and spec.

    Every error names the file and the key: unknown keys, empty axes, non-positive values,
    and surfaces, machines or cutting conditions the catalogs do not define.
    """
    path = resolve_sweep_path(name_or_path)
    data = catalogs.read_yaml_file(path)
    if not isinstance(data, dict):
        raise CatalogError(f"{path}: a sweep file is a mapping of keys (surface, axes, ...)")
    try:
        spec = SweepSpec.model_validate(data, context={"catalog_folder": catalog_folder})
    except ValidationError as exc:
        raise CatalogError(_sweep_error(path, exc)) from None
    except RecursionError:
        raise CatalogError(f"{path}: nested too deeply to be a sweep") from None
    return path.stem, spec


def _sweep_error(path: Path, exc: ValidationError) -> str:
    lines = [f"{path}: invalid sweep:"]
    for e in exc.errors():
        loc = ".".join(str(p) for p in e["loc"] if not str(p).startswith(("list[", "AxisRange")))
        if e["type"] == "extra_forbidden":
            lines.append(f"  - {loc}: unknown key")
        elif e["type"] == "missing":
            lines.append(f"  - {loc}: required key is missing")
        elif e["type"] == "too_short":
            lines.append(f"  - {loc}: the axis is empty; give at least one value")
        elif e["loc"] and e["loc"][0] in CATALOG_KIND:
            lines.append(f"  - key '{loc}': {catalogs.error_text(e)}")
        elif not loc:
            lines.append(f"  - {catalogs.error_text(e)}")
        else:
            lines.append(f"  - {loc}: {catalogs.error_text(e)} (got {catalogs.short_repr(e.get('input'))})")
    return "\n".join(dict.fromkeys(lines))  # union members can repeat the same complaint


def coordinates(spec: SweepSpec) -> dict[str, np.ndarray]:
    """The cube's dimension coordinates, in :data:`AXIS_ORDER` (optional axes if given)."""
    return {
        name: axis_values(getattr(spec.axes, name))
        for name in AXIS_ORDER
        if getattr(spec.axes, name) is not None
    }


def case_at(spec: SweepSpec, index: int) -> Case:
    """The case at flat C-order ``index`` of the sweep's cube."""
    coords = coordinates(spec)
    shape = tuple(v.size for v in coords.values())
    pos = dict(zip(coords, np.unravel_index(index, shape), strict=True))
    value = {name: float(coords[name][pos[name]]) for name in coords if name not in NAMED_AXES}
    assert spec.layout is not None
    request = registry.kind(spec.layout).request_at(spec, value)
    return Case(
        surface=spec.surface,
        layout=request,
        machine=spec.machine,
        cutting=spec.cutting,
        feed_um=value.get("feed_um"),
        nose_radius_um=value.get("nose_radius_um"),
        compensation=str(coords["compensation"][pos["compensation"]])
        if "compensation" in coords
        else spec.compensation,
        resolution=spec.resolution,
    )


def n_cases(spec: SweepSpec) -> int:
    """Number of cases of the sweep."""
    return int(math.prod(v.size for v in coordinates(spec).values()))


def case_lines(spec: SweepSpec, index: int, catalog_folder: Path | None = None) -> tuple[float, Any]:
    """Relative cost of a case (control points plus simulated nodes, for load balancing) and
    the key of the lines it simulates: cases of one sweep with equal keys (angular samples,
    feed, nose radius) share their layout-independent work (:class:`ftsweep.engine.lines.LineCache`).
    A case whose layout cannot be built costs 0 and shares nothing (key None)."""
    case = case_at(spec, index)
    surface = catalogs.entry("surfaces", case.surface, catalog_folder)
    return registry.kind(case.layout.kind).cost(case, surface, catalog_folder)


def plan_tasks(
    spec: SweepSpec, indices: list[int], workers: int, catalog_folder: Path | None = None
) -> list[list[int]]:
    """Group case indices into tasks, the costliest first (longest-processing-time order),
    each task's cases cheapest first.

    Cases that simulate the same lines (:func:`case_lines`) form one task, so a worker
    computes their shared work once. The other cases are packed ``cases_per_task`` to a task,
    by default as many as keeps at least four tasks per worker, at most four; an explicit
    ``cases_per_task`` also caps the shared groups. Each case is written as soon as it
    finishes, so a task's size only affects scheduling, never what a crash can lose.
    """
    if not indices:
        return []
    per_task = spec.cases_per_task or max(1, min(4, len(indices) // (4 * max(workers, 1))))
    cost: dict[int, float] = {}
    shared: dict[Any, list[int]] = {}
    for i in indices:
        cost[i], key = case_lines(spec, i, catalog_folder)
        shared.setdefault(key if key is not None else ("alone", i), []).append(i)
    groups = [sorted(g, key=lambda i: -cost[i]) for g in shared.values()]
    alone = sorted((g[0] for g in groups if len(g) == 1), key=lambda i: -cost[i])
    cap = spec.cases_per_task or len(indices)
    tasks = [g[j : j + cap] for g in groups if len(g) > 1 for j in range(0, len(g), cap)]
    tasks += [alone[j : j + per_task] for j in range(0, len(alone), per_task)]
    # within a task the cheapest case runs first: it reports soonest (the first case of a
    # group computes the shared lines whichever it is), so progress starts early
    return [sorted(t, key=lambda i: cost[i]) for t in sorted(tasks, key=lambda t: -sum(cost[i] for i in t))]
