"""The program requests: one pydantic model per program kind, tagged by ``kind``, in one
discriminated union (:data:`ProgramRequest`), like xarray's backend entrypoints each own their
options. A request is validated once, when it is built (CLI options, sweep YAML, cube specs
and sidecars all build the same model): another kind's field is refused naming its owner,
and each model checks its own combination rules.

Dumps keep the case keys written before the requests were split: a path request writes the
table's target fields as null, options added later are left out while unset.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Optional, Union

from pydantic import Field, PositiveFloat, TypeAdapter, model_serializer, model_validator

from ftsweep.inputs.catalogs import Strict, without_defaults
from ftsweep.stages import spiral

# every path request's dump carried the table's target fields (null) before the split
_TABLE_TARGET = {"pitch": None, "points": None, "aspect": None}


class _Request(Strict):
    """Base of the requests: a field of another kind is refused naming the kinds it belongs
    to (a null one, as stored cube specs carry, is dropped)."""

    kind: str

    @model_validator(mode="before")
    @classmethod
    def _own_fields(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        own = cls.model_fields
        foreign = [k for k, v in data.items() if k not in own and v is not None]
        if foreign:
            raise ValueError(
                f"a {_noun(data.get('kind'))} takes no {', '.join(foreign)}: {_owners(foreign[0])}"
            )
        return {k: v for k, v in data.items() if k in own}

    def label(self) -> str:
        """Short text of the request for progress and error lines."""
        given = self.model_dump(exclude_none=True, exclude={"kind"})
        return " ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in given.items())


def _noun(name: Any) -> str:
    from ftsweep import kinds

    return kinds.registry()[name].noun if name in kinds.registry() else f"{name} program"


def _owners(field: str) -> str:
    from ftsweep import kinds

    owners = [k for k in kinds.registry().values() if field in k.request.model_fields]
    if not owners:
        return "no program kind has it"
    return f"{field} belongs to " + " or ".join(f"{k.noun}s" for k in owners)


class TableRequest(_Request):
    """A ring or mesh table (model §2): explicit pitches, or a target point count and aspect.

    pitch: (Δρ [µm], Δθ [deg]) for rings, (Δx [µm], Δy [µm]) for meshes.
    points, aspect: target N and α (Δρ/Δθ [µm/deg] for rings, Δx/Δy for meshes).
    """

    kind: Literal["ring", "mesh"]
    pitch: Optional[tuple[PositiveFloat, PositiveFloat]] = None
    points: Optional[PositiveFloat] = None
    aspect: Optional[PositiveFloat] = None

    @model_validator(mode="after")
    def _one_way(self) -> TableRequest:
        target = self.points is not None or self.aspect is not None
        if self.pitch is not None and target:
            raise ValueError(
                "give either explicit pitches or a target point count and aspect ratio, not both"
            )
        if self.pitch is None and (self.points is None or self.aspect is None):
            raise ValueError("give explicit pitches, or both a target point count and an aspect ratio")
        return self

    def target(self) -> tuple[float, float]:
        """(points, aspect) of a target-count request."""
        if self.points is None or self.aspect is None:
            raise ValueError("this layout request gives explicit pitches, not a target")
        return self.points, self.aspect

    def label(self) -> str:
        if self.points is not None and self.aspect is not None:
            return f"N≈{self.points:,.0f} α={self.aspect:.3g}"
        return super().label()


SPIRAL_RULES = ("points_per_rev", "arc_um", "chord_um")


class SpiralRequest(_Request):
    """A spiral path program with one sampling rule ([4]): points_per_rev (constant angle),
    arc_um (constant arc length [µm]) or chord_um (chord-error budget [µm]); residual_um, the
    residual budget [µm] that sets the feed ([4] eqs. 1–3) instead of the cutting entry's."""

    kind: Literal["spiral"]
    points_per_rev: Optional[int] = Field(None, ge=3, description="spiral: points per revolution")
    arc_um: Optional[PositiveFloat] = Field(None, description="spiral: path length between points [µm]")
    chord_um: Optional[PositiveFloat] = Field(None, description="spiral: chord-error budget Δcho [µm]")
    residual_um: Optional[PositiveFloat] = Field(
        None, description="spiral: residual (cusp) budget Δres [µm] that sets the feed"
    )

    @model_serializer(mode="wrap")
    def _stable_dump(self, handler: Any) -> Any:
        return {
            **_TABLE_TARGET,
            **without_defaults(handler(self), dict.fromkeys(SPIRAL_RULES + ("residual_um",))),
        }

    @model_validator(mode="after")
    def _one_rule(self) -> SpiralRequest:
        rules = [name for name in SPIRAL_RULES if getattr(self, name) is not None]
        if len(rules) != 1:
            raise ValueError(
                "a spiral program needs exactly one sampling rule: points_per_rev, arc_um or "
                f"chord_um (got {', '.join(rules) or 'none'})"
            )
        return self

    def spiral_rule(self) -> tuple[str, float]:
        """(rule, parameter): ("angle", Np), ("arc", µm) or ("chord", µm)."""
        for name, rule in zip(SPIRAL_RULES, spiral.RULES, strict=True):
            value = getattr(self, name)
            if value is not None:
                return rule, float(value)
        raise AssertionError("validated with exactly one rule")


DPATH_FIELDS = (
    "spacing_um",
    "points_per_cut",
    "transition",
    "zones",
    "offaxis_um",
    "cut_angle_deg",
    "transition_step_deg",
)


class DPathRequest(_Request):
    """A D-shaped slow-tool-servo path ([5]); unset options take ``ftsweep.kinds.dpath.program.DEFAULTS``."""

    kind: Literal["dpath"]
    spacing_um: Optional[PositiveFloat] = Field(
        None, description="dpath: spacing h between cuts [µm] (default: the feed)"
    )
    points_per_cut: Optional[int] = Field(None, ge=2, description="dpath: points on every cut (default 201)")
    transition: Optional[Literal["traditional", "optimised"]] = Field(
        None, description="dpath: turn-round between cuts, arc (traditional) or quintic (optimised, default)"
    )
    zones: Optional[Literal[1, 2, 4]] = Field(
        None, description="dpath: cutting zones per revolution (default 1)"
    )
    offaxis_um: Optional[PositiveFloat] = Field(
        None, description="dpath: distance of the part's centre from the C axis [µm] (default 30 mm)"
    )
    cut_angle_deg: Optional[float] = Field(
        None, description="dpath: direction of the cuts in the part's frame [deg from +x] (default 90)"
    )
    transition_step_deg: Optional[PositiveFloat] = Field(
        None, description="dpath: largest C step between transition points [deg] (default 1)"
    )

    @model_serializer(mode="wrap")
    def _stable_dump(self, handler: Any) -> Any:
        return {**_TABLE_TARGET, **without_defaults(handler(self), dict.fromkeys(DPATH_FIELDS))}


class FresnelRequest(_Request):
    """A freeform Fresnel program on an X-Y-Z-C lathe ([2]); unset options take
    ``ftsweep.kinds.fresnel.program.DEFAULTS``. The case's compensation selects [2]'s tool-edge
    compensation: exact (eq. 10), slope (the straight-line eq. 12) or none."""

    kind: Literal["fresnel"]
    facet_height_um: Optional[PositiveFloat] = Field(
        None, description="fresnel: facet height h [µm] (default 10)"
    )
    points_per_turn: Optional[int] = Field(
        None, ge=8, description="fresnel: control points K on every turn of the quasi-spiral (default 360)"
    )
    deviation_deg: Optional[float] = Field(
        None, ge=-45.0, le=45.0, description="fresnel: rake face turned from the cutting direction [deg]"
    )
    safety: Optional[float] = Field(
        None, ge=1.0, le=10.0, description="fresnel: safety factor K_s on the axis limits (default 1.25)"
    )
    control_points: Optional[Literal["auto", "polar", "arc"]] = Field(
        None,
        description="fresnel: control points polar about the edges' centroids (eqs. 5-6), by arc length "
        "(appendix A.3) or auto (default)",
    )

    @model_serializer(mode="wrap")
    def _stable_dump(self, handler: Any) -> Any:
        return without_defaults(handler(self), dict.fromkeys(FRESNEL_FIELDS))


FRESNEL_FIELDS = ("facet_height_um", "points_per_turn", "deviation_deg", "safety", "control_points")

# one member per kind; a new kind adds its model here and its entry to kinds.registry()
ProgramRequest = Annotated[
    Union[TableRequest, SpiralRequest, DPathRequest, FresnelRequest], Field(discriminator="kind")
]
_ADAPTER: TypeAdapter[Any] = TypeAdapter(ProgramRequest)


def program_request(**fields: Any) -> Any:
    """The validated request of ``fields`` (``kind`` picks the model; pydantic's
    ValidationError names a bad field)."""
    return _ADAPTER.validate_python(fields)
