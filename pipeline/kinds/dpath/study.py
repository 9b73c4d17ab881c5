"""``ftsweep dpath``: a D-path study ([5]): the traditional and the optimised path on one
part, their X motion and junctions, the form error of each through the engine, and the
Archimedean spiral on the same part for comparison (its Z motion, time and P-V), with the
plots of [5] figs. 3 and 7.

The spiral is the usual way to turn the part: centred on the spindle, feed = the D path's
spacing, a point every cut step of path, the same tool and spindle speed
(:func:`spiral_case`). Both are predicted by :func:`ftsweep.engine.simulator.run_case`.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING, Any, Optional

import numpy as np

from ftsweep.engine.case import Case, Resolution, program_request
from ftsweep.engine.planning import ResolvedCase
from ftsweep.engine.threads import current as current_threads
from ftsweep.kinds.dpath import kind as dpath_kind
from ftsweep.kinds.dpath import program as dprog
from ftsweep.simulate import resolve_case, run_case
from ftsweep.stages.paths import dpath, dpath_motion

if TYPE_CHECKING:
    from ftsweep.kinds.dpath.figures import Plots


def d_case(base: Case, transition: str) -> Case:
    """``base`` (a D-path case) with the given transition."""
    return base.model_copy(update={"layout": base.layout.model_copy(update={"transition": transition})})


def spiral_case(base: Case, record: dict[str, Any]) -> Case:
    """The Archimedean spiral on the same part: centred on the C axis, feed = spacing h, a
    point every cut step along the path ([4] constant-arc rule), same tool and entries."""
    return Case(
        surface=base.surface,
        layout=program_request(kind="spiral", arc_um=float(record["cut_step_um"])),
        machine=base.machine,
        cutting=base.cutting,
        feed_um=float(record["spacing_um"]),
        nose_radius_um=base.nose_radius_um,
        compensation=base.compensation,
        resolution=Resolution(),
    )


def spiral_motion(case: Case, resolved: Optional[ResolvedCase] = None) -> dict[str, Any]:
    """The spiral program's axis motion at constant spindle speed: t [s], C [rad], X, Z [µm]
    and :func:`ftsweep.stages.paths.dpath.axis_motion` (``resolved``: the case planned already)."""
    rcase = resolved or resolve_case(case)
    path = rcase.layout
    rpm = rcase.cutting.spindle_rpm
    t = dpath_motion.point_times(path.phi, path.rho, rcase.commands_um, "spindle", rpm)
    motion = dpath_motion.axis_motion(t, path.phi, path.rho, rcase.commands_um)
    return {"t": t, "phi": path.phi, "x": path.rho, "z": rcase.values, **motion}


def feed_mode(
    path: dpath.DPath, z: np.ndarray, rpm: float, feed_mm_min: float, cuts_only: bool = False
) -> dict[str, float]:
    """The constant-feed XZC interpolation of a program: time, C speed range overall and on
    the cuts, and the C speed's largest jump between steps [rpm]. The feed holds along the
    whole path, or with ``cuts_only`` on the cuts alone, the transitions at the C cap ``rpm``
    (docs/kinds.md, "D-shaped slow-tool-servo paths": [5]'s DIFFSYS figures)."""
    on = (path.cut[1:] >= 0) & (path.cut[1:] == path.cut[:-1])
    t = dpath_motion.point_times(path.phi, path.rho, z, "feed", rpm, feed_mm_min, on if cuts_only else None)
    c = np.diff(path.phi) / np.diff(t) * 60.0 / (2.0 * math.pi)
    return {
        "time_s": float(t[-1]),
        "c_speed_min_rpm": float(c.min()),
        "c_speed_max_rpm": float(c.max()),
        "c_speed_cut_min_rpm": float(c[on].min()),
        "c_speed_cut_max_rpm": float(c[on].max()),
        "c_speed_jump_rpm": float(np.abs(np.diff(c)).max()),
    }


def continuity(path: dpath.DPath) -> dict[str, float]:
    """Largest relative jump of ρ, dρ/dθ and d²ρ/dθ² over the junctions (relative to the
    largest magnitude of each on the cut side; the dρ/dθ jump itself [µm/rad] is the case
    record's ``slope_jump_um_rad``)."""
    j = dpath_motion.junctions(path)
    out = {}
    for name in ("rho", "d1", "d2"):
        scale = float(np.abs(j[name]).max()) if j[name].size else 1.0
        out[f"{name}_rel_jump"] = float(np.abs(j[f"jump_{name}"]).max()) / scale if j[name].size else 0.0
    return out


TRANSITIONS = ("traditional", "optimised")


class _Progress:
    """One progress report over the batches of cases run side by side: each case's
    ``(done, total)`` summed under a lock, the totals as far as they are known."""

    def __init__(self, report: Any, cases: int) -> None:
        self.report, self.lock = report, threading.Lock()
        self.done, self.total = [0] * cases, [0] * cases

    def of(self, case: int) -> Optional[Callable[[int, int], None]]:
        if self.report is None:
            return None

        def update(done: int, total: int) -> None:
            with self.lock:
                self.done[case], self.total[case] = done, total
                self.report(sum(self.done), sum(self.total))

        return update


def _transition(rcase: ResolvedCase, feed_mm_min: float, progress: Any) -> dict[str, Any]:
    """One D path's summary: its case record (one thread), junction continuity and the two
    constant-feed modes."""
    record = run_case(rcase.case, progress=progress, resolved=rcase, threads=1)
    keep = {k: v for k, v in record.items() if not k.startswith("seconds") and k != "layers"}
    keep.update(continuity(rcase.layout))
    for name, cuts_only in (("feed_mode", False), ("feed_mode_cuts", True)):
        rpm = rcase.cutting.spindle_rpm
        keep[name] = feed_mode(rcase.layout, rcase.commands_um, rpm, feed_mm_min, cuts_only)
    return keep


def _x_figure(
    plots: Plots, programs: dict[str, tuple[dpath.DPath, np.ndarray]], rpm: float, period_s: float
) -> None:
    """Hand ``plots`` [5] fig. 3 of the planned ``programs`` (:func:`x_motion_curves`)."""
    plots.x_motion(x_motion_curves(programs, rpm, period_s), x_motion_title(rpm))


def _spiral(
    base: Case, program: tuple[dpath.DPath, np.ndarray], progress: Any, threads: int, plots: Optional[Plots]
) -> dict[str, Any]:
    """The spiral on the same part (:func:`spiral_case` of the optimised ``program``'s spacing
    and cut step): its record's figures (its batches on ``threads`` threads) and its axis
    motion (``motion``), handed to ``plots`` with ``program`` before its case runs."""
    path = program[0]
    scase = spiral_case(base, {"cut_step_um": path.cut_step_um, "spacing_um": path.geometry.spacing_um})
    srcase = resolve_case(scase)
    motion = spiral_motion(scase, srcase)
    if plots is not None:
        plots.z_motion(z_motion_curves(motion, program, srcase.cutting.spindle_rpm))
    srec = run_case(scase, progress=progress, resolved=srcase, threads=threads)
    return {
        "n_points": srec["n_points"],
        "pv_nm": srec["pv_nm"],
        "rms_nm": srec["rms_nm"],
        "cusp_nm": srec["cusp_nm"],
        "machining_s": srec["machining_s"],
        "z_velocity_peak_mm_s": float(np.abs(motion["z_velocity_mm_s"]).max()),
        "z_accel_peak_m_s2": float(np.abs(motion["z_accel_m_s2"]).max()),
        "x_accel_peak_m_s2": float(np.abs(motion["x_accel_m_s2"]).max()),
        "motion": motion,
    }


def study(
    base: Case,
    feed_mm_min: float,
    with_spiral: bool = True,
    progress: Any = None,
    threads: Optional[int] = None,
    plots: Optional[Plots] = None,
) -> dict[str, Any]:
    """Both transitions of ``base`` and (optionally) the spiral: one JSON-ready summary.

    Every program is planned once (the two D paths share their compensated cuts,
    :func:`ftsweep.kinds.dpath.kind.shared_cuts`); then the parts that do not depend on each other
    (each transition's case, the spiral's, the ratio table) run side by side on ``threads``
    threads (the context's, :func:`ftsweep.engine.threads.using_threads`, when None): the kernels
    release the GIL. Each transition's case takes one; the spiral, which starts last, spreads
    its batches over all of them, so the core the short ratio table frees does not wait for
    it (the seed example's study 0.2 s sooner on two cores). The summary is the same whatever
    the number. ``plots`` (:class:`ftsweep.kinds.dpath.figures.Plots`) draws the figures meanwhile."""
    out: dict[str, Any] = {"surface": base.surface, "machine": base.machine, "cutting": base.cutting}
    with dpath_kind.shared_cuts():
        resolved = {kind: resolve_case(d_case(base, kind)) for kind in TRANSITIONS}
    programs = {kind: (r.layout, r.commands_um) for kind, r in resolved.items()}
    opt_case = resolved["optimised"]
    rpm = opt_case.cutting.spindle_rpm
    # the C step of one controller period (the records' accel_step_deg, formed alike)
    period = dprog.period_of(opt_case.machine)
    step_deg = math.degrees(rpm * 2.0 * math.pi / 60.0 * period)
    combined = _Progress(progress, len(TRANSITIONS) + int(with_spiral))
    n_threads = max(1, current_threads(threads))
    with ThreadPoolExecutor(n_threads) as pool:
        # its curves formed on a thread of the pool too: the kernels' first loads are most of it
        figure = None if plots is None else pool.submit(_x_figure, plots, programs, rpm, period)
        cases = {
            kind: pool.submit(_transition, rcase, feed_mm_min, combined.of(i))
            for i, (kind, rcase) in enumerate(resolved.items())
        }
        spiral = None
        if with_spiral:
            spiral = pool.submit(_spiral, base, programs["optimised"], combined.of(2), n_threads, plots)
        by_step = pool.submit(accel_by_step, programs, rpm, step_deg)
        for kind, done in cases.items():
            out[kind] = done.result()
        trad, opt = out["traditional"], out["optimised"]
        out["x_accel_ratio"] = opt["x_accel_peak_m_s2"] / trad["x_accel_peak_m_s2"]
        # [5]: the peak lies at the cuts' ends; d²ρ/dθ² is continuous there, so the samples
        # either side of a junction read it alike (within 0.5 %)
        out["x_accel_max_on_cut"] = bool(opt["x_accel_cut_m_s2"] >= 0.995 * opt["x_accel_peak_m_s2"])
        out["accel_period_s"] = trad["accel_period_s"]
        out["accel_step_deg"] = trad["accel_step_deg"]
        out["x_accel_by_step"] = by_step.result()
        if spiral is not None:
            out["spiral"] = spiral.result()
            out["_spiral_motion"] = out["spiral"].pop("motion")
            out["z_velocity_ratio"] = opt["w_velocity_peak_mm_s"] / out["spiral"]["z_velocity_peak_mm_s"]
            out["time_ratio"] = opt["machining_s"] / out["spiral"]["machining_s"]
        if figure is not None:
            figure.result()
    out["_programs"] = programs
    out["_resolved"] = resolved
    return out


# C steps [deg] the X accelerations are formed over in the ratio-versus-step table
STEPS_DEG = (0.05, 0.1, 0.25, 0.5, 1.0, 2.0, 4.0)
PAPER_RATIO = 0.16  # [5]: "16 % of that along the traditional D-shaped toolpath"


def accel_by_step(programs: dict[str, Any], rpm: float, machine_step_deg: float) -> dict[str, Any]:
    """Peak X acceleration [m/s²] of both transitions formed over each C step of
    :data:`STEPS_DEG` and the machine's own (one controller period at the spindle speed,
    marked ``machine``) on the planned curves (:func:`ftsweep.stages.paths.dpath.x_accel_peak_at_step`),
    their ratio, and the step [deg] at which the ratio is [5]'s 0.16 (log-log interpolation)."""
    rows = []
    both = TRANSITIONS
    curve = {k: dpath.radius_at(programs[k][0], programs[k][0].phi)[0] for k in both}
    for deg in sorted({*STEPS_DEG, machine_step_deg}):
        h = math.radians(deg)
        trad, opt = (dpath_motion.x_accel_peak_at_step(programs[k][0], rpm, h, curve[k]) for k in both)
        rows.append(
            {
                "step_deg": deg,
                "traditional_m_s2": trad,
                "optimised_m_s2": opt,
                "ratio": opt / trad,
                "machine": deg == machine_step_deg,
            }
        )
    ratio = np.array([r["ratio"] for r in rows])
    steps = np.array([r["step_deg"] for r in rows])
    at = float(np.exp(np.interp(math.log(PAPER_RATIO), np.log(ratio), np.log(steps))))
    return {"rows": rows, "paper_ratio": PAPER_RATIO, "paper_ratio_step_deg": at}


def _by_step_text(table: dict[str, Any]) -> str:
    """The ratio-versus-step table as one line."""
    cells = ", ".join(
        f"{r['step_deg']:.3g}°{' (machine)' if r['machine'] else ''}: "
        f"{r['traditional_m_s2']:.3g}/{r['optimised_m_s2']:.3g} = {r['ratio']:.3f}"
        for r in table["rows"]
    )
    return (
        f"  X acceleration over a C step h (traditional/optimised m/s² = ratio): {cells}; "
        f"[5]'s {table['paper_ratio']:g} at h = {table['paper_ratio_step_deg']:.2f}°"
    )


def x_motion_curves(
    programs: dict[str, tuple[dpath.DPath, np.ndarray]], rpm: float, period_s: float, cycles: int = 2
) -> dict[str, dict[str, np.ndarray]]:
    """What [5] fig. 3 shows of each transition over its first ``cycles`` revolutions: the
    planned path at constant spindle speed sampled every controller period ``period_s`` [s]
    (eqs. 3–6): polar angle ``deg`` [deg], ρ ``rho_mm`` [mm], X acceleration ``x_accel_m_s2``
    [m/s²] at the samples, X feed ``x_feed_mm_s`` [mm/s] at the steps' middles ``mid_deg``
    (the traditional acceleration is a spike over one period)."""
    out = {}
    for kind, (path, z) in programs.items():
        t = dpath_motion.point_times(path.phi, path.rho, z, "spindle", rpm)
        s, _, m = dprog.sampled_motion(path, z, t, period_s, until_s=cycles * 60.0 / rpm)
        out[kind] = {
            "deg": np.degrees(s.phi),
            "rho_mm": s.rho * 1e-3,
            "mid_deg": np.degrees(0.5 * (s.phi[1:] + s.phi[:-1])),
            "x_feed_mm_s": m.velocity[:, 1] * 1e3,
            "x_accel_m_s2": m.accel[:, 1],
        }
    return out


def x_motion_title(rpm: float) -> str:
    """[5] fig. 3's title at spindle speed ``rpm``."""
    omega = rpm * 2.0 * math.pi / 60.0
    return f"D path: traditional against optimised transition at {rpm:g} rpm (ω = {omega:.3g} rad/s)"


def z_motion_curves(
    spiral: dict[str, Any], program: tuple[dpath.DPath, np.ndarray], rpm: float
) -> dict[str, dict[str, np.ndarray]]:
    """What [5] fig. 7 shows: Z [µm] over one revolution of the spiral (from mid-radius,
    ``spiral`` as :func:`spiral_motion`) and over one cycle of the D path (the mid-zone cut),
    against C within it (``deg`` [deg]), with the Z velocity [mm/s] of the steps from each
    point (``step_deg``)."""
    phi = spiral["phi"]
    mid = 0.5 * phi[-1]
    sel = (phi >= mid) & (phi < mid + 2.0 * math.pi)
    path, z = program
    t = dpath_motion.point_times(path.phi, path.rho, z, "spindle", rpm)
    m = dpath_motion.axis_motion(t, path.phi, path.rho, z)
    cycle = path.n_cuts // 2
    dsel = (path.phi >= path.cut_centre[cycle] - math.pi) & (path.phi < path.cut_centre[cycle] + math.pi)

    def one(phi: np.ndarray, z: np.ndarray, velocity: np.ndarray, on: np.ndarray) -> dict[str, np.ndarray]:
        start = phi[on][0]
        return {
            "deg": np.degrees(phi[on] - start),
            "z_um": z[on],
            "step_deg": np.degrees(phi[:-1][on[:-1]] - start),
            "z_velocity_mm_s": velocity[on[:-1]],
        }

    return {
        "spiral": one(phi, spiral["z"], spiral["z_velocity_mm_s"], sel),
        "D path": one(path.phi, z, m["z_velocity_mm_s"], dsel),
    }


def plot_x_motion(
    programs: dict[str, tuple[dpath.DPath, np.ndarray]], rpm: float, period_s: float, out: Path
) -> Path:
    """[5] fig. 3 (:func:`x_motion_curves`, drawn by :func:`ftsweep.kinds.dpath.figures.draw_x_motion`)
    saved to ``out`` here and now (:class:`ftsweep.kinds.dpath.figures.Plots` draws it beside a study)."""
    from ftsweep.kinds.dpath import figures as dfigures

    return dfigures.draw_x_motion(x_motion_curves(programs, rpm, period_s), x_motion_title(rpm), out)


def plot_z_motion(
    spiral: dict[str, Any], program: tuple[dpath.DPath, np.ndarray], rpm: float, out: Path
) -> Path:
    """[5] fig. 7 (:func:`z_motion_curves`, drawn by :func:`ftsweep.kinds.dpath.figures.draw_z_motion`)
    saved to ``out`` here and now."""
    from ftsweep.kinds.dpath import figures as dfigures

    return dfigures.draw_z_motion(z_motion_curves(spiral, program, rpm), out)


def public(summary: dict[str, Any]) -> dict[str, Any]:
    """The summary without its private arrays (for JSON)."""
    return {k: v for k, v in summary.items() if not k.startswith("_")}


def text_lines(s: dict[str, Any]) -> list[str]:
    """Human-readable summary of :func:`study`."""
    trad, opt = s["traditional"], s["optimised"]
    lines = [
        f"D path on {s['surface']}: zone {opt['cut_length_um'] / 1e3:g} × {opt['cut_width_um'] / 1e3:g} mm, centre "  # noqa: E501
        f"{opt['offaxis_um'] / 1e3:g} mm off-axis, spacing {opt['spacing_um']:g} µm, {opt['n_cuts']} cuts × "
        f"{opt['points_per_cut']} points, {opt['spindle_rpm']:g} rpm",
    ]
    for name, r in (("traditional", trad), ("optimised", opt)):
        lines.append(
            f"  {name:<11}: X {r['x_min_um'] / 1e3:.3f}..{r['x_max_um'] / 1e3:.3f} mm, peak X feed "
            f"{r['x_feed_peak_mm_s']:.1f} mm/s, peak X accel {r['x_accel_peak_m_s2']:.3f} m/s² (cuts "
            f"{r['x_accel_cut_m_s2']:.3f}, transitions {r['x_accel_transition_m_s2']:.3f}); P-V {r['pv_nm']:.1f} nm; "  # noqa: E501
            f"{r['machining_s']:.0f} s; {'feasible' if r['feasible'] else 'INFEASIBLE: ' + r['infeasible_reason']}"  # noqa: E501
        )
    lines.append(
        f"  X acceleration ratio optimised/traditional: {s['x_accel_ratio']:.3f}, formed over the "
        f"controller's period {s['accel_period_s'] * 1e3:.3g} ms (a {s['accel_step_deg']:.3g}° C step; "
        "the traditional spike scales as 1/step)",
    )
    lines.append(_by_step_text(s["x_accel_by_step"]))
    lines.append(
        f"  junctions: traditional dρ/dθ jump {trad['slope_jump_um_rad'] / 1e3:.3f} mm/rad; optimised relative jumps "  # noqa: E501
        f"ρ {opt['rho_rel_jump']:.1e}, dρ/dθ {opt['d1_rel_jump']:.1e}, d²ρ/dθ² {opt['d2_rel_jump']:.1e}"
    )
    for name in ("traditional", "optimised"):
        for mode, where in (("feed_mode", "whole path"), ("feed_mode_cuts", "cuts only")):
            f = s[name][mode]
            c_all = f"{f['c_speed_min_rpm']:.1f}..{f['c_speed_max_rpm']:.1f}"
            cuts = f"{f['c_speed_cut_min_rpm']:.1f}..{f['c_speed_cut_max_rpm']:.1f}"
            lines.append(
                f"  constant feed on the {where} ({name}): {f['time_s']:.0f} s, C {c_all} rpm (cuts {cuts}), "
                f"largest C jump {f['c_speed_jump_rpm']:.1f} rpm"
            )
    if "spiral" in s:
        sp = s["spiral"]
        lines.append(
            f"  spiral on the same part (centred): P-V {sp['pv_nm']:.1f} nm, {sp['machining_s']:.0f} s, peak Z velocity "  # noqa: E501
            f"{sp['z_velocity_peak_mm_s']:.4g} mm/s (D path {opt['w_velocity_peak_mm_s']:.4g} mm/s, ratio "
            f"{s['z_velocity_ratio']:.2e}); D path time / spiral time {s['time_ratio']:.2f}"
        )
    return lines


def default_case(
    surface: str = "concave_sphere",
    machine: str = "sts-xzc",
    cutting: str = "dpath-finish",
    options: Optional[dict[str, Any]] = None,
) -> Case:
    """The D-path case of the study (defaults: [5]'s example on its sphere)."""
    given = {k: v for k, v in (options or {}).items() if v is not None}
    return Case(
        surface=surface, layout=program_request(kind="dpath", **given), machine=machine, cutting=cutting
    )
