"""How big a case is, known before any work (model §5): the spindle angles it samples, the
evaluation nodes of its feed-plane lines and their memory, the points of its program against
the controller's capacity. A case too large is refused here, with the estimate and what to
change, before anything is planned, compensated or allocated.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any, Optional

from ftsweep.defaults import MAX_NODES
from ftsweep.engine.case import Case, CaseError, Resolution
from ftsweep.stages.interpolation.tables import Program


def angular_samples(
    cells: Optional[Callable[[Any, float], float]], layout: Program, rho0_um: float, resolution: Resolution
) -> int:
    """Spindle angles sampled over 360° (even): ``n_theta`` if set, else ``samples_per_cell``
    per table cell along the outer circumference (Np cells for rings, 2πρ0/max(Δx, Δy) for
    meshes: bilinear error grows as the pitch squared, so the coarse direction's cells carry
    the error that must be resolved; for a spiral program, the segments of its most densely
    sampled revolution), as its kind's ``cells(layout, ρ0)`` counts them; with
    ``angular_ladder``, the rule's count rounded up to the ladder's next rung (:func:`ladder_rung`)."""
    if resolution.n_theta is not None:
        n = resolution.n_theta
    else:
        if cells is None:
            raise ValueError(f"a {layout.kind} program is not sampled on spindle angles")
        n = resolution.samples_per_cell * int(cells(layout, rho0_um))
        if resolution.angular_ladder is not None:
            return ladder_rung(n, resolution.angular_ladder)
    return n + (n % 2)


def ladder_rung(n: int, ratio: float) -> int:
    """The smallest even rung 2·⌈r^k/2⌉ (k = 0, 1, ...) of the geometric ladder of ratio
    ``ratio`` that is ≥ ``n``. Rungs depend on ``ratio`` alone, so any two counts between the
    same rungs share one."""
    k = max(0, math.floor(math.log(n) / math.log(ratio)) - 1)
    while 2 * math.ceil(ratio**k / 2.0) < n:
        k += 1
    return 2 * math.ceil(ratio**k / 2.0)


# cost model of a case (ftsweep bench on this 2-core machine): throughput of the line
# simulation, and bytes held per evaluation node of one line by the batch arrays
NODES_PER_SECOND = 3.0e6
BYTES_PER_NODE = 160
MAX_LINE_BYTES = 4 * 2**30


def ray_nodes(rho0_um: float, margin_um: float, points_per_feed: float, feed_um: float) -> float:
    """Evaluation nodes on one ray of a feed-plane line (model §5): the radius plus the margin
    at both ends, ``points_per_feed`` per feed."""
    return (rho0_um + 2.0 * margin_um) * points_per_feed / feed_um


def check_cost(nodes_per_ray: float, n_theta: int, max_nodes: float = MAX_NODES) -> None:
    """Refuse a case that would exhaust memory (one feed-plane line, two rays, must fit) or
    run for hours (more than ``max_nodes`` evaluation nodes), with its estimated cost."""
    line_bytes = 2.0 * nodes_per_ray * BYTES_PER_NODE
    if line_bytes > MAX_LINE_BYTES:
        raise CaseError(
            f"one feed-plane line would hold {2 * nodes_per_ray:,.3g} evaluation nodes "
            f"({line_bytes / 2**30:,.3g} GiB, limit {MAX_LINE_BYTES / 2**30:g} GiB): lower the points "
            "per feed or the nose radius (its contact window sets the simulated margin), or raise the feed"
        )
    total = 2.0 * nodes_per_ray * n_theta / 2.0  # n_theta angles are n_theta/2 lines of two rays
    if total > max_nodes:
        raise CaseError(
            f"the case needs {total:,.3g} evaluation nodes, about {total / NODES_PER_SECOND / 3600:,.2g} "
            f"hours on one core, over the limit of {max_nodes:,.3g}; lower the resolution, or raise "
            "the limit with --max-nodes"
        )


# a file's re-simulation (verify) may cost at most this many times the evaluation nodes of the
# converged default resolution for the same case: its own size class. A convergence study's
# resolution (4x the angular samples, 2x the points per feed) is well inside; a sidecar that
# records 100,000 samples per cell is refused before any work.
VERIFY_COST_RATIO = 64.0
_COST_RATIO: ContextVar[float] = ContextVar("ftsweep_cost_ratio", default=math.inf)


@contextmanager
def bounded_by_default_resolution(ratio: float = VERIFY_COST_RATIO) -> Iterator[None]:
    """Within this block a case whose resolution costs more than ``ratio`` times the nodes of
    the default resolution for the same case is refused before any work
    (:func:`check_relative_cost`): verify judges a recorded resolution by the file's size."""
    token = _COST_RATIO.set(ratio)
    try:
        yield
    finally:
        _COST_RATIO.reset(token)


def check_relative_cost(nodes: float, default_nodes_of: Callable[[], float]) -> None:
    """Refuse, inside :func:`bounded_by_default_resolution`, a case of ``nodes`` evaluation
    nodes when the default resolution gives it ``default_nodes_of()``, naming both (outside
    it, nothing is computed: a sweep's resolution is its own choice)."""
    ratio = _COST_RATIO.get()
    if math.isinf(ratio):
        return
    default_nodes = default_nodes_of()
    if nodes > ratio * default_nodes:
        raise CaseError(
            f"the recorded resolution needs {nodes:,.3g} evaluation nodes, "
            f"{nodes / default_nodes:,.3g} times the {default_nodes:,.3g} of the default resolution for "
            f"this case (limit {ratio:g} times, about {ratio * default_nodes / NODES_PER_SECOND:,.0f} s): a "
            "file is re-simulated at most at its own size's cost; refused before any work"
        )


def count_text(n: float) -> str:
    """A point count as people read it: grouped digits, or 3 significant digits when huge
    (a count past a float's range, as tiny pitches give, by its power of ten)."""
    if n < 1e12:
        return f"{n:,.0f}"
    try:
        return f"{float(n):.3g}"
    except OverflowError:
        return f"about 1e{len(str(int(n))) - 1}"


def check_capacity(case: Case, what: str, n_points: float, capacity: int, note: str = "") -> None:
    """Refuse a program or layout of more points than the machine's controller holds (also an
    estimate, before anything is planned or allocated; ``note`` says how it was estimated)."""
    if n_points > capacity:
        raise CaseError(
            f"the {what} has {count_text(n_points)} points{note}, over the capacity of machine "
            f"'{case.machine}' "
            f"({capacity:,}); use larger pitches, steps or budgets, fewer points, or a larger machine"
        )
