"""The line sampling of spindle programs, tables and spirals (model §3, §5): the part is
simulated on batches of feed-plane lines (spindle angles), each a ray from the axis that the
spiral crosses once per revolution; the controller's interpolation gives the commands on the
passes, the arc envelope the machined height. Memory stays bounded (a few MB per batch)
whatever the layout and resolution. The one simulator (:func:`ftsweep.engine.simulator.run_case`) runs
the batches; this module says what a batch holds.
"""

from __future__ import annotations

import math
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Optional

import numpy as np

from ftsweep.engine.case import CaseError, Resolution
from ftsweep.engine.contract import Simulating
from ftsweep.engine.cost import angular_samples, check_cost, check_relative_cost, ray_nodes
from ftsweep.engine.planning import ResolvedCase, control_table, layer_plan, z_error_of
from ftsweep.engine.record import Timer, record_of
from ftsweep.engine.simulator import Machined, require_finite, require_finite_passes
from ftsweep.inputs import catalogs
from ftsweep.stages.envelope import arcs as envelope
from ftsweep.stages.interpolation import compensation, ray_commands
from ftsweep.stages.interpolation import tables as interpolation
from ftsweep.stages.kinematics import dynamics
from ftsweep.stages.paths import layers
from ftsweep.stages.sampling.surfaces import radial_section


def _xy(r: float, theta: float) -> str:
    return f"x = {r * math.cos(theta):.6g} µm, y = {r * math.sin(theta):.6g} µm"


def _node_point(node_r: np.ndarray, ray_theta: np.ndarray) -> Callable[[int], str]:
    def where(flat: int) -> str:
        a, n = np.unravel_index(flat, node_r.shape)
        return _xy(float(node_r[a, n]), float(ray_theta[a, 0]))

    return where


def _pass_point(grid: Any, ray_theta: np.ndarray) -> Callable[[int], str]:
    """Location of pass ``flat`` of a path grid's (ray, pass) arrays, for messages."""

    def where(flat: int) -> str:
        a, k = np.unravel_index(flat, grid.pass_rho.shape)
        return "the pass at " + _xy(float(grid.pass_rho[a, k]), float(ray_theta[a, 0]))

    return where


def _cells_of(rcase: ResolvedCase) -> Optional[Callable[[Any, float], float]]:
    """The kind's count of spindle cells, or None for a kind not sampled per cell."""
    kind = rcase.kind
    return kind.angular_cells if kind.samples_spindle_angles else None


def _default_nodes(rcase: ResolvedCase, margin_um: float, n_theta: int) -> float:
    """The evaluation nodes of ``rcase`` at the default resolution (``n_theta`` kept for a
    kind not sampled per cell), with the same ray margin [µm]."""
    cells = _cells_of(rcase)
    usual = Resolution(n_theta=None if cells else n_theta)
    theta = angular_samples(cells, rcase.layout, rcase.rho0_um, usual)
    return ray_nodes(rcase.rho0_um, margin_um, usual.points_per_feed, rcase.feed_um) * theta


@dataclass(frozen=True)
class LinePlan:
    """How the part is sampled (model §5): ``n_theta`` spindle angles as feed-plane lines,
    the simulated margin beyond the aperture [µm] (the arc's contact window plus two feeds),
    and the lines simulated per batch so a batch holds about ``batch_nodes`` nodes."""

    n_theta: int
    lines: np.ndarray
    window_um: float
    margin_um: float
    per_batch: int
    zone_split_um: float

    @classmethod
    def of(cls, rcase: ResolvedCase, batch_nodes: int, max_nodes: float) -> LinePlan:
        """The plan of a resolved case; refuses one too costly to run (:func:`check_cost`)."""
        res = rcase.case.resolution
        n_theta = angular_samples(_cells_of(rcase), rcase.layout, rcase.rho0_um, res)
        window = compensation.contact_window_um(rcase.gradient_bound, rcase.nose_radius_um)
        margin = window + 2.0 * rcase.feed_um
        nodes_per_ray = ray_nodes(rcase.rho0_um, margin, res.points_per_feed, rcase.feed_um)
        check_cost(nodes_per_ray, n_theta, max_nodes)
        check_relative_cost(nodes_per_ray * n_theta, lambda: _default_nodes(rcase, margin, n_theta))
        return cls(
            n_theta=n_theta,
            lines=interpolation.line_angles(n_theta),
            window_um=window,
            margin_um=margin,
            per_batch=max(1, int(batch_nodes // (2.0 * nodes_per_ray))),
            zone_split_um=res.zone_split * rcase.aperture.inner_radius_um,
        )

    @property
    def n_batches(self) -> int:
        return math.ceil(self.lines.size / self.per_batch)

    def batch(self, b: int) -> np.ndarray:
        """Line angles [rad] of batch ``b``."""
        return self.lines[b * self.per_batch : (b + 1) * self.per_batch]


def _dynamics(rcase: ResolvedCase, table: np.ndarray) -> Any:
    """The W command's motion over time at the spindle speed (model §6 dynamics)."""
    machine, cutting = rcase.machine, rcase.cutting
    return dynamics.analyse(
        rcase.layout,
        table,
        rcase.rho0_um,
        rcase.feed_um,
        cutting.spindle_rpm,
        machine.command_rate_hz,
        machine.spectrum_threshold,
    )


def _table_of(
    rcase: ResolvedCase, table: Optional[np.ndarray], catalog_folder: Any
) -> tuple[np.ndarray, np.ndarray]:
    """The compensated control table [µm] and its gouge flags, or a given table checked
    against the layout (no gouge flags: it is used as stored). A spiral program's commands
    were planned with it (:func:`plan_spiral`)."""
    layout = rcase.layout
    if table is None and rcase.values is not None and rcase.gouge is not None:
        table, gouge = rcase.values, rcase.gouge
    elif table is None:  # a table: compensated over its whole layout (model §4)
        table, gouge = control_table(
            rcase.case, layout, rcase.surface_spec, rcase.nose_radius_um, catalog_folder
        )
    else:
        table = np.asarray(table, dtype=np.float64)
        shape = getattr(layout, "shape", (layout.n_points,))  # a table's (rows, cols), a path's points
        if table.shape != shape:
            raise CaseError(f"the given table has shape {table.shape}, the layout {shape}")
        gouge = np.zeros(shape, dtype=bool)
    require_finite(table, "the control table", lambda i: rcase.kind.point_text(layout, i))
    return table, gouge


@dataclass(frozen=True)
class LineData:
    """What a batch of feed-plane lines gives independently of the table (model §3–§6): the
    path grid, the ray directions, the design height ``g`` [µm] and radial slope ``gp`` on the
    nodes, which nodes lie inside the aperture, and the exact commands ``w_exact`` [µm] on the
    passes (None when the case does not ask for the interpolation-only error)."""

    grid: Any
    ct: np.ndarray
    st: np.ndarray
    g: np.ndarray
    gp: np.ndarray
    inside: np.ndarray
    w_exact: Optional[np.ndarray]

    @property
    def nbytes(self) -> int:
        arrays = [self.ct, self.st, self.g, self.gp, self.inside, self.grid.node_r]
        arrays += [self.grid.ray_theta, self.grid.first_pass, self.grid.n_passes]
        return sum(a.nbytes for a in arrays) + (0 if self.w_exact is None else self.w_exact.nbytes)


class LineCache:
    """The :class:`LineData` of batches of lines, kept within ``budget_bytes`` for the cases
    that follow on the same lines (e.g. the cases of a sweep that share an angular sampling).

    Entries are keyed by (everything the line data depend on (:func:`line_key`), batch), so a
    cached batch is the very array a case would compute: results are identical with and
    without the cache. To make room, the least recently used batches of other lines are
    dropped first; lines larger than the whole budget keep their first batches. Safe to share
    between threads (a Dask worker may run several tasks at once)."""

    def __init__(self, budget_bytes: float) -> None:
        self.budget_bytes = float(budget_bytes)
        self.nbytes = 0
        self.hits = 0
        self.misses = 0
        self._entries: OrderedDict[tuple[Any, ...], LineData] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: tuple[Any, ...]) -> Optional[LineData]:
        """The cached batch of ``key`` (None if not held)."""
        with self._lock:
            data = self._entries.get(key)
            if data is None:
                self.misses += 1
                return None
            self._entries.move_to_end(key)
            self.hits += 1
            return data

    def put(self, key: tuple[Any, ...], data: LineData) -> None:
        """Keep ``data`` under ``key``, dropping the least recently used to stay in budget."""
        size = data.nbytes
        with self._lock:
            if size > self.budget_bytes or key in self._entries:
                return
            while self.nbytes + size > self.budget_bytes:
                # never evict batches of the lines being filled: cases read their batches in
                # order, so lines larger than the budget keep their first batches (which the
                # next case reuses) instead of each batch evicting the one the next case reads first
                older = next((k for k in self._entries if k[0] != key[0]), None)
                if older is None:
                    return
                self.nbytes -= self._entries.pop(older).nbytes
            self._entries[key] = data
            self.nbytes += size


def line_key(rcase: ResolvedCase, plan: LinePlan) -> tuple[Any, ...]:
    """Everything the :class:`LineData` of a case's batches depend on: the surface entry, the
    spiral (start radius, feed), the arc, the sampling (angles, nodes per feed, margin, batch
    size) and, for the exact envelope, the compensation method."""
    res = rcase.case.resolution
    surface = rcase.surface_spec.model_dump_json()
    mode = rcase.case.compensation if res.interp_error else None
    return (
        surface,
        rcase.rho0_um,
        rcase.feed_um,
        rcase.nose_radius_um,
        plan.n_theta,
        res.points_per_feed,
        plan.margin_um,
        plan.window_um,
        plan.per_batch,
        mode,
    )


def _reach_um(rcase: ResolvedCase, plan: LinePlan, lines: np.ndarray) -> float:
    """Radius [µm] beyond which no pass can shape the aperture along ``lines`` (model §5):
    the aperture's farthest extent along them, plus the nose radius (the farthest an arc
    reaches) and the plan's margin (contact window and two feeds). The evaluated zone, one
    feed and a contact window inside the first pass held, still covers the aperture there.
    Passes beyond it are left out: a rectangle's rays stop near its edge instead of at its
    circumscribed circle (a circle's reach lies past the spiral's start: nothing is left out)."""
    extent = rcase.aperture.extent_along_um(np.cos(lines), np.sin(lines))
    return float(extent.max()) + rcase.nose_radius_um + plan.margin_um


def single_peaked(rcase: ResolvedCase) -> bool:
    """Whether every radial section's h(s) = g(ρ + s) − arc(s) is single-peaked (model §4):
    the surface's curvature bound K below 1/Rc makes it strictly concave (the criterion of
    the table's secant solver). Not for a Fresnel-sliced entry, whose facet walls its base
    surface's bound does not see."""
    if rcase.surface_spec.fresnel is not None:
        return False
    return catalogs.curvature_bound(rcase.surface_spec) * rcase.nose_radius_um < 1.0


def _line_data(rcase: ResolvedCase, plan: LinePlan, lines: np.ndarray, timer: Timer) -> LineData:
    """The layout-independent part of a batch of lines (model §3–§6): surface samples and the
    exact commands along the path (their envelope is evaluated where the metrics need it,
    :class:`ExactLines`)."""
    res, rc = rcase.case.resolution, rcase.nose_radius_um
    t = time.perf_counter()
    grid = interpolation.path_grid(
        lines,
        rcase.rho0_um,
        rcase.feed_um,
        res.points_per_feed,
        plan.margin_um,
        _reach_um(rcase, plan, lines),
    )
    ray_theta = grid.ray_theta[:, None]
    ct, st = np.cos(ray_theta), np.sin(ray_theta)
    if rcase.lines is not None:
        g, gp = rcase.lines(grid.first_pass, grid.spacing_um, grid.origin_node, grid.node_r.shape[1], ct, st)
    else:
        g, gp = radial_section(rcase.surface, grid.node_r, ct, st)
    where = _node_point(grid.node_r, ray_theta)
    require_finite(g, f"the surface '{rcase.case.surface}' height", where)
    require_finite(gp, f"the surface '{rcase.case.surface}' slope", where)
    inside = rcase.aperture.contains_polar(grid.node_r, ct, st)
    t = timer.add("sampling", t)
    if not res.interp_error:
        return LineData(grid, ct, st, g, gp, inside, None)
    mode = compensation.MODE_CODES[rcase.case.compensation]
    w_exact = ray_commands.commands_on_rays(
        g, gp, grid.spacing_um, rc, grid.pass_node_index, grid.n_passes, mode, single_peaked(rcase)
    )
    timer.add("compensation", t)
    require_finite_passes(w_exact, grid.n_passes, "the exact W command", _pass_point(grid, ray_theta))
    return LineData(grid, ct, st, g, gp, inside, w_exact)


def _machined(
    grid: Any, pass_w: np.ndarray, plan: LinePlan, rc: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The envelope (model §5) of commands ``pass_w`` [µm] on ``grid``, evaluated over the
    fully machined zone: machined height z and the cusp peaks (radius, height) [µm]."""
    start = interpolation.first_machined_node(grid, plan.window_um)
    return envelope.machined_lines(grid.node_r, pass_w, grid.n_passes, grid.node_offset, grid.ppf, start, rc)


@dataclass(frozen=True)
class ExactLines:
    """:class:`ftsweep.engine.simulator.ExactEnvelope` of a batch of lines: the envelope of the exact
    commands ``w_exact`` [µm] on the path grid, beside the executed commands ``w`` [µm] whose
    envelope ``z`` [µm] it judges, over the fully machined zone of ``plan``."""

    grid: Any
    w: np.ndarray
    w_exact: np.ndarray
    plan: LinePlan
    rc: float
    z: np.ndarray

    def extrema(self, inside: np.ndarray, ext: np.ndarray) -> int:
        grid = self.grid
        start = interpolation.first_machined_node(grid, self.plan.window_um)
        on_grid = (grid.node_r, self.w, self.w_exact, grid.n_passes, grid.node_offset, grid.ppf, start)
        return int(envelope.interp_extrema_lines(*on_grid, self.rc, self.z, inside, ext))

    def heights(self) -> np.ndarray:
        return _machined(self.grid, self.w_exact, self.plan, self.rc)[0]


class LineSimulation:
    """The batches of feed-plane lines of a table or spiral case (the simulation of its kind,
    :class:`ftsweep.engine.contract.Simulating`): its compensated commands, line plan and layering
    (timed as compensation and interpolation), the layout-independent work of each batch
    taken from (and kept in) a :class:`LineCache` when given."""

    def __init__(self, s: Simulating, timer: Timer) -> None:
        rcase = s.rcase
        t = time.perf_counter()
        self.rcase = rcase
        # planned (and refused when too costly) before the table is compensated
        self.plan = LinePlan.of(rcase, s.batch_nodes, s.max_nodes)
        self.table, self.gouge = _table_of(rcase, s.table, s.catalog_folder)
        timer.add("compensation", t)
        t = time.perf_counter()
        self.layering = layer_plan(rcase, self.table)
        timer.add("interpolation", t)
        self.lines = s.lines
        self.key = line_key(rcase, self.plan) if s.lines is not None else None
        self.n_batches = self.plan.n_batches
        self.zone_split_um = self.plan.zone_split_um
        self.maps = rcase.case.resolution.error_map_bins is not None

    def batch(self, b: int, timer: Timer) -> Machined:
        """Batch ``b`` of lines through the stages that depend on the table (model §3–§6):
        the controller's interpolation along the path (executed layer by layer when layered,
        [3]), the arc envelope, and the design and exact-command envelope they are judged by."""
        rcase, plan = self.rcase, self.plan
        data = self.lines.get((self.key, b)) if self.lines is not None else None
        if data is None:
            data = _line_data(rcase, plan, plan.batch(b), timer)
            if self.lines is not None:
                self.lines.put((self.key, b), data)
        rc, grid = rcase.nose_radius_um, data.grid
        t = time.perf_counter()
        w_interp = interpolation.pass_commands(rcase.layout, self.table, grid)
        if self.layering is not None:
            w_interp = layers.layered_pass_commands(
                self.layering,
                grid.ray_theta,
                grid.n_passes,
                w_interp,
                z_error_of(rcase),
                grid.first_revolution,
            )
            require_finite_passes(
                w_interp,
                grid.n_passes,
                "the layered W command (a pass no layer cuts)",
                _pass_point(grid, grid.ray_theta[:, None]),
            )
        t = timer.add("interpolation", t)
        z, cusp_r, cusp_z = _machined(grid, w_interp, plan, rc)
        exact = None if data.w_exact is None else ExactLines(grid, w_interp, data.w_exact, plan, rc, z)
        t = timer.add("envelope", t)
        cusp_g = interpolation.sample_on_nodes(grid, data.g, data.gp, cusp_r)
        cusp_inside = rcase.aperture.contains_polar(cusp_r, data.ct, data.st)
        x, y = (grid.node_r * data.ct, grid.node_r * data.st) if self.maps else (None, None)
        timer.add("metrics", t)
        return Machined(z, data.g, data.inside, grid.node_r, x, y, cusp_z, cusp_g, cusp_inside, cusp_r, exact)

    def record(self, errors: dict[str, float], timer: Timer) -> dict[str, Any]:
        """The record (:func:`ftsweep.engine.record.record_of`) with the W command's motion over time
        at the spindle speed (model §6 dynamics)."""
        t = time.perf_counter()
        dyn = _dynamics(self.rcase, self.table)
        timer.add("dynamics", t)
        return record_of(self.rcase, self.plan, errors, dyn, self.gouge, self.layering)
