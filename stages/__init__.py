"""Pure numerical stages of ftsweep (numpy/numba only), one subpackage a stage of the
pipeline a case runs through, in its order (docs/architecture.md, "The flow of a case"):

=================  ===========================================================================
``sampling``       surface sampling: the design heights and gradients of every family (model §7)
``layouts``        the table of control points: ring and mesh grids, their first-order error (§2, §3)
``interpolation``  what the controller commands at a point of the path: nose compensation (§4),
                   bilinear tables (§3), the segments between a path program's points
``envelope``       the lower envelope of the tool's nose arcs: the surface left behind (§5)
``metrics``        the form error reduced batch by batch into P-V, RMS and maps (§6)
``kinematics``     axis motion over time against the machine's limits, command dynamics (§6)
``paths``          the path kinds' planners: spirals ([4]), layers ([3]), D paths ([5]), Fresnel ([2])
``numerics``       shared numerics: vectorisable sine and cosine, fixed-point decimal text
=================  ===========================================================================

This package's source is the repository's ``stages/`` folder, installed as ``ftsweep.stages``
(``stages/envelope/arcs.py`` is ``ftsweep.stages.envelope.arcs``). "model §N" cites section N
of "The model" in README.md, "[n]" its references. Each subpackage's face names its public
kernels in ``__all__`` and loads a module only when one of its names is first used, so that
importing a face loads no numba kernel.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

__all__ = ["envelope", "interpolation", "kinematics", "layouts", "metrics", "numerics", "paths", "sampling"]


def face(package: str, exports: dict[str, str]) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """A subpackage face's ``__getattr__`` and ``__dir__`` (PEP 562): ``exports`` maps each
    public name to the module of ``package`` that defines it, imported on first use."""

    def getattr_(name: str) -> Any:
        where = exports.get(name)
        if where is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module = importlib.import_module(f"{package}.{where}")
        return module if where == name else getattr(module, name)

    def dir_() -> list[str]:
        return sorted(exports)

    return getattr_, dir_
