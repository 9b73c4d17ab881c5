"""The platform an export was planned on, and what "as re-planned" means for it
(docs/architecture.md "Trust": exact on the same platform, one unit across platforms).

Re-planning a table or a program is deterministic for one build of ftsweep, numpy and numba
on one CPU: the same recorded case gives the same floating-point operations in the same order,
so every table cell and every printed program number comes out bit for bit the same. Across
platforms it need not: numba compiles for the host CPU (fused multiply-adds where the CPU has
them), and numpy's vectorised loops and libm differ by a last bit, which can flip a value
rounded at a half-unit boundary. The fingerprint names exactly what decides this.
"""

from __future__ import annotations

import hashlib
import platform
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from functools import cache
from typing import Any

from ftsweep.version import __version__


@cache
def fingerprint() -> dict[str, str]:
    """This machine's platform as an export records it: the versions of ftsweep, numpy,
    numba and llvmlite, the CPU architecture, the CPU LLVM compiles numba's kernels for, and
    a digest of that CPU's feature flags (the first 16 hex digits of their SHA-256)."""
    import llvmlite
    import llvmlite.binding as llvm
    import numba
    import numpy

    features = llvm.get_host_cpu_features().flatten()
    return {
        "ftsweep": __version__,
        "numpy": numpy.__version__,
        "numba": numba.__version__,
        "llvmlite": llvmlite.__version__,
        "machine": platform.machine(),
        "cpu": llvm.get_host_cpu_name(),
        "cpu_features": hashlib.sha256(features.encode("ascii")).hexdigest()[:16],
    }


# why verify may allow one unit across platforms ('' for never): the operator asked for it,
# or a trusted key signed the statement that names the platform the file was planned on
_ACROSS: ContextVar[str] = ContextVar("ftsweep_across_platforms", default="")


@contextmanager
def one_unit_across_platforms(why: str) -> Iterator[None]:
    """Within the block, a file planned on another platform (or recording none) is judged
    with one unit of the last printed digit allowed, for the reason ``why`` (the operator's
    ``--across-platforms``, or a trusted signature); outside it, exactly."""
    token = _ACROSS.set(why)
    try:
        yield
    finally:
        _ACROSS.reset(token)


def exact_on_this_platform(recorded: Any) -> tuple[bool, str]:
    """Whether verify must find every cell and program number equal to the re-planned one, and
    why, for the operator. The file does not choose its rule: a ``recorded`` fingerprint of
    this machine, a missing one or another platform's all mean the exact rule, unless the
    operator asked for one unit of the last printed digit across platforms or a trusted key
    signed the platform (:func:`one_unit_across_platforms`)."""
    here = fingerprint()
    if isinstance(recorded, dict):
        differ = sorted(k for k in set(here) | set(recorded) if recorded.get(k) != here.get(k))
        if not differ:
            return True, "planned on this platform: every value exactly as re-planned"
        named = ", ".join(f"{k} {recorded.get(k)!s:.40} here {here.get(k)!s:.40}" for k in differ[:3])
        where = f"planned on another platform ({named})"
    else:
        where = "the sidecar records no platform"
    why = _ACROSS.get()
    if why:
        return False, f"{where}: one unit allowed ({why})"
    return True, f"{where}: every value exactly as re-planned (verify --across-platforms allows one unit)"
