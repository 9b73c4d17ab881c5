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
from typing import Annotated, Any, Literal, NamedTuple, Optional, Union

import numpy as np
from pydantic import (
    ConfigDict,
    Field,
    PositiveFloat,
    PositiveInt,
    TypeAdapter,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_serializer,
    model_validator,
)

from ftsweep import registry
from ftsweep.engine.case import Case, Resolution
from ftsweep.engine.contract import Axis
from ftsweep.inputs import catalogs, corrections
from ftsweep.inputs.catalogs import CatalogError, Strict
from ftsweep.inputs.strict import did_you_mean

MAX_AXIS_VALUES = 100_000


class AxisRange(Strict):
    """``num`` values from ``start`` to ``stop`` inclusive, evenly spaced on a log or linear scale."""

    start: PositiveFloat
    stop: PositiveFloat
    # bounded so that a typo cannot allocate gigabytes before the size check can refuse it
    num: PositiveInt = Field(le=MAX_AXIS_VALUES)
    scale: Literal["log", "linear"] = "log"


AxisSpec = Union[Annotated[list[PositiveFloat], Field(min_length=1)], AxisRange]


_POSITIVE = Annotated[float, Field(gt=0, allow_inf_nan=False)]
_VALUES: TypeAdapter[Any] = TypeAdapter(Annotated[list[_POSITIVE], Field(min_length=1)])
_SIGNED: TypeAdapter[Any] = TypeAdapter(
    Annotated[list[Annotated[float, Field(allow_inf_nan=False)]], Field(min_length=1)]
)


def _kind_axes() -> dict[str, Axis]:
    """Every registered kind's sweep axes by name (kinds may share one, as rings and meshes do)."""
    return {a.name: a for k in registry.kinds().values() for a in k.axes}


class SweepAxes(Strict):
    """The sweep axes: each kind's own (``ProgramKind.axes``: ``points`` and ``aspect`` for
    tables, one rule axis and optionally ``residual_um`` for spirals, ...) and those every
    kind may sweep: ``feed_um``, ``nose_radius_um`` and ``compensation``. A kind's axis is a
    list of positive values or a range (a signed axis: a list); an axis no kind declares is
    refused by name."""

    model_config = ConfigDict(extra="allow", frozen=True, allow_inf_nan=False)

    feed_um: Optional[AxisSpec] = Field(None, description="feeds per revolution [µm/rev]")
    nose_radius_um: Optional[AxisSpec] = Field(None, description="tool nose radii [µm]")
    compensation: Optional[Annotated[list[Literal["exact", "slope", "none"]], Field(min_length=1)]] = Field(
        None, description="tool-nose compensations, a list of exact, slope, none (instead of the sweep's one)"
    )
    correction_gain: Optional[AxisSpec] = Field(
        None, description="gains of the surface's measured correction [-], each in (0, 1.5]"
    )
    correction_terms: Optional[Annotated[list[PositiveInt], Field(min_length=1)]] = Field(
        None, description="terms its measured correction keeps (the low-pass), a list of counts"
    )

    @model_validator(mode="before")
    @classmethod
    def _axes_of_the_kinds(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        known = _kind_axes()
        out = {}
        for name, value in data.items():
            if name in cls.model_fields:
                out[name] = value
                continue
            axis = known.get(name)
            if axis is None:
                names = ", ".join(sorted({*known, *cls.model_fields}))
                hint = did_you_mean(name, {*known, *cls.model_fields})
                raise ValueError(f"axes.{name}: unknown axis{hint}; the axes are {names}")
            if value is not None:
                out[name] = _axis_value(axis, value)
        return out

    def get(self, name: str) -> Any:
        """The spec of axis ``name``, or None where the sweep does not span it."""
        return getattr(self, name, None)

    def given(self) -> dict[str, Any]:
        """Every axis the sweep spans, by name."""
        return {k: v for k, v in {**dict(self), **(self.model_extra or {})}.items() if v is not None}

    @model_serializer(mode="wrap")
    def _stable_dump(self, handler: Any) -> Any:
        # specs written before an axis existed keep their hashes; the first program axes
        # (the tables') were always written, null when unset
        optional = {"compensation": None, "correction_gain": None, "correction_terms": None}
        dumped = catalogs.without_defaults(handler(self), optional)
        unset = {a.name: None for a in _kind_axes().values() if a.dumped_unset}
        return {**unset, **dumped}


def _axis_value(axis: Axis, value: Any) -> Any:
    """A kind's axis validated: positive values or a range, or any finite list if signed;
    ValueError naming the axis, the key within it and the problem."""
    try:
        if isinstance(value, dict) and not axis.signed:
            return AxisRange.model_validate(value)
        return (_SIGNED if axis.signed else _VALUES).validate_python(value)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(["axes", axis.name, *(str(p) for p in first["loc"] if isinstance(p, str))])
        if first["type"] == "too_short":
            raise ValueError(f"{where}: the axis is empty; give at least one value") from None
        if first["type"] == "extra_forbidden":
            raise ValueError(f"{where}: unknown key") from None
        if first["type"] == "missing":
            raise ValueError(f"{where}: required key is missing") from None
        got = catalogs.short_repr(value)
        raise ValueError(f"{where}: {catalogs.error_text(first)} (got {got})") from None


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
    model_config = ConfigDict(extra="allow", frozen=True, allow_inf_nan=False)

    layout: Optional[str] = Field(None, description="the program kind; default: the surface's")
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
    def _options_of_the_kinds(cls, data: Any) -> Any:
        """A key beside the declared ones is a kind's options for every case of its sweeps
        (``dpath:``, a mapping); any other is refused by name."""
        if not isinstance(data, dict):
            return data
        keys = {k.options_key for k in registry.kinds().values() if k.options_key}
        for name, value in data.items():
            if name in cls.model_fields:
                continue
            if name not in keys:
                raise ValueError(f"{name}: unknown key{did_you_mean(name, [*cls.model_fields, *keys])}")
            if value is not None and not isinstance(value, dict):
                got = type(value).__name__
                raise ValueError(f"{name}: the options of every case are a mapping (got {got})")
        return data

    @field_validator("layout")
    @classmethod
    def _a_registered_kind(cls, name: Optional[str]) -> Optional[str]:
        if name is not None:
            registry.kind(name)  # ValueError naming the known kinds
        return name

    @model_validator(mode="before")
    @classmethod
    def _layout_of_the_surface(cls, data: Any, info: ValidationInfo) -> Any:
        applies, folder = _catalog_folder(info)
        name = data.get("surface") if isinstance(data, dict) else None
        if applies and isinstance(data, dict) and data.get("layout") is None and isinstance(name, str):
            try:
                surface = catalogs.entry("surfaces", name, folder)
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
    def _a_correction_to_sweep(self, info: ValidationInfo) -> SweepSpec:
        applies, folder = _catalog_folder(info)
        gains, terms = self.axes.correction_gain, self.axes.correction_terms
        if not applies or (gains is None and terms is None):
            return self
        surface = catalogs.entry("surfaces", self.surface, folder)
        given_gains = [float(g) for g in axis_values(gains)] if gains is not None else [None]
        given_terms: list[Optional[int]] = list(terms) if terms is not None else [None]
        try:
            for gain in given_gains:
                for kept in given_terms:
                    corrections.as_cased(surface, gain, kept)
        except ValueError as exc:
            raise ValueError(f"axes.correction_*: surface {self.surface}: {exc}") from None
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
        for name, spec in self.axes.given().items():
            values = axis_values(spec)
            if np.unique(values).size != values.size:
                raise ValueError(f"axes.{name} repeats a value: {values.tolist()}")
        return self

    def options_of(self, key: str) -> Optional[dict[str, Any]]:
        """The options every case of a kind's sweep takes under ``key`` (``dpath:``), if given."""
        return (self.model_extra or {}).get(key)

    @model_serializer(mode="wrap")
    def _stable_dump(self, handler: Any) -> Any:
        # the options keys of the first path kinds were always written, null when unset
        kinds = registry.kinds().values()
        unset = {k.options_key: None for k in kinds if k.options_key and k.options_dumped_unset}
        return {**unset, **handler(self)}

    def spec_hash(self) -> str:
        """Stable hash of the resolved spec: a cube belongs to exactly one spec."""
        text = json.dumps(self.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]


# the axes every kind may sweep, after its own in a cube
COMMON_AXES = ("feed_um", "nose_radius_um", "compensation", "correction_gain", "correction_terms")
# axes whose values are names, not numbers (a cube's coordinate of strings, without units)
NAMED_AXES = ("compensation",)
COMMON_ATTRS = {
    "compensation": {"long_name": "tool-nose compensation: exact, slope or none"},
    "feed_um": {"units": "um", "long_name": "feed per spindle revolution"},
    "nose_radius_um": {"units": "um", "long_name": "tool nose radius"},
    "correction_gain": {"units": "1", "long_name": "gain of the measured correction"},
    "correction_terms": {"units": "1", "long_name": "terms the measured correction keeps (its low-pass)"},
}
COMMON_COUNTS = ("correction_terms",)


def axis_order(spec: SweepSpec) -> tuple[str, ...]:
    """The order of the cube's dimensions: the kind's own axes, then the common ones."""
    own = registry.kind(spec.layout).axis_names if spec.layout is not None else ()
    return (*own, *COMMON_AXES)


def axis_counts(axis: str, kind: str) -> bool:
    """Whether a sweep axis of kind ``kind`` counts things (its values whole numbers)."""
    if axis in COMMON_ATTRS:
        return axis in COMMON_COUNTS
    return {a.name: a for a in registry.kind(kind).axes}[axis].count


def axis_attrs(axis: str, kind: str) -> dict[str, str]:
    """Units (parseable by pint/UDUNITS) and long name of a sweep axis of kind ``kind``."""
    if axis in COMMON_ATTRS:
        return dict(COMMON_ATTRS[axis])
    declared = {a.name: a for a in registry.kind(kind).axes}[axis]
    return {"units": declared.units, "long_name": declared.long_name}


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
        if not candidate.exists():
            raise CatalogError(f"sweep file {candidate} does not exist")
        if not candidate.is_file():
            what = "a folder" if candidate.is_dir() else "a device, FIFO or socket"
            raise CatalogError(f"sweep file {candidate} is {what}, not a YAML file; nothing was read")
        return candidate
    path = sweep_dir() / f"{name_or_path}.yaml"
    if not path.is_file():
        known = sorted(p.stem for p in sweep_dir().glob("*.yaml"))
        raise CatalogError(
            f"unknown sweep '{name_or_path}'{did_you_mean(name_or_path, known)} (no {path}); "
            f"known: {', '.join(known) or 'none'}"
        )
    return path


class LoadedSweep(NamedTuple):
    """A sweep read and validated once: its name (the file's stem) and its spec."""

    name: str
    spec: SweepSpec


def load_sweep(name_or_path: str, catalog_folder: Path | None = None) -> LoadedSweep:
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
    return LoadedSweep(path.stem, spec)


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
        elif not loc or catalogs.error_text(e).startswith(f"{loc}."):
            lines.append(f"  - {catalogs.error_text(e)}")  # the message names its key itself
        else:
            lines.append(f"  - {loc}: {catalogs.error_text(e)} (got {catalogs.short_repr(e.get('input'))})")
    return "\n".join(dict.fromkeys(lines))  # union members can repeat the same complaint


def coordinates(spec: SweepSpec) -> dict[str, np.ndarray]:
    """The cube's dimension coordinates, in :func:`axis_order` (optional axes if given)."""
    return {
        name: axis_values(spec.axes.get(name)) for name in axis_order(spec) if spec.axes.get(name) is not None
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
        correction_gain=value.get("correction_gain"),
        correction_terms=int(value["correction_terms"]) if "correction_terms" in value else None,
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
    try:
        return _cost(spec, index, catalog_folder)
    except ValueError:  # refused when it runs, with the reason; it costs nothing to plan
        return 0.0, None


def _cost(spec: SweepSpec, index: int, catalog_folder: Path | None) -> tuple[float, Any]:
    case = case_at(spec, index)
    surface = catalogs.entry("surfaces", case.surface, catalog_folder)
    kind = registry.kind(case.layout.kind)
    cutting = catalogs.entry("cutting", case.cutting, catalog_folder)
    feed = kind.feed(case, cutting, case.nose_radius_of(cutting), surface, catalog_folder, None)
    return kind.cost(case, surface, catalog_folder, feed)


Costs = dict[int, tuple[float, Any]]


def case_costs(
    spec: SweepSpec, indices: list[int], catalog_folder: Path | None = None
) -> tuple[Costs, dict[int, str]]:
    """One pass over cases ``indices``: the cost and shared-lines key of each (as
    :func:`case_lines`), and why a case cannot run as specified where that is known before it
    is planned (its feed, a layout the aperture rules out, over the controller's capacity: its
    kind's ``feed`` and ``cost`` refuse it, a CaseError or another ValueError)."""
    costs: Costs = {}
    refused: dict[int, str] = {}
    for index in indices:
        try:
            costs[index] = _cost(spec, index, catalog_folder)
        except ValueError as exc:
            refused[index] = str(exc)
    return costs, refused


def plan_tasks(
    spec: SweepSpec,
    indices: list[int],
    workers: int,
    catalog_folder: Path | None = None,
    costs: Optional[Costs] = None,
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
        cost[i], key = costs[i] if costs is not None and i in costs else case_lines(spec, i, catalog_folder)
        shared.setdefault(key if key is not None else ("alone", i), []).append(i)
    groups = [sorted(g, key=lambda i: -cost[i]) for g in shared.values()]
    alone = sorted((g[0] for g in groups if len(g) == 1), key=lambda i: -cost[i])
    cap = spec.cases_per_task or len(indices)
    tasks = [g[j : j + cap] for g in groups if len(g) > 1 for j in range(0, len(g), cap)]
    tasks += [alone[j : j + per_task] for j in range(0, len(alone), per_task)]
    # within a task the cheapest case runs first: it reports soonest (the first case of a
    # group computes the shared lines whichever it is), so progress starts early
    return [sorted(t, key=lambda i: cost[i]) for t in sorted(tasks, key=lambda t: -sum(cost[i] for i in t))]
