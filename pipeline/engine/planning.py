"""Planning a case: its catalog entries looked up (or the recorded ones taken), every
refusal that needs them, and its program made: a ring or mesh layout, a spiral's points by
its rule and budgets ([4]), a D path ([5]), the compensated commands (model §4), the layered
plan of a program deeper than the stroke ([3]).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Optional

import numpy as np

from ftsweep.engine.case import Case, CaseError
from ftsweep.engine.contract import Planning, ProgramKind
from ftsweep.engine.cost import check_capacity, check_cost, ray_nodes
from ftsweep.engine.threads import compensate_in_parts
from ftsweep.inputs import catalogs, corrections
from ftsweep.inputs.case_entries import Entries
from ftsweep.stages.interpolation import compensation, spiral_program
from ftsweep.stages.kinematics import dynamics
from ftsweep.stages.layouts import grids as layouts
from ftsweep.stages.layouts.grids import Layout
from ftsweep.stages.paths import layers


@dataclass(frozen=True)
class ResolvedCase:
    """A case with its catalog entries looked up and every rule checked: all the stages need
    (lengths µm). Built by :func:`resolve_case`. For a spiral program, ``layout`` is its
    :class:`~ftsweep.stages.interpolation.spiral_program.SpiralPath` and ``values``/``gouge`` its compensated
    commands [µm] and their gouge flags, planned with it (``plan_seconds``)."""

    case: Case
    kind: ProgramKind
    surface_spec: Any
    machine: Any
    cutting: Any
    layout: Any  # a table (Layout), a SpiralPath or a DPath
    surface: Any  # the surface callable fn(x, y) -> (f, ∂f/∂x, ∂f/∂y)
    aperture: Any
    feed_um: float
    nose_radius_um: float
    gradient_bound: float
    lines: Any = None  # the family's line evaluator (catalogs.line_sampler), or None
    values: Optional[np.ndarray] = None
    gouge: Optional[np.ndarray] = None
    chord_error_um: float = math.nan
    residual_error_um: float = math.nan
    plan_seconds: float = 0.0

    @property
    def commands_um(self) -> np.ndarray:
        """The compensated commands [µm] of a path program, planned with it (``values``); a
        table's case has none (its commands are the simulator's), and asking is a CaseError."""
        if self.values is None:
            raise CaseError(f"a {self.kind.noun} has no planned commands")
        return self.values

    @property
    def rho0_um(self) -> float:
        """Start radius of the spiral [µm] (model §1): the aperture's circumscribed radius, or
        that of a spiral program read from a file (where its X sets it)."""
        own = getattr(self.layout, "rho0_um", None)
        return float(self.aperture.outer_radius_um if own is None else own)


def resolve_case(
    case: Case,
    kind: ProgramKind,
    catalog_folder: Any = None,
    specs: Optional[Entries] = None,
    program: Optional[tuple[Any, np.ndarray]] = None,
    progress: Optional[Callable[[int, int], None]] = None,
) -> ResolvedCase:
    """Look up a case's entries (or take ``specs``) and refuse what cannot be simulated: a
    feed not below 2·Rc (model §5), a layout the aperture or the
    controller's capacity rules out, a surface without a finite slope bound.

    The case's ``kind`` sets its feed and plans its program: a table's
    layout, a spiral's points by its rule and their compensated commands ([4]), a D path
    ([5]); a given ``program`` (path, commands [µm]), e.g. read back from an exported file,
    is taken as it stands instead. ``progress(done, total)`` follows a long planning (a
    Fresnel program's timing)."""
    surface_spec, machine, cutting = specs or resolve_specs(case, catalog_folder)
    surface_spec = cased_surface(case, surface_spec)
    rc = case.nose_radius_of(cutting)
    feed = kind.feed(case, cutting, rc, surface_spec, catalog_folder, program)
    bound = _checked_bounds(case, surface_spec, catalog_folder, feed, rc)
    surface = catalogs.surface_callable(surface_spec, catalog_folder)
    planning = Planning(
        case, surface_spec, machine, cutting, surface, feed, rc, bound, catalog_folder, program, progress
    )
    layout, extra = kind.plan(planning)
    check_capacity(case, kind.noun, layout.n_points, machine.capacity_points)
    return ResolvedCase(
        case=case,
        kind=kind,
        surface_spec=surface_spec,
        machine=machine,
        cutting=cutting,
        layout=layout,
        surface=surface,
        aperture=catalogs.aperture_of(surface_spec),
        feed_um=feed,
        nose_radius_um=rc,
        gradient_bound=bound,
        lines=catalogs.line_sampler(surface_spec),
        **extra,
    )


def _checked_bounds(case: Case, surface_spec: Any, catalog_folder: Any, feed: float, rc: float) -> float:
    """The surface's slope bound, after refusing a feed not below 2·Rc (model §5), a surface
    without a finite slope bound, and a feed-plane line too large for memory (known before
    anything is planned or compensated)."""
    try:
        catalogs.check_feed(feed, rc)
    except ValueError as exc:
        raise CaseError(str(exc)) from None
    bound = catalogs.gradient_bound(surface_spec, catalog_folder)
    if not math.isfinite(bound):
        raise CaseError(
            f"the slope bound of surface '{case.surface}' is not finite: the surface gives no finite "
            "slope on its aperture"
        )
    margin = compensation.contact_window_um(bound, rc) + 2.0 * feed
    rho0 = float(catalogs.aperture_of(surface_spec).outer_radius_um)
    check_cost(ray_nodes(rho0, margin, case.resolution.points_per_feed, feed), 2, math.inf)
    return bound


def z_error_of(rcase: ResolvedCase) -> float:
    """Z positioning error per retraction [µm]: the case's, else the machine's."""
    z_error = rcase.case.z_error_um
    return float(rcase.machine.z_error_um if z_error is None else z_error)


def layer_change_of(rcase: ResolvedCase) -> float:
    """Time per layer segment to stop the spindle, move Z and restart [s]: the case's, else
    the machine's (a stated machine property, [3] gives none)."""
    change = rcase.case.layer_change_s
    return float(rcase.machine.layer_change_s if change is None else change)


def layer_plan(rcase: ResolvedCase, table: np.ndarray) -> Optional[layers.LayerPlan]:
    """The layered plan ([3], :mod:`ftsweep.stages.paths.layers`) of a case whose commands span
    more than the machine's travel (the table's range bounds every interpolated command),
    planned on the commands the controller executes along the spiral; None for a single
    pass (the commands fit the travel, or the case asks ``layers: off``)."""
    machine = rcase.machine
    span = float(np.max(table) - np.min(table))
    if rcase.case.layers == "off" or span <= machine.travel_um:
        return None
    k = dynamics.commands_per_revolution(machine.command_rate_hz, rcase.cutting.spindle_rpm)

    def chunks() -> Any:
        return layers.command_stream(rcase.layout, table, rcase.rho0_um, rcase.feed_um, k)

    phi_end = spiral_program.spiral_end_rad(rcase.rho0_um, rcase.feed_um)
    try:
        return layers.plan_layers(chunks, machine.travel_um, machine.layer_margin_um, phi_end)
    except ValueError as exc:
        raise CaseError(f"layered plan: {exc}") from None


def resolve_specs(case: Case, catalog_folder: Any = None) -> Entries:
    """The (surface, machine, cutting) catalog entries a case names, the surface's measured
    correction with the case's gain and terms (:func:`cased_surface`)."""
    return Entries(
        cased_surface(case, catalogs.entry("surfaces", case.surface, catalog_folder)),
        catalogs.entry("machines", case.machine, catalog_folder),
        catalogs.entry("cutting", case.cutting, catalog_folder),
    )


def cased_surface(case: Case, surface_spec: Any) -> Any:
    """``surface_spec`` with the case's ``correction_gain`` and ``correction_terms`` in its
    measured correction (:func:`ftsweep.inputs.corrections.as_cased`)."""
    try:
        return corrections.as_cased(surface_spec, case.correction_gain, case.correction_terms)
    except ValueError as exc:
        raise CaseError(f"surface {case.surface}: {exc}") from None


Solver = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


def compensator(case: Case, surface_spec: Any, surface: Any, nose_radius_um: float, bound: float) -> Solver:
    """``solve(rho, theta) -> (w, gouge)``: the case's compensation (model §4) of ``surface``
    (a callable, e.g. a part as mounted) at radial positions ρ [µm] on sections θ [rad], with
    the slope bound ``bound`` and the surface entry's curvature bound; to be run in parts
    (:func:`ftsweep.engine.threads.compensate_in_parts`)."""
    curvature = catalogs.curvature_bound(surface_spec)

    def solve(rho: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return compensation.compensate(
            surface,
            rho,
            theta,
            nose_radius_um,
            case.compensation,
            bound,
            n_scan=case.resolution.compensation_scan,
            curvature_bound=curvature,
        )

    return solve


def control_table(
    case: Case,
    layout: Layout,
    surface_spec: Any,
    nose_radius_um: float,
    catalog_folder: Any = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The compensated control table [µm] of ``layout`` and its gouge flags (model §4), in
    parts on the context's threads (:mod:`ftsweep.engine.threads`); on ``surface_spec`` as the
    case has it (:func:`cased_surface`)."""
    node_rho, node_theta = layouts.layout_nodes(layout)
    surface_spec = cased_surface(case, surface_spec)
    surface = catalogs.surface_callable(surface_spec, catalog_folder)
    bound = catalogs.gradient_bound(surface_spec, catalog_folder)
    solve = compensator(case, surface_spec, surface, nose_radius_um, bound)
    return compensate_in_parts(solve, node_rho, node_theta)
