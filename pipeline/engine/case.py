"""The spec of one case: an immutable, validated value with a stable key (its canonical JSON's
hash). A case names its surface, program request (one model per kind, each a
:class:`Request` declared in its kind's package and found by its ``kind`` through
:mod:`ftsweep.registry`), machine, cutting conditions and resolution; every combination rule
is checked once, when the spec is built (CLI options, sweep YAML and sidecars alike).
"""

from __future__ import annotations

import hashlib
import json
from typing import Any, ClassVar, Literal, Optional

from pydantic import (
    Field,
    PositiveFloat,
    PositiveInt,
    SerializeAsAny,
    field_validator,
    model_serializer,
    model_validator,
)

from ftsweep.defaults import POINTS_PER_FEED, SAMPLES_PER_CELL
from ftsweep.engine import plugins as registry
from ftsweep.inputs import catalogs
from ftsweep.inputs.catalogs import Strict
from ftsweep.inputs.strict import unit_of


class CaseError(ValueError):
    """A case cannot be run as specified; the message says what to change."""


class Request(Strict):
    """Base of the program requests, one model per kind tagged by ``kind``, like xarray's
    backend entrypoints each own their options: a field of another kind is refused naming
    the kinds it belongs to (a null one, as stored cube specs carry, is dropped).

    ``null_fields``: fields a kind's dump writes as null though it has none of them, so that
    case keys written before the requests were split stay the same.
    """

    kind: str
    null_fields: ClassVar[tuple[str, ...]] = ()

    @model_validator(mode="before")
    @classmethod
    def _own_fields(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        own = cls.model_fields
        foreign = [k for k, v in data.items() if k not in own and v is not None]
        if foreign:
            raise ValueError(
                f"a {registry.noun(data.get('kind'))} takes no {', '.join(foreign)}: "
                f"{registry.owners(foreign[0])}"
            )
        return {k: v for k, v in data.items() if k in own}

    def stable_dump(self, dumped: dict[str, Any], optional: tuple[str, ...]) -> dict[str, Any]:
        """``dumped`` without the ``optional`` fields left unset, after the kind's null fields."""
        return {
            **dict.fromkeys(self.null_fields),
            **catalogs.without_defaults(dumped, dict.fromkeys(optional)),
        }

    def label(self) -> str:
        """Short text of the request for progress and error lines: its given fields with their
        units (``chord 0.5 µm``), the unset ones left out."""
        given = self.model_dump(exclude_none=True, exclude={"kind"})
        return " ".join(_field_text(k, v) for k, v in given.items() if v is not None)


def _field_text(name: str, value: Any) -> str:
    """``chord 0.5 µm`` for ``chord_um=0.5``; ``points_per_rev=500`` for a count."""
    number = f"{value:g}" if isinstance(value, float) else str(value)
    unit = unit_of(name)
    if unit is None:
        return f"{name}={number}"
    suffix, symbol, _ = unit
    return f"{name[: -len(suffix)]} {number}{'' if symbol == '°' else ' '}{symbol}"


def program_request(**fields: Any) -> Any:
    """The validated request of ``fields``: ``kind`` picks the registered kind's model
    (ValueError naming an unknown kind, pydantic's ValidationError a bad field)."""
    model: Any = registry.kind(fields.get("kind")).request
    return model.model_validate(fields)


class Resolution(Strict):
    """Simulation resolution (model §5). The defaults are converged: P-V moves by less
    than 3 % when the angular samples are quadrupled and the points per feed doubled."""

    samples_per_cell: PositiveInt = Field(
        SAMPLES_PER_CELL,
        description="spindle angles sampled per table cell at the outer radius; an odd number puts "
        "one sample on each ring cell's angular midpoint, where bilinear error peaks",
    )
    points_per_feed: PositiveInt = Field(
        POINTS_PER_FEED,
        description="evaluation points per feed along each angle; even, so the cusp midway "
        "between passes is a node",
    )
    n_theta: Optional[PositiveInt] = Field(
        None, description="number of sampled spindle angles over 360°; overrides samples_per_cell"
    )
    compensation_scan: int = Field(
        5,
        ge=3,
        le=256,
        description="coarse-scan samples of the exact compensation where the surface declares no "
        "curvature bound (with one, the solver and its scan density follow from the bound)",
    )
    zone_split: float = Field(
        0.5, gt=0.0, lt=1.0, description="inner/outer zone boundary as a fraction of the inscribed radius"
    )
    error_map_bins: Optional[int] = Field(
        None,
        ge=4,
        le=1024,
        description="bins per side of a coarse error map over the aperture (None: no map)",
    )

    interp_error: bool = Field(
        True,
        description="also simulate the envelope of the exact commands, for pv_interp_nm (the "
        "interpolation-only error, model §6); off skips them (about a fifth of a case) and "
        "leaves pv_interp_nm NaN",
    )

    angular_ladder: Optional[float] = Field(
        None,
        gt=1.0,
        le=2.0,
        description="round the angular samples of the samples_per_cell rule up to the next rung "
        "2·⌈r^k/2⌉ of a geometric ladder of ratio r, so cases of a sweep with nearby samplings share "
        "the same lines and reuse their layout-independent work; costs up to a factor r more samples, "
        "and ring samples no longer fall on the cells' angular midpoints (None: the rule's own count)",
    )

    @model_serializer(mode="wrap")
    def _stable_dump(self, handler: Any) -> Any:
        # cubes of specs written before these options existed stay resumable
        return catalogs.without_defaults(handler(self), {"interp_error": True, "angular_ladder": None})

    @field_validator("points_per_feed")
    @classmethod
    def _even(cls, value: int) -> int:
        if value % 2:
            raise ValueError("must be even so the cusp midway between passes is sampled")
        return value


class Case(Strict):
    """Everything that determines one prediction. ``key()`` is stable across processes."""

    surface: str
    layout: SerializeAsAny[Request]
    machine: str = "fts-1m"
    cutting: str = "reference"
    feed_um: Optional[PositiveFloat] = Field(None, description="overrides the cutting entry [µm/rev]")
    nose_radius_um: Optional[PositiveFloat] = Field(None, description="overrides the cutting entry [µm]")
    compensation: Literal["exact", "slope", "none"] = "exact"
    correction_gain: Optional[float] = Field(
        None, gt=0.0, le=1.5, description="overrides the surface's measured correction's gain [-]"
    )
    correction_terms: Optional[PositiveInt] = Field(
        None, description="overrides the terms its measured correction keeps (the low-pass)"
    )
    resolution: Resolution = Resolution()
    layers: Literal["auto", "off"] = Field(
        "auto",
        description="auto: cut commands spanning more than the machine's travel in layers ([3]); "
        "off: one pass, infeasible when the commands exceed the travel",
    )
    z_error_um: Optional[float] = Field(
        None, description="Z positioning error per retraction between layers [µm]; overrides the machine's"
    )
    layer_change_s: Optional[float] = Field(
        None,
        ge=0.0,
        description="time per layer segment to stop the spindle, move Z and restart [s]; overrides the "
        "machine's",
    )

    @field_validator("layout", mode="before")
    @classmethod
    def _request_of_its_kind(cls, value: Any) -> Any:
        if isinstance(value, Request):
            return value
        if not isinstance(value, dict) or "kind" not in value:
            raise ValueError("a program request is a mapping with its kind")
        model: Any = registry.kind(value["kind"]).request
        return model.model_validate(value)

    @model_serializer(mode="wrap")
    def _stable_dump(self, handler: Any) -> Any:
        # keys of cases written before layered machining stay the same
        return catalogs.without_defaults(
            handler(self),
            {
                "layers": "auto",
                "z_error_um": None,
                "layer_change_s": None,
                "correction_gain": None,
                "correction_terms": None,
            },
        )

    def feed_of(self, cutting: Any) -> float:
        """The feed F given [µm/rev]: the case's, else its cutting entry's (a spiral's residual
        budget or a D path's spacing may set another: its kind's ``feed``)."""
        return float(self.feed_um or cutting.feed_um)

    def nose_radius_of(self, cutting: Any) -> float:
        """The nose radius Rc in force [µm]: the case's, else its cutting entry's."""
        return float(self.nose_radius_um or cutting.nose_radius_um)

    def key(self) -> str:
        """Stable hash of the canonical JSON of the spec (16 hex digits)."""
        text = json.dumps(self.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]
