"""The program-kind contract (docs/architecture.md, "The program-kind contract").

A program kind is a subclass of :class:`ProgramKind`, in the shape of xarray's
``BackendEntrypoint``: class attributes that name it, its sweep axes and its defaults,
capability flags that say what it offers beyond the required methods, and typed methods that
say how a sweep point becomes its request, how its feed is set, how it is planned into a
program, which record fields it adds, what a case of it costs, how the one simulator samples
its program and which file format exports it. An installed kind is one entry point of group
``ftsweep.kinds`` naming its class; the registry (:mod:`ftsweep.engine.plugins`) makes one
instance of it, and its command-line options and commands are reached through that instance,
so the class lives in a module that loads no kernel (the kind's package face): its methods
import the planner, kernels and request model when first called. The engine is handed a
kind and never looks one up by name.

A kind's program (a table, a spiral path, a D path, ...) is its own type: the engine passes
it between the kind's methods without reading it, so the contract types it ``Any``; so are the
values that come from the layers above (a sweep spec, seen through :class:`SweepView`) and the
catalog entries, which are validated models of :mod:`ftsweep.inputs.catalogs`.
"""

from __future__ import annotations

import abc
from collections.abc import Callable, Hashable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Literal, NamedTuple, Optional, Protocol

if TYPE_CHECKING:
    import xarray

# The engine's own types the contract speaks of: its modules import this one, so naming them
# here would close an import circle. Each is named for the reader and is Any to mypy; a kind's
# methods annotate the real classes (ftsweep.engine.case.Case and .Request,
# ftsweep.engine.planning.ResolvedCase, ftsweep.engine.record.Timer,
# ftsweep.engine.lines.LineCache, ftsweep.engine.result.Quantity).
Case = Any
Request = Any
ResolvedCase = Any
Timer = Any
LineCache = Any
Quantity = Any

# a command-line decorator: a function of the command it adds options to
Decorator = Callable[[Any], Any]


class Planning(NamedTuple):
    """What a kind's ``plan`` receives: the case, its entries, the surface callable, the feed
    [µm/rev] and nose radius [µm] in force, the slope bound, the catalog folder, a given
    program (path, commands [µm]) read back from a file, or None to plan one, and a progress
    callback ``(done, total)`` for a long planning (None: silent)."""

    case: Case
    surface_spec: Any
    machine: Any
    cutting: Any
    surface: Callable[..., Any]
    feed_um: float
    nose_radius_um: float
    gradient_bound: float
    catalog_folder: Optional[Path]
    program: Optional[tuple[Any, Any]]
    progress: Optional[Callable[[int, int], None]] = None


class Simulating(NamedTuple):
    """What a kind's ``simulation`` receives: the resolved case, a given table [µm] (the
    controller's as stored) or None, the catalog folder, the nodes per batch, the largest
    number of nodes a case may have, and a cache of shared work (or None). It is made in
    the case's thread context (:mod:`ftsweep.engine.threads`): work it does up front, such as
    compensating a table, may split over the threads; :func:`ftsweep.engine.simulator.run_case` spreads
    the batches."""

    rcase: ResolvedCase
    table: Any
    catalog_folder: Optional[Path]
    batch_nodes: int
    max_nodes: float
    lines: Optional[LineCache]


class Simulation(Protocol):
    """How the one simulator (:func:`ftsweep.engine.simulator.run_case`) samples a kind's program: its
    batches of rays, each machined into a :class:`ftsweep.engine.simulator.Machined`, the inner/outer
    zone boundary [µm], and the record of the finished case from its metrics (the kind's
    fields, its axis motion against the machine's limits). ``batch`` may run on several
    threads at once (``run_case(threads=N)``): it must not change shared state, or only in
    a way ``record`` reads back in batch order, so results do not depend on N."""

    n_batches: int
    zone_split_um: float

    def batch(self, b: int, timer: Timer) -> Any: ...

    def record(self, errors: dict[str, float], timer: Timer) -> dict[str, Any]: ...


class BenchRow(NamedTuple):
    """A whole-process benchmark row a kind declares (``ftsweep bench --whole``): ``args`` of
    the ``ftsweep`` command (``{dir}``: a scratch folder shared by the rows), at most ``runs``
    runs, after the row ``needs`` names has run once (the one that writes its input)."""

    label: str
    args: tuple[str, ...]
    runs: int = 1
    needs: Optional[str] = None


class ReferenceBench(NamedTuple):
    """What ``ftsweep bench --reference`` times a kind's brute-force reference beside: the
    label of one of its whole-process rows (a ``predict``) and the case that predict simulates."""

    row: str
    case: Case


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
    feed : how its values stand to the feed, for what a sweep says of its feed (``compare``):
        ``"is"`` they are the feed (a spacing between cuts), ``"sets"`` the feed follows from
        them (a residual budget), ``""`` neither.
    """

    name: str
    units: str
    long_name: str
    signed: bool = False
    dumped_unset: bool = False
    count: bool = False
    feed: Literal["", "is", "sets"] = ""


@dataclass(frozen=True)
class FileFormat:
    """How one kind of exported file is written, recognised, verified and reported (a kind's
    :meth:`ProgramKind.file_format`; :mod:`ftsweep.exports.files` holds the machinery).

    magic : how its first line starts (None: the default format, read when no other's
        first line matches).
    export : ``(out, side, case, specs, chosen, extra, name) -> sidecar``.
    verify : ``(path, progress, pv_tolerance_nm, trust_plugins) -> record``.
    exported : the lines that say what ``export`` wrote (``(out, sidecar) -> lines``).
    verified : the lines that say what ``verify`` found (``record -> lines``).
    dialect : a path kind's :class:`ftsweep.exports.dialects.Adapter` (None: ftsweep's own
        format only).
    compiled : ``(path, trust_plugins) -> record fields`` of the compiled C reference's check
        of a file verify has read (:mod:`ftsweep.exports.compiled`); None: no reference.
    """

    name: str
    magic: str | None
    export: Callable[..., dict[str, Any]] | None
    verify: Callable[..., dict[str, Any]]
    exported: Callable[[Path, dict[str, Any]], list[str]]
    verified: Callable[[dict[str, Any]], list[str]]
    # an export-layer value (the Adapter of ftsweep.exports.dialects) the engine never reads
    dialect: Any = None
    compiled: Callable[[Path, bool], dict[str, Any]] | None = None


class SweepView(Protocol):
    """What a kind reads of a sweep spec (:class:`ftsweep.sweeps.spec.SweepSpec`, a layer above):
    its layout, surface and cutting entries, its axes (``axes.get(name)``: a list, a range or
    None) and the options of a kind's own key."""

    @property
    def layout(self) -> Optional[str]: ...

    @property
    def surface(self) -> str: ...

    @property
    def cutting(self) -> str: ...

    @property
    def axes(self) -> Any: ...

    def options_of(self, key: str) -> Optional[dict[str, Any]]: ...


class ProgramKind(abc.ABC):
    """One program kind: subclass it, set the class attributes, implement the abstract methods.

    Class attributes, all required but those given a value here:

    name : the request's ``kind``, the record's ``layout``; also the entry point's name.
    noun : what a program of it is called in messages (``ring layout``, ``spiral program``).
    sweeps : how its sweeps are called in messages (``spiral sweeps``).
    axes : its own sweep axes, :class:`Axis` values (beside the feed, nose-radius and
        compensation axes every kind may sweep).
    pitches : the names of its two pitch fields (Δρ, Δθ of a ring; a path's mean steps).
    options : the command-line options (``predict``'s keys) that belong to it.
    machine, cutting : the catalog entries ``predict`` takes when none is given: a machine
        that can run the kind (a Fresnel program needs X, Y, Z, C limits) and its cutting.
    aspect_units : units of its aspect ratio (model §2).
    aspect_range : the aspect ratios [its units] a sweep or search may span, for kinds swept
        over aspect ratios (tables); None for path programs.
    options_key : the sweep spec's key of options for every case of its sweeps (``dpath:``),
        if it has one; ``options_dumped_unset``: a sweep spec's dump writes it as null when
        unset, so that the hashes of specs written when the key was declared for every sweep
        stay the same.
    bench_rows : its whole-process benchmark rows (:class:`BenchRow`).
    description : what its program is, one clause for the commands' ``--help`` (xarray's
        ``BackendEntrypoint.description``); ``exports_as``: what ``export`` writes for it.
    predict_help : a paragraph on its ``predict`` options for ``predict --help``;
        ``examples``: its ``predict`` command lines there.

    Capability flags (xarray's ``open_dataset_parameters`` and the like), each saying that the
    kind implements the optional methods named:

    samples_spindle_angles : :meth:`angular_cells` (a spindle program whose cells set the
        angles the line engine samples).
    estimates : :meth:`estimate` and :meth:`seed` (a first-order P-V estimate over its sweep).
    has_reference : :meth:`reference` (a brute-force evaluation straight from the model) and
        :meth:`reference_bench`, the row it is timed beside.
    """

    name: ClassVar[str]
    noun: ClassVar[str]
    sweeps: ClassVar[str]
    axes: ClassVar[tuple[Axis, ...]]
    pitches: ClassVar[tuple[str, str]]
    options: ClassVar[tuple[str, ...]]
    machine: ClassVar[str]
    cutting: ClassVar[str]
    aspect_units: ClassVar[str]
    aspect_range: ClassVar[Optional[tuple[float, float]]] = None
    options_key: ClassVar[Optional[str]] = None
    options_dumped_unset: ClassVar[bool] = False
    bench_rows: ClassVar[tuple[BenchRow, ...]] = ()
    description: ClassVar[str]
    exports_as: ClassVar[str]
    predict_help: ClassVar[str] = ""
    examples: ClassVar[tuple[str, ...]] = ()

    samples_spindle_angles: ClassVar[bool] = False
    estimates: ClassVar[bool] = False
    has_reference: ClassVar[bool] = False

    # what a subclass must set itself (the registry refuses a kind that leaves one unset)
    REQUIRED: ClassVar[tuple[str, ...]] = (
        "name",
        "noun",
        "sweeps",
        "axes",
        "pitches",
        "options",
        "machine",
        "cutting",
        "aspect_units",
        "description",
        "exports_as",
    )

    def __repr__(self) -> str:
        return f"<program kind {self.name!r} ({type(self).__module__}.{type(self).__qualname__})>"

    @property
    def axis_names(self) -> tuple[str, ...]:
        """The names of its own sweep axes, in their order in a cube."""
        return tuple(a.name for a in self.axes)

    # -- what every kind implements ---------------------------------------------------------

    @property
    @abc.abstractmethod
    def request(self) -> type[Request]:
        """Its request model (a :class:`ftsweep.engine.case.Request`), which validates its
        fields and their combination rules once, when a request is built."""

    @property
    @abc.abstractmethod
    def fields(self) -> tuple[Quantity, ...]:
        """The fields its records add to every kind's (:mod:`ftsweep.engine.result`), in the
        order a record lists them."""

    @abc.abstractmethod
    def file_format(self) -> FileFormat:
        """How a case of it is exported and verified; called when a file is written or read."""

    @abc.abstractmethod
    def request_at(self, spec: SweepView, point: Mapping[str, float]) -> Request:
        """The request of one sweep point (``{axis: value}``)."""

    @abc.abstractmethod
    def feed(
        self,
        case: Case,
        cutting: Any,
        nose_radius_um: float,
        surface_spec: Any,
        catalog_folder: Optional[Path],
        program: Any,
    ) -> float:
        """The feed F [µm/rev] of a case: the cutting's, or one its own rule sets (a residual
        budget), for a given program (read from a file) or None."""

    @abc.abstractmethod
    def plan(self, planning: Planning) -> tuple[Any, dict[str, Any]]:
        """The case's program and the extra fields of its resolved case."""

    @abc.abstractmethod
    def record_fields(self, rcase: ResolvedCase) -> dict[str, Any]:
        """Its fields of a finished case's record (:mod:`ftsweep.engine.result`)."""

    @abc.abstractmethod
    def cost(
        self, case: Case, surface_spec: Any, catalog_folder: Optional[Path], feed_um: float
    ) -> tuple[float, Hashable]:
        """A case's relative cost and the key of the lines it shares with other cases, handed
        the feed :meth:`feed` set; raises CaseError for a case its planning would refuse
        where that is known without planning (over the controller's capacity, a layout the
        aperture rules out), so a sweep refuses it before it is sent."""

    @abc.abstractmethod
    def simulation(self, inputs: Simulating, timer: Timer) -> Simulation:
        """How the one simulator samples its program (:mod:`ftsweep.engine.lines` for spindle
        programs, tables and spirals)."""

    @abc.abstractmethod
    def pitch_text(self, record: Mapping[str, Any]) -> str:
        """A program's pitches or mean steps, with units."""

    @abc.abstractmethod
    def point_text(self, program: Any, flat: int) -> str:
        """Where the point of flat index ``flat`` lies, for errors."""

    @abc.abstractmethod
    def warm_request(self) -> Request:
        """A coarse request of the kind that compiles its kernels in a new worker."""

    # -- what a kind may refine --------------------------------------------------------------

    def describe(self, record: Mapping[str, Any]) -> list[str]:
        """Lines that describe a predicted program (``predict``); none by default."""
        return []

    def check_sweep(self, spec: SweepView) -> None:  # noqa: B027 - a hook a kind may leave as it is
        """Its sweep's rules beyond "only its own axes" (one rule axis, a feed set twice, ...),
        raising ValueError naming the key; none by default."""

    def from_options(self, options: Mapping[str, Any]) -> tuple[dict[str, Any], list[str]]:
        """The request's fields from ``predict``'s options, and the notices to show, raising
        ValueError naming an option for a combination it refuses; by default its own options
        that were given."""
        return {"kind": self.name, **{k: options[k] for k in self.options if options.get(k) is not None}}, []

    def click_options(self) -> Optional[Decorator]:
        """A decorator adding its options to a command (click options, built with
        :mod:`ftsweep.options`), or None; ``predict`` applies every kind's, each decorator once
        (the ring and mesh kinds share theirs). Must load no kernel: ``--help`` calls it."""
        return None

    def commands(self) -> tuple[Any, ...]:
        """The click commands it adds to ``ftsweep`` (``ftsweep dpath``); none by default. Must
        load no kernel: ``--help`` calls it."""
        return ()

    def bench_cases(self) -> dict[str, tuple[str, Request]]:
        """Its in-process benchmark cases of about a million points (``ftsweep bench``) by
        name: ``(surface, request)``; its :meth:`warm_request` on the same surface pays the
        compile first. None by default."""
        return {}

    def angular_cells(self, program: Any, rho0_um: float) -> float:
        """Cells along the outer circumference that set the spindle angles the line engine
        samples (:func:`ftsweep.engine.cost.angular_samples`); with ``samples_spindle_angles``."""
        raise NotImplementedError(f"the {self.noun} samples no spindle angles")

    def estimate(
        self, spec: SweepView, coords: Mapping[str, Any], catalog_folder: Optional[Path]
    ) -> xarray.Dataset:
        """A first-order P-V estimate (``pv_estimate_nm``) over its sweep's axes, which ``sweep
        --prune`` uses; with ``estimates``."""
        raise NotImplementedError(f"{self.sweeps} have no estimate")

    def seed(
        self,
        surface_spec: Any,
        tolerance_nm: float,
        capacity: int,
        cusp_nm: float,
        aspect_range: tuple[float, float],
        catalog_folder: Optional[Path],
    ) -> tuple[float, float, float]:
        """Where a tolerance search starts (``optimize --seed estimate``): target N, α and the
        estimated P-V [nm]; with ``estimates``."""
        raise NotImplementedError(f"{self.sweeps} have no estimate")

    def reference(self, rcase: ResolvedCase) -> dict[str, Any]:
        """``{pv_nm, rms_nm, pv_interp_nm, n_eval, seconds}`` of a brute-force evaluation of a
        case straight from the model, independent of the stages' kernels, that the simulator is
        tested and timed against (``ftsweep bench --reference``); with ``has_reference``."""
        raise NotImplementedError(f"the {self.noun} has no reference evaluation")

    def reference_bench(self) -> ReferenceBench:
        """The whole-process row and case its :meth:`reference` is timed beside, where the kind
        has such a row (NotImplementedError where not)."""
        raise NotImplementedError(f"the {self.noun} has no reference evaluation")


def unset_attributes(cls: type[ProgramKind]) -> list[str]:
    """The required class attributes (:attr:`ProgramKind.REQUIRED`) a kind's class leaves unset."""
    return [name for name in cls.REQUIRED if not hasattr(cls, name)]
