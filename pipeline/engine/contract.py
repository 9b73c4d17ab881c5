"""The program-kind contract (docs/architecture.md, "The program-kind contract").

A program kind is one :class:`ProgramKind` value, in the spirit of flox's ``Aggregation``
table and xarray's backend entrypoints: it names its sweep axes and says how a sweep point
becomes its request, how its feed is set, how it is planned into a program, which record
fields it adds, what a case of it costs, how the one simulator samples its program, and
which file format exports it. The engine is handed a kind's value and never looks one up by
name; :mod:`ftsweep.registry` finds the installed kinds through entry points.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple, Optional, Protocol


class Planning(NamedTuple):
    """What a kind's ``plan`` receives: the case, its entries, the surface callable, the feed
    [µm/rev] and nose radius [µm] in force, the slope bound, the catalog folder, a given
    program (path, commands [µm]) read back from a file, or None to plan one, and a progress
    callback ``(done, total)`` for a long planning (None: silent)."""

    case: Any
    surface_spec: Any
    machine: Any
    cutting: Any
    surface: Callable[..., Any]
    feed_um: float
    nose_radius_um: float
    gradient_bound: float
    catalog_folder: Any
    program: Optional[tuple[Any, Any]]
    progress: Optional[Callable[[int, int], None]] = None


class Simulating(NamedTuple):
    """What a kind's ``simulation`` receives: the resolved case, a given table [µm] (the
    controller's as stored) or None, the catalog folder, the nodes per batch, the largest
    number of nodes a case may have, and a cache of shared work (or None). It is made in
    the case's thread context (:mod:`ftsweep.engine.threads`): work it does up front, such as
    compensating a table, may split over the threads; :func:`ftsweep.engine.simulator.run_case` spreads
    the batches."""

    rcase: Any
    table: Any
    catalog_folder: Any
    batch_nodes: int
    max_nodes: float
    lines: Any


class Simulation(Protocol):
    """How the one simulator (:func:`ftsweep.engine.simulator.run_case`) samples a kind's program: its
    batches of rays, each machined into a :class:`ftsweep.engine.simulator.Machined`, the inner/outer
    zone boundary [µm], and the record of the finished case from its metrics (the kind's
    fields, its axis motion against the machine's limits). ``batch`` may run on several
    threads at once (``run_case(threads=N)``): it must not change shared state, or only in
    a way ``record`` reads back in batch order, so results do not depend on N."""

    n_batches: int
    zone_split_um: float

    def batch(self, b: int, timer: Any) -> Any: ...

    def record(self, errors: dict[str, float], timer: Any) -> dict[str, Any]: ...


class BenchRow(NamedTuple):
    """A whole-process benchmark row a kind declares (``ftsweep bench --whole``): ``args`` of
    the ``ftsweep`` command (``{dir}``: a scratch folder shared by the rows), at most ``runs``
    runs, after the row ``needs`` names has run once (the one that writes its input)."""

    label: str
    args: tuple[str, ...]
    runs: int = 1
    needs: Optional[str] = None


@dataclass(frozen=True)
class Axis:
    """One sweep axis of a kind: its key under a sweep spec's ``axes:`` and the cube's
    coordinate of the same name.

    units : units a unit library parses (pint, UDUNITS), for the cube's coordinate.
    long_name : what the coordinate is, for the cube and ``--help``.
    signed : its values may be zero or negative (given as a list, never a log range).
    dumped_unset : a sweep spec's dump writes it as null when unset, so that the hashes of
        specs written when it was the only program axis stay the same.
    count : its values count things (points): a cube's coordinate holds them as integers
        when they are whole.
    """

    name: str
    units: str
    long_name: str
    signed: bool = False
    dumped_unset: bool = False
    count: bool = False


@dataclass(frozen=True)
class ProgramKind:
    """One program kind.

    name : the request's ``kind``, the record's ``layout``.
    noun : what a program of it is called in messages (``ring layout``, ``spiral program``).
    axes : its own sweep axes, :class:`Axis` values (beside the feed, nose-radius and
        compensation axes every kind may sweep).
    fields : the fields its records add to every kind's (:mod:`ftsweep.engine.result`), in
        the order a record lists them: :class:`ftsweep.engine.result.Quantity` values.
    pitches : the names of its two pitch fields (Δρ, Δθ of a ring; a path's mean steps).
    file_format : ``() -> FileFormat`` (:class:`ftsweep.exports.files.FileFormat`): how a case
        of it is exported and verified; called when a file is written or read.
    request : its request model (an :class:`ftsweep.engine.case.Request`), which validates its fields
        and their combination rules once, when a request is built.
    request_at : ``(sweep spec, {axis: value}) -> request`` of one sweep point.
    feed : ``(case, cutting, nose radius, surface spec, catalog folder, program) -> F [µm/rev]``.
    plan : ``(Planning) -> (program, extra fields of the resolved case)``.
    record_fields : ``(resolved case) -> its fields of the record`` (:mod:`ftsweep.engine.result`).
    cost : ``(case, surface spec, catalog folder, feed [µm/rev]) -> (relative cost, key of
        shared lines)``, handed the feed its ``feed`` set; raises CaseError for a case its
        planning would refuse where that is known without planning (over the controller's
        capacity, a layout the aperture rules out), so a sweep refuses it before it is sent.
    simulation : ``(Simulating, timer) -> Simulation``: how the one simulator samples its
        program (:mod:`ftsweep.engine.lines` for spindle programs, tables and spirals).
    pitch_text : ``(record) -> text`` of a program's pitches or mean steps, with units.
    point_text : ``(program, flat index) -> text`` naming where a point lies, for errors.
    angular_cells : ``(program, ρ0 [µm]) -> cells`` along the outer circumference that set
        the spindle angles the line engine samples (:func:`ftsweep.engine.cost.angular_samples`).
    warm_request : a coarse request of the kind that compiles its kernels in a new worker.
    aspect_range : the aspect ratios [its units] a sweep or search may span, for kinds swept
        over aspect ratios (tables); None for path programs.
    aspect_units : units of its aspect ratio (model §2).
    describe : ``(record) -> lines`` that describe a predicted program (``predict``).
    check_sweep : ``(sweep spec) -> None``, raising ValueError naming the key, for the rules
        of its sweep beyond "only its own axes" (one rule axis, a feed set twice, ...).
    sweeps : how its sweeps are called in messages (``spiral sweeps``).
    options : the command-line options (``predict``'s keys) that belong to it.
    click_options : a decorator adding those options to a command (click options, built with
        :mod:`ftsweep.options`); ``predict`` applies every kind's, each decorator once (the ring
        and mesh kinds share theirs), so a kind outside the package adds its own. An installed
        kind also names it in an entry point of group ``ftsweep.options``, so that ``predict
        --help`` reads it without loading the kind.
    from_options : ``(options) -> (request fields, notices)`` of ``predict``'s options,
        raising ValueError naming the option for a combination it refuses.
    machine, cutting : the catalog entries ``predict`` takes when none is given: a machine
        that can run the kind (a Fresnel program needs X, Y, Z, C limits) and its cutting.
    options_key : the sweep spec's key of options for every case of its sweeps (``dpath:``),
        if it has one.
    estimate : ``(sweep spec, its cube's coordinates, catalog folder) -> Dataset`` of a
        first-order P-V estimate over its sweep's axes (``pv_estimate_nm``), which
        ``sweep --prune`` uses; None where the kind has none.
    seed : ``(surface spec, tolerance [nm], capacity, cusp [nm], aspect range, catalog folder)
        -> (target N, α, estimated P-V [nm])`` where a tolerance search starts (``optimize
        --seed estimate``); None where the kind has no estimate.
    bench_cases : ``() -> {name: (surface, request)}``: its in-process benchmark cases of about
        a million points (``ftsweep bench``); its ``warm_request`` on the same surface pays the
        compile first.
    bench_rows : its whole-process benchmark rows (:class:`BenchRow`).
    reference : ``(resolved case) -> {pv_nm, rms_nm, pv_interp_nm, n_eval, seconds}``: a
        brute-force evaluation of a case straight from the model, independent of the stages'
        kernels, that the simulator is tested and timed against (``ftsweep bench
        --reference``); None where the kind has none.
    options_dumped_unset : a sweep spec's dump writes its options key as null when unset, so
        that the hashes of specs written when the key was declared for every sweep stay the same.
    """

    name: str
    noun: str
    request: type
    axes: tuple[Axis, ...]
    fields: tuple[Any, ...]
    pitches: tuple[str, str]
    file_format: Callable[[], Any]
    request_at: Callable[[Any, dict[str, float]], Any]
    feed: Callable[..., float]
    plan: Callable[[Planning], tuple[Any, dict[str, Any]]]
    record_fields: Callable[[Any], dict[str, Any]]
    cost: Callable[[Any, Any, Any, float], tuple[float, Any]]
    simulation: Callable[[Simulating, Any], Simulation]
    pitch_text: Callable[[dict[str, Any]], str]
    point_text: Callable[[Any, int], str]
    angular_cells: Optional[Callable[[Any, float], float]]
    warm_request: Callable[[], Any]
    describe: Callable[[dict[str, Any]], list[str]] = lambda r: []
    check_sweep: Callable[[Any], None] = lambda spec: None
    sweeps: str = "table sweeps"
    options: tuple[str, ...] = ()
    click_options: Optional[Callable[[Any], Any]] = None
    from_options: Callable[[dict[str, Any]], tuple[dict[str, Any], list[str]]] = lambda o: ({}, [])
    aspect_range: Optional[tuple[float, float]] = None
    aspect_units: str = "um/deg"
    machine: str = "fts-1m"
    cutting: str = "reference"
    options_key: Optional[str] = None
    options_dumped_unset: bool = False
    estimate: Optional[Callable[[Any, Any, Any], Any]] = None
    seed: Optional[Callable[..., tuple[float, float, float]]] = None
    bench_cases: Callable[[], dict[str, tuple[str, Any]]] = lambda: {}
    bench_rows: tuple[BenchRow, ...] = ()
    reference: Optional[Callable[[Any], dict[str, Any]]] = None

    @property
    def axis_names(self) -> tuple[str, ...]:
        """The names of its own sweep axes, in their order in a cube."""
        return tuple(a.name for a in self.axes)
