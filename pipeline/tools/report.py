"""``ftsweep report``: the figures engineers judge layouts by, and one HTML page with them.

1. P-V against point count, one line per aspect ratio (log axes);
2. P-V against aspect ratio, one line per point count, the optimum marked;
3. a heat map of P-V over (point count, aspect ratio);
4. the error map of a chosen case (default: the best at the largest budget), re-simulated
   with a fine map, colour bar in nm, P-V and pitches in the title;
5. the W command spectrum of that case with the servo bandwidth marked.
"""

from __future__ import annotations

import html
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, Optional

import numpy as np

import ftsweep.tools.accessor  # noqa: F401  (registers ds.ftsweep)
from ftsweep import registry
from ftsweep.engine.planning import control_table
from ftsweep.inputs.catalogs import aperture_of
from ftsweep.simulate import resolve_case, run_case
from ftsweep.stages.kinematics import dynamics
from ftsweep.store import cube, ledger
from ftsweep.store.io import save_figure, write_text_atomic
from ftsweep.store.storage import PathLike, place
from ftsweep.tools import query
from ftsweep.tools.accessor import _axes, plot_map
from ftsweep.tools.query import flat_of
from ftsweep.tools.select import SelectError, choose, describe, eligible, open_cube, recorded_case

FIGURES = {
    "pv_vs_points": "P-V against point count, one line per aspect ratio",
    "pv_vs_aspect": "P-V against aspect ratio, one line per point count, optimum marked",
    "pv_heatmap": "P-V over point count and aspect ratio",
    "error_map": "Form error of the chosen case over the part",
    "w_spectrum": "Spectrum of the W command of the chosen case",
}


def _save(ax: Any, path: Path) -> Path:
    """Save the figure of ``ax`` atomically, with the umask's permissions (:func:`save_figure`)."""
    return save_figure(ax.figure, path)


def resimulate(
    cube_path: PathLike,
    index: int,
    map_bins: int,
    progress: Optional[Callable[[int, int], None]] = None,
    trust_plugins: bool = False,
) -> tuple[dict[str, Any], Any]:
    """Re-run case ``index`` of a cube with an error map of ``map_bins`` bins, from the cube's
    recorded spec and catalog entries. Returns the record and (case, layout, table, specs)."""
    base, specs = recorded_case(open_cube(cube_path), index, trust_plugins)
    case = base.model_copy(
        update={"resolution": base.resolution.model_copy(update={"error_map_bins": map_bins})}
    )
    rcase = resolve_case(case, specs=specs)
    layout = rcase.layout
    if rcase.values is not None and rcase.gouge is not None:
        # a path program is planned with its commands once, here, and handed to the run
        table, gouge = rcase.values, rcase.gouge
        record = run_case(case, progress=progress, specs=specs, program=(layout, table))
        record["gouge_points"] = int(np.count_nonzero(gouge))
        return record, (case, layout, table, specs)
    # a table is compensated once, here, and handed to the run (which would redo it)
    table, gouge = control_table(case, layout, specs.surface, rcase.nose_radius_um)
    record = run_case(case, progress=progress, specs=specs, table=table)
    record["gouge_points"] = int(np.count_nonzero(gouge))
    return record, (case, layout, table, specs)


def plot_spectrum(record: dict[str, Any], layout: Any, table: np.ndarray, specs: Any) -> Any:
    """Amplitude spectra [nm] of W on the revolutions the verdict is judged on (model §6: 100,
    75, 50 and 25 % of the start radius), with the servo bandwidth and the significance floor
    (``spectrum_threshold`` of the dominant component over them all) the verdict uses: the case
    is infeasible by its spectrum exactly when a component above the floor lies right of the
    bandwidth. Components under 1 pm are not drawn (a line to a floor would be an artefact)."""
    surface, machine, cutting = specs
    k = dynamics.commands_per_revolution(machine.command_rate_hz, cutting.spindle_rpm)
    rho0 = float(getattr(layout, "rho0_um", None) or aperture_of(surface).outer_radius_um)
    spectra = [
        dynamics.spectrum(
            dynamics.analysed_revolution(layout, table, rho0, record["feed_um"], k, frac)[1 : k + 2],
            k,
            cutting.spindle_rpm,
        )
        for frac in dynamics.ANALYSED_RADII
    ]
    floor_nm = dynamics.significance_floor(spectra, machine.spectrum_threshold) * 1e3
    ax = _axes(None, (7.0, 4.4))
    for frac, (freq, amp) in zip(dynamics.ANALYSED_RADII, spectra, strict=True):
        shown = np.where(amp * 1e3 >= 1e-3, amp * 1e3, np.nan)
        ax.loglog(freq, shown, ".", ms=2.5, label=f"revolution at r = {frac * rho0:.0f} µm")
    ax.axvline(
        machine.bandwidth_hz, color="tab:red", ls="--", label=f"servo bandwidth {machine.bandwidth_hz:g} Hz"
    )
    ax.axhline(
        floor_nm,
        color="0.3",
        ls=":",
        label=f"significant from {floor_nm:.3g} nm ({machine.spectrum_threshold:.0%} of the largest)",
    )
    ax.set_xlabel(f"frequency [Hz] at {cutting.spindle_rpm:g} rpm")
    ax.set_ylabel("amplitude of W [nm]")
    ax.set_ylim(bottom=min(1e-3, floor_nm / 10))
    top = record["w_freq_max_hz"]
    verdict = (
        f"feasible: significant content up to {top:.0f} Hz, within the bandwidth"
        if record["feasible"]
        else f"INFEASIBLE: {record.get('infeasible_reason') or 'the machine limits'}"
    )
    ax.set_title(
        f"W command spectrum ({k:,} commands/rev at {machine.command_rate_hz / 1e3:g} kHz)\n{verdict}",
        fontsize=9,
    )
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return ax


def make_report(
    cube_path: PathLike,
    out_dir: Optional[Path] = None,
    index: Optional[int | str] = None,
    map_bins: int = 160,
    progress: Optional[Callable[[int, int], None]] = None,
    trust_plugins: bool = False,
    budget_points: Optional[int] = None,
    tolerance_nm: Optional[float] = None,
) -> dict[str, Path]:
    """Write the figures and ``index.html`` into ``out_dir``; returns their paths. The error map
    and spectrum show the case ``export`` chooses with the same ``budget_points``,
    ``tolerance_nm`` or ``index``; none given, the case the cube's last export wrote (its
    ledger), else the best at the largest budget."""
    at = place(cube_path)
    ds = open_cube(at)
    if not bool(eligible(ds).any()):
        raise SelectError(
            f"{at} has no computed, feasible case to report on yet; run the sweep first "
            f"(ftsweep sweep ... --out {at})"
        )
    stem = at.name.removesuffix(".zarr") + "-report"
    out = Path(out_dir) if out_dir else (at.path.with_name(stem) if at.local else Path("outputs") / stem)
    out.mkdir(parents=True, exist_ok=True)
    paths: dict[str, Path] = {}
    paths["pv_vs_points"] = _save(ds.ftsweep.plot_pv(), out / "pv_vs_points.png")
    if "aspect" in ds.dims:  # a spiral cube has no aspect axis to plot over
        paths["pv_vs_aspect"] = _save(ds.ftsweep.plot_aspect(), out / "pv_vs_aspect.png")
        paths["pv_heatmap"] = _save(ds.ftsweep.plot_heatmap(), out / "pv_heatmap.png")

    exported = None
    if index is None and budget_points is None and tolerance_nm is None:
        exported = ledger.latest_case(at)  # the case its last export chose, where it has one
        if exported is not None and exported[0] in query.case_numbers(ds):
            index = exported[0]
        else:
            exported = None
            budget_points = int(
                np.nanmax(ds["points"].values if "points" in ds.dims else ds["n_points"].values)
            )
    chosen = choose(ds, budget_points, tolerance_nm, index)
    if exported is not None:
        chosen["rule"] = f"the case last exported from the cube ({exported[1]})"
    flat = flat_of(ds, chosen["index"])
    record, (case, layout, table, specs) = resimulate(at, flat, map_bins, progress, trust_plugins)
    shown = dict(describe(ds, flat), pv_nm=record["pv_nm"])
    paths["error_map"] = _save(
        plot_map(record["error_map_x_um"], record["error_map_peak_nm"], shown, "peak"), out / "error_map.png"
    )
    if registry.kind(case.layout.kind).samples_spindle_angles:
        # the W spectrum of one revolution: programs about the spindle (tables, spirals); a D
        # path's motion is in its record (X feed and accelerations) and `ftsweep dpath`'s plots
        paths["w_spectrum"] = _save(plot_spectrum(record, layout, table, specs), out / "w_spectrum.png")
    paths["index"] = write_text_atomic(out / "index.html", _html(ds, chosen, record, paths))
    return paths


def _cube_rows(ds: Any) -> str:
    """The table rows that say which cube the report shows: its sweep, provenance and cases."""
    attrs = ds.attrs
    return "".join(
        f"<tr><th>{html.escape(k)}</th><td>{html.escape(str(v))}</td></tr>"
        for k, v in (
            ("sweep", attrs.get("sweep_name")),
            ("surface", attrs.get("surface")),
            ("layout method", attrs.get("layout_method")),
            ("ftsweep version", attrs.get("ftsweep_version")),
            ("git revision", attrs.get("git_revision")),
            ("cube created", attrs.get("created")),
            (
                "cases",
                f"{int(ds['status'].size)} ({int((ds['status'] == cube.DONE).sum())} done, "
                f"{int((ds['status'] == cube.FAILED).sum())} failed, "
                f"{int((ds['status'] == cube.REFUSED).sum())} refused, "
                f"{int((ds['status'] == cube.PRUNED).sum())} pruned)",
            ),
        )
    )


def _html(ds: Any, chosen: dict[str, Any], record: dict[str, Any], paths: dict[str, Path]) -> str:
    """The report's page: the cube, the chosen case, its motion, the figures and the spec."""
    attrs = ds.attrs
    rows = _cube_rows(ds)
    case_rows = "".join(
        f"<tr><th>{html.escape(k)}</th><td>{v:.4g}</td></tr>"
        if isinstance(v, float) and math.isfinite(v)
        else f"<tr><th>{html.escape(k)}</th><td>{html.escape(str(v))}</td></tr>"
        for k, v in chosen.items()
    )
    content = (
        f"content up to {record['w_freq_max_hz']:.0f} Hz"
        if math.isfinite(record.get("w_freq_max_hz", math.nan))
        else "no spectrum (a program's own block times)"
    )
    dyn = (
        f"stroke {record['stroke_um']:.3g} µm, peak velocity {record['w_velocity_peak_mm_s']:.3g} mm/s, "
        f"peak acceleration {record['w_accel_peak_m_s2']:.3g} m/s², {content}"
        if "w_freq_max_hz" in record
        else "; ".join(line.split(None, 1)[1] for line in registry.kind(record["layout"]).describe(record))
    )
    figs = "".join(
        f'<figure><img src="{html.escape(paths[k].name)}" alt="{html.escape(t)}"><figcaption>{html.escape(t)}'
        f"</figcaption></figure>"
        for k, t in FIGURES.items()
        if k in paths
    )
    spec = html.escape(json.dumps(json.loads(attrs.get("sweep_spec", "{}")), indent=2))
    title = html.escape(str(attrs.get("sweep_name")))
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>ftsweep report: {title}</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}}
table{{border-collapse:collapse;margin:1em 0}}th,td{{border:1px solid #ccc;padding:3px 8px;text-align:left}}
figure{{display:inline-block;margin:1em;vertical-align:top}}img{{max-width:520px}}pre{{background:#f5f5f5;padding:1em}}
</style></head><body>
<h1>ftsweep report: {html.escape(str(attrs.get("sweep_name")))}</h1>
<table>{rows}</table>
<h2>Chosen case ({html.escape(chosen.get("rule", ""))})</h2>
<table>{case_rows}</table>
<p>Re-simulated P-V {record["pv_nm"]:.2f} nm; W motion: {html.escape(dyn)}.</p>
<h2>Figures</h2>{figs}
<h2>Sweep spec</h2><pre>{spec}</pre>
</body></html>
"""
