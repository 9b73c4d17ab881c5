"""The controller entry of a machine (docs/controllers.md): the dialect its path programs are
written in, how it forms the path between points, its limits, and every convention a program
depends on (the controller's profile), so that a program is read as that controller reads it."""

from __future__ import annotations

from typing import Literal, Optional

import numpy as np
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

# a profile's conventions where an entry leaves them unset: what each dialect's controller does
# at power-on with its factory parameters (docs/controllers.md, "Controller profiles")
DIALECT_CONVENTIONS: dict[str, dict[str, object]] = {
    "linuxcnc": {
        "whole_number_words": "mm",
        "power_on_motion": "none",
        "g93_f_every_block": True,
        "dwell_p": "s",
        "c_wrap": "cumulative",
    },
    # a PMAC motor's factory Ixx27 is 0: no rollover, C as written
    "pmac-pvt": {"c_wrap": "cumulative"},
    "pmac-spline": {"c_wrap": "cumulative"},
}


class Controller(Strict):
    """The controller that runs a machine's path programs (docs/controllers.md): the dialect
    it reads, how it forms the path between points, its limits, and its profile — the
    conventions a program depends on (units of a word without a decimal point, power-on modal
    state, what G93's F means, dwell and offset codes, PMAC's time units)."""

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
        description="meaning of F under G93: 1/(block time in minutes) (RS274, LinuxCNC, Fanuc) or the "
        "block time in seconds (Moore, Beckhoff)",
    )
    g93_f_every_block: bool = Field(
        False, description="every G93 motion block must carry its own F (LinuxCNC); else F is modal"
    )
    f_min: Optional[PositiveFloat] = Field(None, description="least F a block may carry (none: unchecked)")
    f_max: Optional[PositiveFloat] = Field(None, description="largest F a block may carry (none: unchecked)")
    whole_number_words: Literal["mm", "increments", "refuse"] = Field(
        "refuse",
        description="an axis word without a decimal point (X1): millimetres (Moore, LinuxCNC), least "
        "input increments of input_increment_um (Fanuc without decimal-point programming), or refused "
        "as ambiguous",
    )
    input_increment_um: PositiveFloat = Field(
        1.0, description="the least input increment a whole-number word counts [µm] (Fanuc IS-B: 1)"
    )
    power_on_motion: Literal["G00", "G01", "none"] = Field(
        "G00",
        description="motion mode before the program sets one: rapid, linear (Moore), or none (LinuxCNC: "
        "an axis word before G0/G1 is an error)",
    )
    power_on_feed: Literal["G93", "G94"] = Field("G94", description="feed mode before the program sets one")
    power_on_distance: Literal["G90", "G91"] = Field("G90", description="absolute or incremental at power-on")
    dwell_p: Literal["ms", "s"] = Field(
        "ms", description="units of G04's P word (Fanuc, Moore: ms; LinuxCNC: s); G04 X is always seconds"
    )
    servo_period_s: Optional[PositiveFloat] = Field(
        None,
        description="the controller's interpolation period [s]: no block may take less (none: unchecked)",
    )
    ix90_ms: PositiveFloat = Field(
        1000.0,
        description="the time unit of PVT velocities and feed rates [ms] (Turbo PMAC Isx90, PMAC/PMAC2 "
        "Ix90, Power PMAC Coord[x].FeedTime); 1000: per second, 60000: per minute",
    )
    i42: Literal[0, 1] = Field(
        0,
        description="Turbo PMAC I42: which word times SPLINE and PVT moves, 0 TM, 1 TA (PVT<ms> sets the "
        "time in either); times in ms, 0-4,095.9998 ms at 1/4 µs in both",
    )
    pmac_syntax: Literal["turbo", "power"] = Field(
        "turbo",
        description="Turbo PMAC (PVT<ms>, SPLINE1 timed by TM or TA) or Power PMAC (pvt<ms>, spline<ms>)",
    )
    time_quantum_s: PositiveFloat = Field(
        1e-6, description="resolution of a segment's time [s] (PMAC PVT and SPLINE: 0.25 µs)"
    )
    max_segment_s: PositiveFloat = Field(60.0, description="longest time one segment may take [s]")
    decimals: int = Field(6, ge=3, le=9, description="digits after the point of positions (mm, deg)")
    c_wrap: Literal["revolution", "cumulative"] = Field(
        "revolution", description="C printed modulo 360 deg (revolution) or accumulated (cumulative)"
    )
    max_blocks: PositiveInt = Field(50_000_000, description="most program blocks the controller accepts")
    c_limit_deg: Optional[PositiveFloat] = Field(
        None,
        description="the C axis's soft limit [deg] where C is printed accumulated (LinuxCNC: the INI's "
        "MIN_LIMIT/MAX_LIMIT of the C joint); none: a wrapped rotary, unlimited",
    )

    @model_validator(mode="before")
    @classmethod
    def _dialect_conventions(cls, data: object) -> object:
        if isinstance(data, dict):
            return {**DIALECT_CONVENTIONS.get(str(data.get("dialect")), {}), **data}
        return data

    @model_validator(mode="after")
    def _dialect_matches(self) -> Controller:
        want = DIALECT_INTERPOLATION[self.dialect]
        if self.interpolation != want:
            raise ValueError(
                f"dialect {self.dialect} commands {want} interpolation, but interpolation is "
                f"{self.interpolation}"
            )
        if self.f_min is not None and self.f_max is not None and self.f_min > self.f_max:
            raise ValueError(f"f_min {self.f_min:g} is above f_max {self.f_max:g}")
        return self

    @property
    def pmac_timer(self) -> str:
        """The word that times a Turbo PMAC's SPLINE and PVT moves under its I42 (the Software
        Reference's I42 entry: 0 TM, 1 TA; ``PVT<ms>`` sets the time in either)."""
        return "TA" if self.i42 == 1 else "TM"

    @property
    def one_segment_time(self) -> bool:
        """Whether every segment of a move takes one time (SPLINE1: one TM, or TA under I42 = 1,
        for the whole sequence), so a program's points must lie evenly in time."""
        return self.interpolation == "spline1"

    def segment_refusal(self, seconds: np.ndarray) -> str:
        """Why this controller cannot run segments taking ``seconds`` [s] one after another, or
        '' where it can (docs/controllers.md, "Interpolation"): none may take longer than
        ``max_segment_s``; under SPLINE1 every segment but the last (it ends where the path
        does) takes one time, in whole ``time_quantum_s`` steps (Turbo PMAC's I42 entry: ms at
        1/4 µs). NaN entries, a layered program's approach moves, are passed over."""
        from ftsweep.stages.interpolation.segments import whole_steps  # loads numba: not for a catalog

        seconds = np.asarray(seconds, dtype=float)
        longest = float(np.nanmax(seconds, initial=0.0))
        if longest > self.max_segment_s:
            return (
                f"a segment takes {longest * 1e3:.6g} ms, longer than the controller's "
                f"{self.max_segment_s * 1e3:g} ms"
            )
        inner = seconds[:-1]
        if not self.one_segment_time or not inner.size:
            return ""
        word = "spline<ms>" if self.pmac_syntax == "power" else self.pmac_timer
        if not np.allclose(inner, inner[0], rtol=1e-9, atol=0.0):
            return (
                f"SPLINE1 segments all take one time ({word}): these take "
                f"{float(inner.min()) * 1e3:.6g} to {float(inner.max()) * 1e3:.6g} ms"
            )
        if not whole_steps(float(inner[0]), self.time_quantum_s):
            return (
                f"SPLINE1 segments all take one time ({word}) of whole {self.time_quantum_s * 1e6:g} µs "
                f"steps: these take {float(inner[0]) * 1e3:.6g} ms"
            )
        return ""

    def cut_rule(self) -> str:
        """How a reader of this dialect tells a cut from the moves that are not cuts, where a
        cut starts and how it ends (docs/controllers.md, "What a cut is")."""
        if self.dialect.startswith("pmac"):
            ends = (
                "SPLINE1's added pieces: one segment time from rest before the first point and one to rest "
                "after the last"
                if self.interpolation == "spline1"
                else "a PVT cut starts at rest (velocity 0 at the RAPID's end point) and ends at its last "
                "point's velocity, or at rest where that is 0 (a stop segment)"
            )
            return (
                "a cut is the PVT or SPLINE moves after the RAPID or LINEAR moves to the start; it ends at "
                f"the next RAPID or LINEAR (the retract, not cut) or CLOSE; {ends}"
            )
        return (
            "a cut is a run of G93 (inverse-time) feed blocks that turn C, from where the tool stands; "
            "a G93 block that moves no axis (C360 -> C0 modulo 360) stands still for its time, a G93 move "
            "that does not turn C and every G94 or G00 move are not cuts and end one; M2/M30 ends the program"
        )

    def conventions(self) -> list[str]:
        """The conventions a program of this controller's dialect relies on, in the
        controller's words (each exported file's header states them; verify compares)."""
        if self.dialect.startswith("pmac"):
            mode = "PVT" if self.interpolation == "pvt" else "SPLINE1"
            rollover = (
                "rolls over each revolution (Ixx27)" if self.c_wrap == "revolution" else "without rollover"
            )
            if self.pmac_syntax == "power":
                unit = f"Coord[x].FeedTime={self.ix90_ms:g}"
                timing = "segment time in pvt<ms>/spline<ms>"
            else:
                unit = f"Isx90={self.ix90_ms:g}"
                timing = f"I42={self.i42} segment time by {self.pmac_timer} or PVT<ms>"
            return [
                f"{unit} velocity per {self.ix90_ms / 1000.0:g} s, {timing} in ms at 1/4 us steps, "
                f"{self.pmac_syntax.title()} PMAC {mode} syntax, ABS, C {rollover}"
            ]
        f = "block time in s" if self.g93_f == "seconds" else "1/block time in 1/min"
        words = {"mm": "mm", "increments": f"{self.input_increment_um:g} um increments", "refuse": "refused"}
        return [
            f"G93 F = {f}{' on every block' if self.g93_f_every_block else ''}, power-on "
            f"{self.power_on_motion} {self.power_on_feed} {self.power_on_distance}, axis words without a "
            f"point {words[self.whole_number_words]}, G04 P in {self.dwell_p}, C {self.c_wrap}"
            + (f" within {self.c_limit_deg:g} deg" if self.c_limit_deg is not None else "")
        ]
