"""What an inverse-time program's F makes of its blocks (docs/controllers.md): a reading of
G93's F no lathe could run — a spindle outside a lathe's speeds, hours a revolution, a block
shorter than the controller's servo period — is refused naming the block's line and the
convention that is the likely cause (machine.controller.g93_f)."""

from __future__ import annotations

import math
from typing import Any, Optional

import numpy as np

from ftsweep.inputs.programs.moves import DialectError, Moves

# what a lathe's spindle program can be [rpm], and its slowest revolution [s]
RPM_RANGE = (0.1, 20_000.0)
MAX_REVOLUTION_S = 3600.0


def check_timing(m: Moves, ctrl: Any, first_f: Optional[str]) -> None:
    """Refuse a reading of ``m``'s block times [s] that cannot be a lathe program under the
    profile ``ctrl``: the program's mean spindle speed or any block's outside
    :data:`RPM_RANGE`, a revolution over :data:`MAX_REVOLUTION_S`, a block under the servo
    period. ``first_f``: where the first G93 F stands and what it is read as (the hint)."""
    seconds = np.asarray(m.seconds, dtype=np.float64)
    turn = np.abs(np.diff(m.c_deg)) / 360.0
    timed = np.isfinite(seconds) & (seconds > 0)
    total, revs = float(np.sum(seconds[timed])), float(np.sum(turn[timed]))
    rpm = revs / total * 60.0 if total > 0 else math.nan
    hint, question = first_f or "the program", _question(ctrl)
    if revs > 0 and not RPM_RANGE[0] <= rpm <= RPM_RANGE[1]:
        raise DialectError(f"{hint} gives a spindle of {rpm:.3g} rpm, not a lathe's{question}")
    per_rev = np.divide(seconds, turn, out=np.zeros_like(seconds), where=timed & (turn > 0))
    if np.any(per_rev > MAX_REVOLUTION_S):
        k = int(np.argmax(per_rev))
        raise DialectError(
            f"{m.where(k + 1)}: {hint} gives {per_rev[k] / 3600.0:.3g} hours a revolution{question}"
        )
    block_rpm = np.divide(turn * 60.0, seconds, out=np.full(seconds.shape, np.nan), where=timed)
    fast = np.flatnonzero(block_rpm > RPM_RANGE[1])
    if fast.size:
        k = int(fast[0])
        raise DialectError(
            f"{m.where(k + 1)}: a block of {seconds[k]:.3g} s turning C {turn[k] * 360.0:.4g} deg gives a "
            f"spindle of {block_rpm[k]:.3g} rpm, not a lathe's ({hint}){question}"
        )
    period = ctrl.servo_period_s
    short = timed & (seconds < (period or 0.0) * (1 - 1e-9))
    if np.any(short):
        k = int(np.flatnonzero(short)[0])
        raise DialectError(
            f"{m.where(k + 1)}: a block of {seconds[k]:.3g} s, under the controller's servo period "
            f"{period:g} s ({hint}){question}"
        )


def _question(ctrl: Any) -> str:
    other = "seconds per block" if ctrl.g93_f == "inverse_minutes" else "inverse minutes"
    return f": does this controller read F as {other}? see machine.controller.g93_f"
