"""The controller entry of a machine (docs/controllers.md): the dialect its path programs are
written in, how it forms the path between points, and its limits."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, PositiveFloat, PositiveInt, model_validator

from ftsweep.inputs.strict import Strict

# the interpolation each program dialect commands (docs/controllers.md)
DIALECT_INTERPOLATION = {
    "text": "linear",
    "iso-sts": "linear",
    "linuxcnc": "linear",
    "pmac-pvt": "pvt",
    "pmac-spline": "spline1",
}


class Controller(Strict):
    """The controller that runs a machine's path programs (docs/controllers.md): the dialect
    it reads, how it forms the path between points, and its limits."""

    dialect: Literal["text", "iso-sts", "pmac-pvt", "pmac-spline", "linuxcnc"] = Field(
        "text", description="program dialect export writes by default"
    )
    interpolation: Literal["linear", "pvt", "spline1"] = Field(
        "linear",
        description="how the path between program points is formed: linear segments, cubic Hermite "
        "through positions and velocities (PVT), uniform cubic B-spline (SPLINE1)",
    )
    g93_f: Literal["inverse_minutes", "seconds"] = Field(
        "inverse_minutes",
        description="meaning of F under G93: 1/(block time in minutes) (ISO, LinuxCNC) or the block "
        "time in seconds",
    )
    time_quantum_s: PositiveFloat = Field(
        1e-6, description="resolution of a segment's time [s] (PMAC PVT: 0.25 µs; SPLINE1: 1 ms)"
    )
    max_segment_s: PositiveFloat = Field(60.0, description="longest time one segment may take [s]")
    decimals: int = Field(6, ge=3, le=9, description="digits after the point of positions (mm, deg)")
    c_wrap: Literal["revolution", "cumulative"] = Field(
        "revolution", description="C printed modulo 360 deg (revolution) or accumulated (cumulative)"
    )
    max_blocks: PositiveInt = Field(50_000_000, description="most program blocks the controller accepts")

    @model_validator(mode="after")
    def _dialect_matches(self) -> Controller:
        want = DIALECT_INTERPOLATION[self.dialect]
        if self.interpolation != want:
            raise ValueError(
                f"dialect {self.dialect} commands {want} interpolation, but interpolation is "
                f"{self.interpolation}"
            )
        return self
