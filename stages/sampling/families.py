"""The registry of surface families (model §7): each family's evaluator, parameters with
units, bounds of its gradient and curvature and its line evaluator, declared once by
:func:`surface_family` beside its kernels (:mod:`ftsweep.stages.sampling.arrays`,
:mod:`ftsweep.stages.sampling.forms`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple, Optional

import numpy as np


# --------------------------------------------------------------------------- registry
@dataclass(frozen=True)
class Param:
    """One catalog parameter of a surface family: its type (a plain annotation: float, int,
    list[list[float]], dict[int, float]), its description with units, its default (``...``:
    required) and constraints (``positive``: > 0; ``min_length`` of a list or mapping). The
    catalog's validated models are generated from these (ftsweep.inputs.catalogs)."""

    annotation: Any
    description: str
    default: Any = ...
    positive: bool = False
    min_length: Optional[int] = None


class Family(NamedTuple):
    """A surface family: its evaluator, an analytic bound of its gradient magnitude (None: the
    bound is estimated by sampling the aperture, see :func:`sampled_gradient_bound`), its
    catalog parameters, a check of parameter combinations (raises ValueError), and an
    analytic bound of the Hessian's spectral norm ‖∇²f‖ [1/µm] (None: unknown), with which
    exact compensation takes its fast solver where K·Rc < 1 (model §4), and a line evaluator
    ``lines(first, spacing, offset, n_nodes, cos_t, sin_t, **params) -> (g, g')`` that samples
    the radial sections of a path grid in one pass (see :func:`evaluate_lines`; None: the
    case runner forms the grid's x, y and calls ``evaluate``)."""

    evaluate: Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray]]
    gradient_bound: Callable[..., float] | None
    params: dict[str, Param]
    check: Callable[[dict[str, Any]], None] | None = None
    curvature_bound: Callable[..., float] | None = None
    lines: Callable[..., tuple[np.ndarray, np.ndarray]] | None = None


FAMILIES: dict[str, Family] = {}


def surface_family(
    name: str,
    params: dict[str, Param],
    gradient_bound: Callable[..., float] | None = None,
    check: Callable[[dict[str, Any]], None] | None = None,
    curvature_bound: Callable[..., float] | None = None,
    lines: Callable[..., tuple[np.ndarray, np.ndarray]] | None = None,
) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Register the decorated evaluator as surface family ``name`` (usable in the catalogs as
    ``family: name`` with ``params``): the one place a new family is declared."""

    def register(evaluate: Callable[..., Any]) -> Callable[..., Any]:
        if name in FAMILIES:
            raise ValueError(f"surface family {name!r} is registered twice")
        FAMILIES[name] = Family(evaluate, gradient_bound, dict(params), check, curvature_bound, lines)
        return evaluate

    return register


def _um(text: str) -> str:
    return text + " [µm]"
