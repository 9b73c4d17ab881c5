"""Catalog loading: YAML entries validated into typed, immutable specs.

Catalog files live in ``catalogs/`` (or the folder named by ``FTSWEEP_CATALOGS``). Each
file maps entry names to entries; unknown keys, missing keys and out-of-range values are
refused with a :class:`CatalogError` naming the file, the entry, the key and what is
allowed.
"""

from __future__ import annotations

import functools
import math
import os
import reprlib
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, Literal, Optional, Union, cast

import numpy as np
from pydantic import (
    BaseModel,
    Field,
    PositiveFloat,
    PositiveInt,
    ValidationError,
    create_model,
    model_validator,
)

from ftsweep.inputs import surfaceplugins
from ftsweep.inputs.controllers import Controller
from ftsweep.inputs.corrections import MeasuredCorrection, corrected_callable
from ftsweep.inputs.strict import Strict, allowed_keys, did_you_mean
from ftsweep.inputs.yamlfiles import CatalogError, read_yaml_file
from ftsweep.stages.kinematics import axes as kinematics
from ftsweep.stages.sampling.surfaces import FAMILIES, Aperture, Family, SurfaceFn

_SHORT = reprlib.Repr()
_SHORT.maxlevel, _SHORT.maxlist, _SHORT.maxdict, _SHORT.maxstring, _SHORT.maxother = 2, 4, 4, 60, 60


def short_repr(value: Any) -> str:
    """A bounded repr of user input for error messages (nested or huge input, e.g. a YAML
    alias bomb, is elided, never printed whole)."""
    return _SHORT.repr(value)


def error_text(error: Any) -> str:
    """The message of one pydantic error without pydantic's "Value error, " prefix."""
    return str(error["msg"]).removeprefix("Value error, ")


def without_defaults(data: Any, defaults: dict[str, Any]) -> Any:
    """``data`` (a model's dump) without the keys of ``defaults`` whose value is that default:
    options added after specs were first written are left out of a dump while unset, so the
    hashes of those specs (case keys, cube spec hashes) do not change."""
    if isinstance(data, dict):
        for name, default in defaults.items():
            if name in data and type(data[name]) is type(default) and data[name] == default:
                del data[name]
    return data


# --------------------------------------------------------------------------- apertures
# a program kind's name, checked against the registry when a case is built (the catalogs sit below it)
KIND_NAME = r"^[a-z][a-z0-9_]{0,31}$"


class CircleAperture(Strict):
    shape: Literal["circle"]
    radius_um: PositiveFloat = Field(description="aperture radius [µm]")


class RectangleAperture(Strict):
    shape: Literal["rectangle"]
    width_um: PositiveFloat = Field(description="aperture width along x [µm]")
    height_um: PositiveFloat = Field(description="aperture height along y [µm]")


ApertureSpec = Annotated[Union[CircleAperture, RectangleAperture], Field(discriminator="shape")]


# --------------------------------------------------------------------------- surfaces
class HeightMapParams(Strict):
    path: str = Field(description="NetCDF (.nc), Zarr (.zarr) or .npy file; relative to the catalog folder")
    variable: Optional[str] = Field(None, description="height variable of a NetCDF/Zarr file")
    x_name: str = "x"
    y_name: str = "y"
    spacing_um: Optional[tuple[PositiveFloat, PositiveFloat]] = Field(
        None, description="(dx, dy) of a .npy grid"
    )
    origin_um: Optional[tuple[float, float]] = Field(
        None, description="(x, y) of element [0, 0] of a .npy grid"
    )
    scale_to_um: PositiveFloat = Field(1.0, description="factor turning the file's heights into µm")


class PluginParams(Strict):
    function: str = Field(description="module:function taking x, y [µm] and returning heights (and slopes)")
    params: dict[str, Any] = Field(default_factory=dict, description="keyword arguments for the function")


class FresnelSlicing(Strict):
    """Slice the surface into a Fresnel form ([2] eq. 3): facets of constant height along its
    contour lines, counted from the lowest point inside the aperture."""

    facet_height_um: PositiveFloat = Field(description="height h of every facet [µm]")


class _SurfaceBase(Strict):
    description: str = ""
    fresnel: Optional[FresnelSlicing] = Field(
        None, description="evaluate the surface's Fresnel form: {facet_height_um: h} ([2] eq. 3)"
    )
    correction: Optional[MeasuredCorrection] = Field(
        None, description="the design less a measured part's unexplained error (ftsweep correct writes it)"
    )
    aperture: ApertureSpec
    layout: str = Field(pattern=KIND_NAME, description="program kind by default (a table's: ring or mesh)")
    gradient_bound: Optional[PositiveFloat] = Field(
        None, description="upper bound of |∇f| [-]; default analytic, or sampled over the aperture"
    )
    curvature_bound: Optional[PositiveFloat] = Field(
        None,
        description="upper bound of the Hessian norm ‖∇²f‖ [1/µm]; default the family's analytic one, "
        "if any. With it exact compensation solves each point in a few evaluations where K·Rc < 1, "
        "and scans densely enough for 0.01 nm elsewhere; a surface found more curved is refused",
    )


class HeightMapSurface(_SurfaceBase):
    family: Literal["height_map"]
    params: HeightMapParams


class PluginSurface(_SurfaceBase):
    family: Literal["plugin"]
    params: PluginParams


def _params_model(name: str, family: Family) -> type[BaseModel]:
    """The validated model of a registered family's parameters (from its ``Param`` list)."""
    fields: dict[str, Any] = {}
    for key, p in family.params.items():
        constraints: dict[str, Any] = {"description": p.description}
        if p.positive:
            constraints["gt"] = 0
        if p.min_length is not None:
            constraints["min_length"] = p.min_length
        fields[key] = (p.annotation, Field(p.default, **constraints))
    validators: dict[str, Any] = {}
    if family.check is not None:
        check = family.check

        def _check(self: BaseModel) -> BaseModel:
            check(self.model_dump())
            return self

        validators["check_combination"] = model_validator(mode="after")(_check)
    title = "".join(part.capitalize() for part in name.split("_"))
    model: type[BaseModel] = create_model(  # type: ignore[call-overload]
        f"{title}Params", __base__=Strict, __validators__=validators, **fields
    )
    return model


def _surface_model(name: str, family: Family) -> type[BaseModel]:
    """The catalog entry model of a registered family: ``family: name`` and its parameters."""
    title = "".join(part.capitalize() for part in name.split("_"))
    tag: Any = Literal[name]
    model: type[BaseModel] = create_model(  # type: ignore[call-overload]
        f"{title}Surface",
        __base__=_SurfaceBase,
        family=(tag, ...),
        params=(_params_model(name, family), ...),
    )
    return cast(type[BaseModel], model)


@functools.lru_cache(maxsize=8)
def _generated(names: tuple[str, ...]) -> tuple[dict[str, type[BaseModel]], Any]:
    models = {name: _surface_model(name, FAMILIES[name]) for name in names}
    union: Any = Annotated[
        Union[(*models.values(), HeightMapSurface, PluginSurface)],  # noqa: UP007
        Field(discriminator="family"),
    ]
    return models, union


def surface_spec() -> Any:
    """The catalog entry type of a surface: one generated model per family registered with
    ``stages.surfaces.surface_family`` (also one registered after this module was imported),
    plus the families users bring (height maps, plug-ins), which load files or code and so
    are declared here, and those of surface plug-ins (:mod:`ftsweep.inputs.surfaceplugins`,
    imported first). ``SurfaceSpec`` names it too."""
    surfaceplugins.load()
    return _generated(tuple(FAMILIES))[1]


def registered_surfaces() -> dict[str, type[BaseModel]]:
    """The generated entry model of every registered family (plug-ins' included)."""
    surfaceplugins.load()
    return _generated(tuple(FAMILIES))[0]


def __getattr__(name: str) -> Any:
    # SurfaceSpec follows the registry, so it is computed on access
    if name == "SurfaceSpec":
        return surface_spec()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


USER_FAMILIES = ("height_map", "plugin")


def surface_callable(spec: Any, folder: Path | None = None) -> SurfaceFn:
    """The surface callable ``fn(x, y) -> (f, fx, fy)`` of a catalog entry (µm in, µm out); its
    Fresnel form ([2] eq. 3) when the entry sets ``fresnel``, its measured correction first
    (:mod:`ftsweep.inputs.corrections`, eq. 1) when it sets ``correction``."""
    fn = base_callable(spec, folder)
    if spec.correction is not None:
        fn = corrected_callable(fn, spec.correction, aperture_of(spec))
    if spec.fresnel is None:
        return fn
    from ftsweep.inputs.facets import sliced_callable

    return sliced_callable(fn, aperture_of(spec), spec.fresnel.facet_height_um)


def base_callable(spec: Any, folder: Path | None = None) -> SurfaceFn:
    """The surface callable of a catalog entry without its ``fresnel`` transform."""
    if spec.family in USER_FAMILIES:
        from ftsweep.inputs import usersurfaces

        return usersurfaces.build(
            spec.family, spec.params.model_dump(mode="json"), aperture_of(spec), folder or catalog_dir()
        )
    return functools.partial(FAMILIES[spec.family].evaluate, **spec.params.model_dump())


def line_sampler(spec: Any) -> Callable[..., tuple[np.ndarray, np.ndarray]] | None:
    """The family's line evaluator ``fn(first, spacing, offset, n_nodes, cos_t, sin_t) -> (g, g')``
    of a catalog entry (model §4, §5; see :func:`ftsweep.stages.sampling.geometry.evaluate_lines`), or
    None where the family has none (user surfaces): the case runner then samples the node grid
    through :func:`surface_callable`."""
    family = FAMILIES.get(spec.family)
    changed = spec.fresnel is not None or spec.correction is not None
    if spec.family in USER_FAMILIES or family is None or family.lines is None or changed:
        return None
    return functools.partial(family.lines, **spec.params.model_dump())


def gradient_bound(spec: Any, folder: Path | None = None) -> float:
    """Upper bound of |∇f| [-]: the entry's own, the family's analytic one, or a sampled estimate."""
    if spec.gradient_bound is not None:
        return float(spec.gradient_bound)
    family = FAMILIES.get(spec.family)
    if family is not None and family.gradient_bound is not None and spec.correction is None:
        return family.gradient_bound(**spec.params.model_dump())
    return _sampled_bound(spec.model_dump_json(), str(folder or catalog_dir()))


def curvature_bound(spec: Any) -> float:
    """Upper bound of ‖∇²f‖ [1/µm]: the entry's own, the family's analytic one, or inf (unknown)."""
    if spec.curvature_bound is not None:
        return float(spec.curvature_bound)
    family = FAMILIES.get(spec.family)
    if family is not None and family.curvature_bound is not None and spec.correction is None:
        return float(family.curvature_bound(**spec.params.model_dump()))
    return math.inf


@functools.lru_cache(maxsize=32)
def _sampled_bound(spec_json: str, folder: str) -> float:
    from pydantic import TypeAdapter

    from ftsweep.stages.sampling.surfaces import sampled_gradient_bound

    spec = TypeAdapter(surface_spec()).validate_json(spec_json)
    return sampled_gradient_bound(surface_callable(spec, Path(folder)), aperture_of(spec).outer_radius_um)


def aperture_of(spec: Any) -> Aperture:
    """The stage-level :class:`~ftsweep.stages.sampling.surfaces.Aperture` of a catalog entry."""
    return Aperture(**spec.aperture.model_dump())


# --------------------------------------------------------------------------- machines
class AxisLimits(Strict):
    """The X, Z and C limits of a slow-tool-servo lathe ([5]), and the Y axis and C
    acceleration of an X-Y-Z-C lathe ([2]): positions [mm], speeds and accelerations an
    exported program must respect on every line."""

    x_min_mm: float = Field(description="lowest X position (tool radius) [mm]")
    x_max_mm: float = Field(description="highest X position (tool radius) [mm]")
    z_min_mm: float = Field(description="lowest Z position [mm]")
    z_max_mm: float = Field(description="highest Z position [mm]")
    x_feed_mm_s: PositiveFloat = Field(description="largest X feed-rate [mm/s]")
    x_accel_m_s2: PositiveFloat = Field(description="largest X acceleration [m/s²]")
    z_velocity_mm_s: PositiveFloat = Field(description="largest Z velocity [mm/s]")
    z_accel_m_s2: PositiveFloat = Field(description="largest Z acceleration [m/s²]")
    c_speed_rpm: PositiveFloat = Field(description="largest C (spindle) speed in position mode [rev/min]")
    # the Y axis and C acceleration of an X-Y-Z-C lathe ([2]); None on an X-Z-C lathe
    y_min_mm: Optional[float] = Field(None, description="lowest Y position [mm] (X-Y-Z-C lathe)")
    y_max_mm: Optional[float] = Field(None, description="highest Y position [mm]")
    y_feed_mm_s: Optional[PositiveFloat] = Field(None, description="largest Y feed-rate [mm/s]")
    y_accel_m_s2: Optional[PositiveFloat] = Field(None, description="largest Y acceleration [m/s²]")
    c_accel_rad_s2: Optional[PositiveFloat] = Field(
        None, description="largest C (spindle) acceleration in position mode [rad/s²]"
    )

    @model_validator(mode="after")
    def _ranges(self) -> AxisLimits:
        ys = (self.y_min_mm, self.y_max_mm, self.y_feed_mm_s, self.y_accel_m_s2)
        if any(v is None for v in ys) and not all(v is None for v in ys):
            raise ValueError("a Y axis needs all of y_min_mm, y_max_mm, y_feed_mm_s and y_accel_m_s2")
        for axis in ("x", "z") if self.y_min_mm is None else ("x", "y", "z"):
            lo, hi = getattr(self, f"{axis}_min_mm"), getattr(self, f"{axis}_max_mm")
            if not lo < hi:
                raise ValueError(f"{axis}_min_mm {lo:g} must be below {axis}_max_mm {hi:g}")
        return self

    def limits(self, names: tuple[str, ...]) -> kinematics.Limits:
        """The limits of the axes ``names`` (of C, X, Y, Z) in SI for the kinematics stage
        (:mod:`ftsweep.stages.kinematics.axes`); C's position is free, a limit not declared (C's
        acceleration on an X-Z-C lathe) is not checked. ValueError for a Y axis not declared."""
        if "Y" in names and self.y_min_mm is None:
            raise ValueError("the machine declares no Y axis")
        inf = math.inf
        rows = {
            "C": (-inf, inf, self.c_speed_rpm * 2.0 * math.pi / 60.0, self.c_accel_rad_s2 or inf),
            "X": (self.x_min_mm * 1e-3, self.x_max_mm * 1e-3, self.x_feed_mm_s * 1e-3, self.x_accel_m_s2),
            "Y": tuple(
                inf if v is None else v * k
                for v, k in (
                    (self.y_min_mm, 1e-3),
                    (self.y_max_mm, 1e-3),
                    (self.y_feed_mm_s, 1e-3),
                    (self.y_accel_m_s2, 1.0),
                )
            ),
            "Z": (self.z_min_mm * 1e-3, self.z_max_mm * 1e-3, self.z_velocity_mm_s * 1e-3, self.z_accel_m_s2),
        }
        table = np.array([rows[n] for n in names], dtype=np.float64)
        return kinematics.Limits(
            tuple(names), tuple(n == "C" for n in names), table[:, 0], table[:, 1], table[:, 2], table[:, 3]
        )


class Machine(Strict):
    """A fast tool servo and its controller (model §1, §6 dynamics); a slow-tool-servo lathe
    also declares its X, Z, C ``axes`` limits ([5])."""

    description: str = ""
    capacity_points: PositiveInt = Field(description="control points the controller can hold")
    command_rate_hz: PositiveFloat = Field(description="FTS command rate [Hz]")
    travel_um: PositiveFloat = Field(description="W-axis travel [µm]")
    peak_accel_m_s2: PositiveFloat = Field(description="peak W acceleration [m/s²]")
    continuous_accel_m_s2: PositiveFloat = Field(description="continuous W acceleration [m/s²]")
    bandwidth_hz: PositiveFloat = Field(description="closed-loop bandwidth [Hz]")
    bandwidth_amplitude_um: PositiveFloat = Field(description="amplitude at which the bandwidth holds [µm]")
    spectrum_threshold: float = Field(
        0.01,
        gt=0.0,
        lt=1.0,
        description="a W spectral component is significant above this fraction of the dominant one",
    )
    table_unit_nm: PositiveFloat = Field(
        1.0, description="value of one integer step in the header table [nm]"
    )
    table_int_type: Literal["int16", "int32"] = Field("int32", description="integer type of the header table")
    # layered machining of parts deeper than the travel ([3]; ftsweep.stages.paths.layers)
    layer_margin_um: float = Field(
        0.0, ge=0.0, description="stroke kept free at the travel's ends in layered machining, in all [µm]"
    )
    z_error_um: float = Field(
        0.0, description="Z positioning error per retraction between layers [µm] (positive: falls short)"
    )
    layer_change_s: float = Field(
        2.0, ge=0.0, description="time to stop the spindle, move Z and restart, per layer segment [s]"
    )
    axes: Optional[AxisLimits] = Field(
        None, description="X, Z, C (and Y) limits of a slow-tool-servo or X-Y-Z-C lathe ([5], [2])"
    )
    controller: Optional[Controller] = Field(
        None, description="the controller that runs path programs (none: ftsweep's text, linear)"
    )

    @property
    def interpolation(self) -> str:
        """How the controller forms the path between program points (linear when undeclared)."""
        return "linear" if self.controller is None else self.controller.interpolation

    @model_validator(mode="after")
    def _margin_below_travel(self) -> Machine:
        if not self.layer_margin_um < self.travel_um:
            raise ValueError(
                f"layer_margin_um {self.layer_margin_um:g} must be below travel_um {self.travel_um:g}"
            )
        return self


class Cutting(Strict):
    """Cutting conditions (model §1, §7)."""

    description: str = ""
    feed_um: PositiveFloat = Field(description="feed per revolution F [µm/rev]")
    nose_radius_um: PositiveFloat = Field(description="tool nose radius Rc [µm]")
    spindle_rpm: PositiveFloat = Field(description="spindle speed [rev/min]")

    @model_validator(mode="after")
    def _feed_below_twice_the_radius(self) -> Cutting:
        check_feed(self.feed_um, self.nose_radius_um)
        return self


def check_feed(feed_um: float, nose_radius_um: float) -> None:
    """Refuse a feed of at least 2·Rc: consecutive arcs would not intersect and the cusp
    F²/(8·Rc) of model §5 would no longer describe the surface."""
    if not feed_um < 2.0 * nose_radius_um:
        raise ValueError(
            f"feed {feed_um:g} µm/rev is not below twice the nose radius ({2.0 * nose_radius_um:g} µm): "
            "consecutive tool arcs would not overlap"
        )


class Reference(Strict):
    """A published prediction (model §8) to check the model against."""

    surface: str
    layout: str = Field(pattern=KIND_NAME, description="the table's kind (ring or mesh)")
    pitch: tuple[PositiveFloat, PositiveFloat] = Field(description="(Δρ µm, Δθ deg) or (Δx µm, Δy µm)")
    points_paper: PositiveInt = Field(description="point count the paper states")
    pv_nm: PositiveFloat = Field(description="published P-V [nm]")
    rel_tol: float = Field(0.15, gt=0.0, description="relative tolerance on pv_nm")
    abs_tol_nm: float = Field(5.0, ge=0.0, description="absolute tolerance on pv_nm [nm]")

    @property
    def tolerance_nm(self) -> float:
        """Allowed deviation [nm]: max(rel_tol·pv, abs_tol_nm)."""
        return max(self.rel_tol * self.pv_nm, self.abs_tol_nm)


def recorded_entries(
    surface: str, machine: str, cutting: str, folder: Path | None = None
) -> dict[str, dict[str, Any]]:
    """The catalog entries a run uses, as cubes record them for provenance:
    ``{"surface": {name: entry}, "machine": {...}, "cutting": {...}}``."""
    return {
        "surface": {surface: entry("surfaces", surface, folder).model_dump(mode="json")},
        "machine": {machine: entry("machines", machine, folder).model_dump(mode="json")},
        "cutting": {cutting: entry("cutting", cutting, folder).model_dump(mode="json")},
    }


# --------------------------------------------------------------------------- loading
def catalog_dir_reason() -> str:
    """Why :func:`catalog_dir` is the folder it is (what ``ftsweep catalogs`` says)."""
    if os.environ.get("FTSWEEP_CATALOGS"):
        return "$FTSWEEP_CATALOGS"
    if catalog_dir().name == "catalogs":
        return "the checkout's catalogs/, beside this editable install"
    return "the copy this installed package ships; set $FTSWEEP_CATALOGS to read another folder"


def catalog_dir() -> Path:
    """Folder holding the catalog YAML files: ``$FTSWEEP_CATALOGS``, else the repository's
    ``catalogs/`` (a source checkout or editable install), else the copy a regular install
    ships inside the package (``ftsweep/catalogs_data``)."""
    env = os.environ.get("FTSWEEP_CATALOGS")
    if env:
        return Path(env)
    package = Path(__file__).resolve().parents[1]  # ftsweep/, this module being ftsweep/inputs/
    repo = package.parent / "catalogs"
    return repo if (repo / "surfaces.yaml").is_file() else package / "catalogs_data"


def _format_error(path: Path, name: str, err: ValidationError, model: Any) -> str:
    lines = [f"{path}: entry '{name}' is invalid:"]
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"])
        where = f"{name}.{loc}" if loc else name
        if e["type"] == "extra_forbidden":
            allowed, key = allowed_keys(model, e["loc"][:-1]), str(e["loc"][-1])
            hint = f"{did_you_mean(key, allowed)} (allowed: {', '.join(allowed)})" if allowed else ""
            lines.append(f"  - {where}: unknown key{hint}")
        elif e["type"] == "missing":
            lines.append(f"  - {where}: required key is missing")
        elif e["type"] == "union_tag_invalid":  # a family nobody registered
            known = ", ".join(sorted(registered_surfaces()) + list(USER_FAMILIES))
            got = e.get("ctx", {}).get("tag")
            lines.append(
                f"  - {where}: unknown surface family {got!r}{did_you_mean(str(got), known.split(', '))}"
            )
            lines.append(f"    (known: {known}); {surfaceplugins.HOW}")
        else:
            lines.append(f"  - {where}: {error_text(e)} (got {short_repr(e.get('input'))})")
    return "\n".join(lines)


def _read_yaml(path: Path) -> dict[str, Any]:
    if not path.exists():
        env = os.environ.get("FTSWEEP_CATALOGS")
        why = (
            f"the folder FTSWEEP_CATALOGS={env} names has no {path.name}: point it at a folder of "
            "catalogs (surfaces.yaml, machines.yaml, cutting.yaml, ...) or unset it for the installed ones"
            if env and path.parent == Path(env)
            else "the catalogs are incomplete"
        )
        raise CatalogError(f"catalog file {path} does not exist: {why}")
    data = read_yaml_file(path)
    if not isinstance(data, dict) or not data:
        raise CatalogError(f"{path}: expected a mapping of entry names to entries")
    return data


def load_catalog(path: Path, model: Any) -> dict[str, Any]:
    """Load every entry of a catalog file into ``model`` (a pydantic model or union type)."""
    from pydantic import TypeAdapter

    adapter = TypeAdapter(model)
    out: dict[str, Any] = {}
    from ftsweep.freetext import TextError, check_text

    for name, entry in _read_yaml(path).items():
        try:
            check_text(name, "the entry's name")  # names are written into headers and programs
        except TextError as exc:
            raise CatalogError(f"{path}: entry {str(name)[:80]!r}: {exc}") from None
        if not isinstance(entry, dict):
            raise CatalogError(f"{path}: entry '{name}' must be a mapping, got {type(entry).__name__}")
        try:
            out[str(name)] = adapter.validate_python(entry)
        except ValidationError as exc:
            raise CatalogError(_format_error(path, str(name)[:80], exc, model)) from None
        except RecursionError:
            raise CatalogError(f"{path}: entry '{str(name)[:80]}' is nested too deeply") from None
    return out


@functools.lru_cache(maxsize=64)
def _cached(kind: str, folder: str, mtime_ns: int) -> dict[str, Any]:
    models = {"machines": Machine, "cutting": Cutting, "references": Reference}
    model = surface_spec() if kind == "surfaces" else models[kind]
    return load_catalog(Path(folder) / f"{kind}.yaml", model)


def entry(kind: str, name: str, folder: Path | None = None) -> Any:
    """One validated entry of catalog ``kind``: ``surfaces``, ``machines``, ``cutting`` or
    ``references``."""
    folder = folder or catalog_dir()
    entries = _load(kind, folder)
    if name not in entries:
        raise CatalogError(
            f"unknown {kind[:-1] if kind.endswith('s') else kind} '{name}'{did_you_mean(name, entries)} in "
            f"{folder / (kind + '.yaml')}; known: {', '.join(sorted(entries))}"
        )
    return entries[name]


def entries(kind: str, folder: Path | None = None) -> dict[str, Any]:
    """All validated entries of catalog ``kind``."""
    return dict(_load(kind, folder or catalog_dir()))


def _load(kind: str, folder: Path) -> dict[str, Any]:
    # the file's modification time is part of the key, so an edited catalog is re-read
    path = Path(folder) / f"{kind}.yaml"
    mtime = path.stat().st_mtime_ns if path.exists() else -1
    return _cached(kind, str(folder), mtime)
