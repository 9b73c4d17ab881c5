"""The request of a spiral path program ([4]): one sampling rule and an optional residual budget."""

from __future__ import annotations

from typing import Any, ClassVar, Literal, Optional

from pydantic import Field, PositiveFloat, model_serializer, model_validator

from ftsweep.engine.case import Case, Request
from ftsweep.stages.paths import spiral

SPIRAL_RULES = ("points_per_rev", "arc_um", "chord_um")


class SpiralRequest(Request):
    """A spiral path program with one sampling rule ([4]): points_per_rev (constant angle),
    arc_um (constant arc length [µm]) or chord_um (chord-error budget [µm]); residual_um, the
    residual budget [µm] that sets the feed ([4] eqs. 1–3) instead of the cutting entry's."""

    kind: Literal["spiral"]
    # its dumps carried the table's target fields (null) before each kind had its own request
    null_fields: ClassVar[tuple[str, ...]] = ("pitch", "points", "aspect")
    points_per_rev: Optional[int] = Field(None, ge=3, description="spiral: points per revolution")
    arc_um: Optional[PositiveFloat] = Field(None, description="spiral: path length between points [µm]")
    chord_um: Optional[PositiveFloat] = Field(None, description="spiral: chord-error budget Δcho [µm]")
    residual_um: Optional[PositiveFloat] = Field(
        None, description="spiral: residual (cusp) budget Δres [µm] that sets the feed"
    )

    @model_serializer(mode="wrap")
    def _stable_dump(self, handler: Any) -> Any:
        return self.stable_dump(handler(self), SPIRAL_RULES + ("residual_um",))

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


def request_of(case: Case) -> SpiralRequest:
    """The spiral request of a case (TypeError for a case of another kind: a planner of this kind
    is handed only its own)."""
    if not isinstance(case.layout, SpiralRequest):
        raise TypeError(f"a {case.layout.kind} case is not a spiral program's")
    return case.layout
