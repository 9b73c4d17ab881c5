"""The request of a D-shaped slow-tool-servo path ([5])."""

from __future__ import annotations

from typing import Any, ClassVar, Literal, Optional

from pydantic import Field, PositiveFloat, model_serializer

from ftsweep.engine.case import Case, Request

DPATH_FIELDS = (
    "spacing_um",
    "points_per_cut",
    "transition",
    "zones",
    "offaxis_um",
    "cut_angle_deg",
    "transition_step_deg",
)


class DPathRequest(Request):
    """A D-shaped slow-tool-servo path ([5]); unset options take ``ftsweep.kinds.dpath.program.DEFAULTS``."""

    kind: Literal["dpath"]
    # its dumps carried the table's target fields (null) before each kind had its own request
    null_fields: ClassVar[tuple[str, ...]] = ("pitch", "points", "aspect")
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
        return self.stable_dump(handler(self), DPATH_FIELDS)


def request_of(case: Case) -> DPathRequest:
    """The dpath request of a case (TypeError for a case of another kind: a planner of this kind
    is handed only its own)."""
    if not isinstance(case.layout, DPathRequest):
        raise TypeError(f"a {case.layout.kind} case is not a dpath program's")
    return case.layout
