"""The request of a freeform Fresnel program on an X-Y-Z-C lathe ([2])."""

from __future__ import annotations

from typing import Any, Literal, Optional

from pydantic import Field, PositiveFloat, model_serializer

from ftsweep.engine.case import Request
from ftsweep.kinds.fresnel.names import FRESNEL_FIELDS


class FresnelRequest(Request):
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

    timing: Optional[Literal["optimal", "paper", "constant"]] = Field(
        None,
        description="fresnel: timesteps: the least time the limits allow (optimal, default), [2]'s "
        "eqs. 15-16 (paper) or one constant step",
    )

    @model_serializer(mode="wrap")
    def _stable_dump(self, handler: Any) -> Any:
        return self.stable_dump(handler(self), FRESNEL_FIELDS)
