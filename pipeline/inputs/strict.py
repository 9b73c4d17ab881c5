"""The base of every catalog spec, and the physically meaningful range of every number."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Annotated, Any, Optional, Union

from pydantic import BaseModel, ConfigDict, model_validator

__all__ = ["UNITS", "did_you_mean", "unit_of"]

# a number's unit from the end of its name: (suffix, symbol, as a sentence says it)
UNITS = (
    ("_mm_min", "mm/min", "mm/min"),
    ("_um", "µm", "µm"),
    ("_nm", "nm", "nm"),
    ("_mm", "mm", "mm"),
    ("_deg", "°", "degrees"),
    ("_rpm", "rpm", "rpm"),
    ("_hz", "Hz", "Hz"),
    ("_s", "s", "seconds"),
)


def unit_of(name: str) -> Optional[tuple[str, str, str]]:
    """``(suffix, symbol, words)`` of the unit a name ends with (``chord_um``: µm), else None."""
    return next((unit for unit in UNITS if name.endswith(unit[0])), None)


def did_you_mean(word: str, known: Any) -> str:
    """`` (did you mean 'axes'?)`` for the known name closest to a misspelt ``word`` (difflib's
    ratio ≥ 0.6), else an empty string: the hint a refusal of an unknown key or name ends with."""
    import difflib

    close = difflib.get_close_matches(str(word)[:100], [str(k) for k in known], n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


# the largest magnitude of a length in µm any part, pitch, feed or travel has: 10 m
MAX_LENGTH_UM = 1e7
# the smallest tool radius a diamond has: 1 nm (a sharper one divides the envelope by ~0)
MIN_RADIUS_UM = 1e-3
# the most points, samples or cases one count may ask for (a controller holds ~10⁶)
MAX_COUNT = 1e9
# anything else (speeds, accelerations, frequencies, ratios, angles in degrees): no
# quantity of a lathe is this large in its unit
MAX_MAGNITUDE = 1e12

_COUNTS = ("points", "samples", "cases", "bins", "layers", "rows", "cols", "turns", "cuts")


def physical_range(name: str) -> tuple[float, float]:
    """``(smallest non-zero magnitude, largest magnitude)`` a number named ``name`` may have,
    by its unit (the suffix of its name: ``_um`` a length in µm) and its role (a radius, a
    count)."""
    low = MIN_RADIUS_UM if "radius" in name and name.endswith("_um") else 0.0
    if name.endswith("_um"):
        return low, MAX_LENGTH_UM
    if any(word in name for word in _COUNTS) and not name.endswith(("_nm", "_s", "_hz", "_deg")):
        return 0.0, MAX_COUNT
    return 0.0, MAX_MAGNITUDE


def check_physical(name: str, value: float) -> Optional[str]:
    """None when ``value`` lies within :func:`physical_range` of ``name``, else what is wrong,
    naming the range."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    low, high = physical_range(name)
    if not math.isfinite(value) or abs(value) > high or (value != 0 and abs(value) < low):
        bounds = f"{low:g} to {high:g}" if low else f"at most {high:g} in magnitude"
        return f"{value:g} is outside the physically meaningful range of {name} ({bounds})"
    return None


def _numbers(value: Any) -> Iterator[float]:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        yield value
    elif isinstance(value, (list, tuple)):
        for item in value:
            yield from _numbers(item)
    elif isinstance(value, dict):
        for item in value.values():
            yield from _numbers(item)
    elif isinstance(value, BaseModel):  # an axis range: its ends and steps are the axis's numbers
        yield from _numbers(value.model_dump())


class Strict(BaseModel):
    """Base of every spec: unknown keys, mutation, non-finite numbers and numbers outside
    their unit's physically meaningful range (:func:`physical_range`) are refused."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, defer_build=True)

    @model_validator(mode="after")
    def _physical(self) -> Strict:
        fields = {name: getattr(self, name) for name in type(self).model_fields}
        for name, value in {**fields, **(self.model_extra or {})}.items():
            for number in _numbers(value):
                problem = check_physical(name, number)
                if problem:
                    raise ValueError(problem)
        return self


def allowed_keys(model: Any, loc: tuple[Any, ...]) -> list[str]:
    """Field names of the (sub)model at ``loc``, following discriminated-union tags."""
    candidates = union_members(model)
    for part in loc:
        nxt = []
        for m in candidates:
            if isinstance(m, type) and issubclass(m, BaseModel):
                if part in m.model_fields:
                    nxt.extend(union_members(m.model_fields[part].annotation))
                elif isinstance(part, str):
                    # a discriminated union puts the tag value in loc: keep the tagged member
                    tag = [
                        f
                        for f in m.model_fields.values()
                        if getattr(f.annotation, "__args__", None) == (part,)
                    ]
                    if tag:
                        nxt.append(m)
        candidates = nxt
    names: list[str] = []
    for m in candidates:
        if isinstance(m, type) and issubclass(m, BaseModel):
            names.extend(k for k in m.model_fields if k not in names)
    return names


def union_members(annotation: Any) -> list[Any]:
    """The models an annotation may hold: a union's members, through ``Annotated``."""
    args: tuple[Any, ...] = tuple(getattr(annotation, "__args__", None) or ())
    origin = getattr(annotation, "__origin__", None)
    if origin is Annotated or (args and getattr(annotation, "__metadata__", None)):
        return union_members(args[0])
    if origin is Union:
        return [m for a in args for m in union_members(a)]
    return [annotation]
