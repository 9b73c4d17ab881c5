"""The request of a ring or mesh table (model §2)."""

from __future__ import annotations

from typing import Literal, Optional

from pydantic import PositiveFloat, model_validator

from ftsweep.engine.case import Request


class TableRequest(Request):
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
