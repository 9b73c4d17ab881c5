"""The one simulator: any program kind's case through surface sampling, its program, the
controller's interpolation along the tool's path, the arc envelope and the metrics, in the
order of docs/architecture.md, on batches of rays so memory stays bounded whatever the program.

A kind says how its program is sampled (its :class:`ftsweep.engine.contract.Simulation`: the rays of
a batch, the passes crossing them with their commands, the design they are judged by, and the
record it adds); :func:`run_case` runs every kind's batches through the same accumulation of
the metrics (model §6) and error maps.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, NamedTuple, Optional, Protocol

import numpy as np

from ftsweep.engine.case import Case, CaseError
from ftsweep.engine.contract import ProgramKind, Simulating, Simulation
from ftsweep.engine.cost import MAX_NODES
from ftsweep.engine.planning import ResolvedCase, resolve_case
from ftsweep.engine.record import ErrorMap, Timer, timed
from ftsweep.engine.result import STAGES
from ftsweep.engine.threads import current as current_threads
from ftsweep.engine.threads import using_threads
from ftsweep.inputs.case_entries import Entries
from ftsweep.stages.envelope import arcs as envelope
from ftsweep.stages.interpolation import compensation
from ftsweep.stages.interpolation import tables as interpolation
from ftsweep.stages.metrics import moments as metrics


def require_finite(values: np.ndarray, what: str, where: Callable[[int], str]) -> None:
    """Raise :class:`CaseError` if ``values`` hold NaN or inf, naming how many and the first
    place (``where(flat index)``)."""
    finite = np.isfinite(values)
    if not finite.all():
        _not_finite(what, int(finite.size - finite.sum()), int(np.flatnonzero(~finite.ravel())[0]), where)


def require_finite_passes(
    w: np.ndarray, n_passes: np.ndarray, what: str, where: Callable[[int], str]
) -> None:
    """:func:`require_finite` over the passes of (rays, passes) commands ``w``: the first
    ``n_passes[a]`` of row a (the rest is padding), read in place."""
    count, first = interpolation.nonfinite_passes(w, n_passes)
    if count:
        _not_finite(what, count, first, where)


def _not_finite(what: str, count: int, first: int, where: Callable[[int], str]) -> None:
    raise CaseError(f"{what} is not finite (NaN or inf) at {count:,} points, first at {where(first)}")


STAGE_TIMERS = STAGES
# evaluation nodes per batch of rays: a batch's arrays (~40 bytes a node) stay in a core's
# caches from one stage to the next (docs/performance.md, "Tuned constants")
BATCH_NODES = 150_000


class ExactEnvelope(Protocol):
    """The envelope (model §5) of a batch's exact commands, which the interpolation-only error
    d = z − z_exact (model §6) is judged by, evaluated only where it can matter."""

    def extrema(self, inside: np.ndarray, ext: np.ndarray) -> int:
        """Extend ``ext`` = [min, max] [µm] by d over the ``inside`` nodes; returns the rays
        (or lines) whose exact envelope had to be evaluated."""
        ...

    def heights(self) -> np.ndarray:
        """z_exact [µm] on every node of the batch (NaN off the evaluation nodes)."""
        ...


@dataclass(frozen=True)
class ExactRows:
    """:class:`ExactEnvelope` of rows whose passes are given directly (the grids of
    :func:`ftsweep.stages.envelope.arcs.envelope_rows`): positions ``pos`` [µm], the executed
    commands ``w`` and the exact ones ``w_exact`` [µm], ``n_valid`` passes per row, nose
    radius ``rc`` [µm], the evaluation radii ``query`` [µm] and the machined height ``z``."""

    pos: np.ndarray
    w: np.ndarray
    w_exact: np.ndarray
    n_valid: np.ndarray
    rc: float
    query: np.ndarray
    z: np.ndarray

    def extrema(self, inside: np.ndarray, ext: np.ndarray) -> int:
        return int(
            envelope.interp_extrema_rows(
                self.pos, self.w, self.w_exact, self.n_valid, self.rc, self.query, self.z, inside, ext
            )
        )

    def heights(self) -> np.ndarray:
        return envelope.machined_rows(self.pos, self.w_exact, self.n_valid, self.rc, self.query)[0]


def exact_at_passes(
    rcase: ResolvedCase,
    surface: Callable[..., Any],
    pos: np.ndarray,
    theta: np.ndarray,
    on: np.ndarray,
    base: np.ndarray,
    curvature_bound: float,
) -> np.ndarray:
    """The exact commands [µm] (the compensated design, model §4) at the passes ``on`` of a
    batch of rays at angles ``theta`` [rad], passes at radii ``pos`` [µm] on ``surface`` (in
    the frame the rays are cast in); ``base`` elsewhere."""
    res = rcase.case.resolution
    w_exact = np.array(base, dtype=np.float64, copy=True)
    w_exact[on], _ = compensation.compensate(
        surface,
        pos[on],
        np.broadcast_to(theta[:, None], pos.shape)[on],
        rcase.nose_radius_um,
        rcase.case.compensation,
        rcase.gradient_bound,
        n_scan=res.compensation_scan,
        curvature_bound=curvature_bound,
    )
    return w_exact


class Machined(NamedTuple):
    """One batch of rays machined (model §5) and what it is judged by (model §6), arrays of
    (rays, nodes) in µm: the machined height ``z``, the design ``g``, the nodes ``inside``
    the aperture, their distance ``r`` from the part's centre (for the zones), their place
    ``x``, ``y`` in the part's frame (None when no error map is asked); the cusp peaks between
    passes: height, design, inside, distance; and the envelope of the exact commands
    (None when the case asks the interpolation-only error off)."""

    z: np.ndarray
    g: np.ndarray
    inside: np.ndarray
    r: np.ndarray
    x: Optional[np.ndarray]
    y: Optional[np.ndarray]
    cusp_z: np.ndarray
    cusp_g: np.ndarray
    cusp_inside: np.ndarray
    cusp_r: np.ndarray
    exact: Optional[ExactEnvelope]


def run_case(
    case: Case,
    kind: ProgramKind,
    catalog_folder: Any = None,
    progress: Optional[Callable[[int, int], None]] = None,
    batch_nodes: int = BATCH_NODES,
    table: Optional[np.ndarray] = None,
    specs: Optional[Entries] = None,
    max_nodes: float = MAX_NODES,
    lines: Any = None,
    program: Optional[tuple[Any, np.ndarray]] = None,
    threads: Optional[int] = None,
    resolved: Optional[ResolvedCase] = None,
) -> dict[str, Any]:
    """Predict the form error of one case of program kind ``kind`` (model §1–§6).

    Returns a flat record whose fields :mod:`ftsweep.engine.result` declares (names, units, order):
    the resolved inputs (surface, program, n_points, its pitches or steps, cutting
    conditions), the metrics of :func:`ftsweep.stages.metrics.moments.finalize` in nm, the points
    flagged as gouging, the feed cusp height, the axis motion against the machine's limits,
    and wall seconds per stage (``seconds_<stage>``) and in total (``seconds``); with
    ``resolution.error_map_bins``, the error maps. ``progress(done, total)`` is called after
    each batch. A given ``table`` [µm] (of the case's layout shape) replaces the compensated
    one: the controller's table as stored, e.g. after quantisation. ``specs`` = (surface,
    machine, cutting) entries replace the catalog look-up, e.g. the entries a cube or header
    recorded. A case of more than ``max_nodes`` evaluation nodes, or whose single line would
    not fit in memory, is refused before any work (:func:`ftsweep.engine.cost.check_cost`); a
    non-finite height, slope, command or metric fails the case naming where it occurred. With
    a ``lines`` cache (:class:`ftsweep.engine.lines.LineCache`), work that does not depend on the
    program is shared between cases: the result is the same. A path program is planned by its
    rule unless ``program`` (path, commands [µm]) gives it as stored, e.g. read from a file.
    With ``threads`` > 1 the batches (and a table's compensation) run on that many threads
    (the numba kernels release the GIL); the metrics still take the batches in order, so the
    record is the same, value for value, whatever the number of threads. None: the number
    set by :func:`ftsweep.engine.threads.using_threads` around the call (one unless set).
    ``resolved``: the case as :func:`ftsweep.engine.planning.resolve_case` already resolved it (its
    program planned), simulated as it is instead of planned again.
    """
    threads = current_threads(threads)
    t_start = time.perf_counter()
    timer = Timer()
    with using_threads(threads):  # planning and a table's compensation split their work too
        rcase = resolved or resolve_case(case, kind, catalog_folder, specs, program)
        timer.seconds["compensation"] = rcase.plan_seconds
        inputs = Simulating(rcase, table, catalog_folder, batch_nodes, max_nodes, lines)
        sim = kind.simulation(inputs, timer)
    bins = case.resolution.error_map_bins
    emap = ErrorMap.over(rcase.aperture, bins) if bins else None
    stats = metrics.empty_stats()
    for b, machined in enumerate(_batches(sim, timer, threads)):
        _accumulate(machined, sim.zone_split_um, stats, emap, timer)
        if progress is not None:
            progress(b + 1, sim.n_batches)
    errors = metrics.finalize(stats)
    if not case.resolution.interp_error:
        errors["pv_interp_nm"] = math.nan  # not simulated: asked off
    record = sim.record(errors, timer)
    if emap is not None:
        record.update(emap.as_record())
    return timed(record, timer, t_start, kind)


def _batches(sim: Simulation, timer: Timer, threads: int) -> Iterator[Machined]:
    """The machined batches of ``sim`` in order, computed on ``threads`` threads with at most
    two batches per thread in flight, so memory stays a few batches whatever the case."""
    if threads == 1 or sim.n_batches < 2:
        for b in range(sim.n_batches):
            yield sim.batch(b, timer)
        return
    with ThreadPoolExecutor(threads, thread_name_prefix="ftsweep-case") as pool:
        pending: deque[Future[Machined]] = deque()
        try:
            for b in range(sim.n_batches):
                pending.append(pool.submit(sim.batch, b, timer))
                if len(pending) >= 2 * threads:
                    yield pending.popleft().result()
            while pending:
                yield pending.popleft().result()
        finally:
            for f in pending:  # a failed batch or an abandoned case: start no more
                f.cancel()


def _accumulate(
    m: Machined, split_um: float, stats: np.ndarray, emap: Optional[ErrorMap], timer: Timer
) -> None:
    """A machined batch into the metric statistics (model §6) and the error map."""
    t = time.perf_counter()
    metrics.accumulate(m.z, m.g, m.inside, m.r, split_um, stats)
    metrics.accumulate_extrema(m.cusp_z, m.cusp_g, m.cusp_inside, m.cusp_r, split_um, stats)
    if emap is not None and m.x is not None and m.y is not None:
        emap.add_points(m.z, m.g, m.inside, m.x, m.y)
    t = timer.add("metrics", t)
    if m.exact is not None:
        m.exact.extrema(m.inside, stats[metrics.INTERP])
        timer.add("envelope", t)
