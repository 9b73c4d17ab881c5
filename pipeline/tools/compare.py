"""``ftsweep compare``: program kinds against each other on one part, from their cubes, under
the same conditions (surface, tool, feed, machine, compensation: :func:`conditions`).

Each cube contributes one line: for every value of its point axis (target N of a table
sweep, or the rule axis of a spiral sweep) its best eligible case, the one ``select`` would
choose there (:func:`ftsweep.tools.query.best_per_points`). The table lists them side by side and
the plot draws P-V against the realised point count, one line per cube (program kind).

Each kind's own rule sets the spindle angles it is simulated on (a table's by its cells, a
spiral's by its densest revolution), which moves P-V by a few per cent; so the rows of
spindle programs are simulated again on one sampling, the finest among them
(:func:`common_sampling`), their cube's P-V kept beside. D paths and Fresnel programs are
sampled on rays of their own geometry and keep theirs.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from typing import Any, Optional

from ftsweep import registry
from ftsweep.store.storage import PathLike, Place, place
from ftsweep.tools import query
from ftsweep.tools.select import SelectError, open_cube, recorded_case


def label_of(ds: Any, path: PathLike) -> str:
    """``kind: rule`` of a cube, e.g. ``ring table`` or ``spiral (chord_um)``."""
    kind = ds.attrs.get("layout_method", "?")
    stem = place(path).name.removesuffix(".zarr")
    if registry.kind(kind).aspect_range is None:  # a path program: its rule or spacing axis
        return f"{kind} ({ds['status'].dims[0]}) {stem}"
    return f"{kind} table {stem}"


# each compared cube's place, with the storage options it was given (rows hold its text)
_OPENED_AT: dict[str, Place] = {}

# what must match for two cubes to be compared: the part, the tool, the feed, the machine and
# the compensation (the spindle-angle sampling is the resolution's, recorded per case)
CONDITIONS = ("surface", "nose_radius_um", "feed_um", "machine", "compensation", "resolution")


def _values_text(values: Iterable[float]) -> str:
    return ", ".join(f"{v:g}" for v in sorted(set(values)))


def conditions(ds: Any) -> dict[str, str]:
    """The cutting conditions of a cube as its recorded spec and entries give them: surface,
    nose radius [µm] and feed [µm/rev] (one value, or every value of a swept axis: a kind's
    axis whose values are its feed, or set it, :attr:`ftsweep.engine.contract.Axis.feed`),
    machine, compensation. Text, to compare and to show."""
    from ftsweep.sweeps.spec import SweepSpec, axis_values

    spec = SweepSpec.model_validate_json(ds.attrs["sweep_spec"])
    cutting = json.loads(ds.attrs["catalog_entries"])["cutting"][spec.cutting]
    axes = spec.axes
    own = {a.feed: a for a in registry.kind(str(ds.attrs["layout_method"])).axes if a.feed}
    sets = own.get("sets")
    if sets is not None and axes.get(sets.name) is not None:
        feed = f"set by {sets.name} " + _values_text(axis_values(axes.get(sets.name))) + f" {sets.units}"
    else:
        spacing = own.get("is")
        swept = axes.feed_um if axes.feed_um is not None else (spacing and axes.get(spacing.name))
        feed = _values_text(axis_values(swept) if swept is not None else [cutting["feed_um"]])
    radii = (
        axis_values(axes.nose_radius_um) if axes.nose_radius_um is not None else [cutting["nose_radius_um"]]
    )
    res = spec.resolution
    sampling = f"{res.samples_per_cell} samples per cell, {res.points_per_feed} points per feed"
    return {
        "surface": spec.surface,
        "nose_radius_um": _values_text(radii),
        "feed_um": feed,
        "machine": spec.machine,
        "compensation": ", ".join(axes.compensation) if axes.compensation else spec.compensation,
        "resolution": sampling + (f", {res.n_theta} angles" if res.n_theta else ""),
    }


def differing(per_cube: dict[str, dict[str, str]]) -> list[str]:
    """The conditions whose text differs between the cubes."""
    return [c for c in CONDITIONS if len({cond[c] for cond in per_cube.values()}) > 1]


def compare_rows(
    paths: list[PathLike], allow_different: bool = False
) -> tuple[list[dict[str, Any]], dict[str, dict[str, str]]]:
    """One row per (cube, point-axis value) with a chosen case: cube label, the axis value,
    realised N and the case's P-V, RMS and interpolation-only P-V [nm]; and each cube's
    :func:`conditions` by label. Cubes whose conditions differ are refused, naming the
    difference, unless ``allow_different``."""
    rows: list[dict[str, Any]] = []
    per_cube: dict[str, dict[str, str]] = {}
    for path in paths:
        ds = open_cube(path).load()
        label = label_of(ds, path)
        _OPENED_AT[str(place(path))] = place(path)
        per_cube[label] = conditions(ds)
        for target, flat in query.best_per_points(ds):
            if flat is None:
                continue
            case = query.describe(ds, flat)
            rows.append(
                {
                    "program": label,
                    "kind": str(ds.attrs.get("layout_method")),
                    "cube": str(place(path)),
                    "index": case["index"],  # its case number, which growth never changes
                    "name": case["name"],
                    "target": target,
                    "n_points": case["n_points"],
                    "pv_nm": case["pv_nm"],
                    "rms_nm": case["rms_nm"],
                    "pv_interp_nm": case["pv_interp_nm"],
                    "n_theta": int(ds["n_theta"].values.ravel()[flat]) if "n_theta" in ds else None,
                }
            )
    differ = differing(per_cube)
    if differ and not allow_different:
        what = "; ".join(
            f"{c}: " + " vs ".join(f"{cond[c]} ({label.split()[-1]})" for label, cond in per_cube.items())
            for c in differ
        )
        raise SelectError(
            f"the cubes were made under different conditions ({what}): compare like with like, or give "
            "--allow-different to list them anyway"
        )
    if not rows:
        raise SelectError("none of the cubes has a computed, feasible case to compare")
    return sorted(rows, key=lambda r: (r["program"], r["n_points"])), per_cube


def plot_compare(rows: list[dict[str, Any]], title: str = "") -> Any:
    """P-V [nm] against realised point count, one line per program (log axes)."""
    from ftsweep.tools.accessor import _axes, _cmap

    ax = _axes(None, (7.0, 4.6))
    programs = list(dict.fromkeys(r["program"] for r in rows))
    cmap = _cmap(len(programs))
    for i, name in enumerate(programs):
        mine = [r for r in rows if r["program"] == name]
        ax.plot(
            [r["n_points"] for r in mine], [r["pv_nm"] for r in mine], "o-", ms=4, color=cmap(i), label=name
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("control points N (count)")
    ax.set_ylabel("P-V form error [nm]")
    ax.set_title(title or "table against path: P-V against point count", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return ax


def common_sampling(
    rows: list[dict[str, Any]],
    trust_plugins: bool = False,
    progress: Optional[Callable[[int, int], None]] = None,
) -> Optional[int]:
    """Simulate the rows of spindle programs (kinds sampled by spindle angles) again on the
    largest angle count among them, in place: ``pv_nm``, ``rms_nm``, ``pv_interp_nm`` and
    ``n_theta`` then hold that sampling's, ``pv_recorded_nm`` the cube's. Returns the count
    (None when fewer than two such rows). Each case is re-planned from its cube's recorded
    spec and entries."""
    from ftsweep.simulate import run_case

    spindle = [r for r in rows if registry.kind(r["kind"]).samples_spindle_angles and r["n_theta"]]
    if len(spindle) < 2:
        return None
    n_theta = max(int(r["n_theta"]) for r in spindle)
    todo = [r for r in spindle if r["n_theta"] != n_theta]
    for r in spindle:
        r["pv_recorded_nm"] = r["pv_nm"]
    opened: dict[str, Any] = {}
    for i, r in enumerate(todo):
        ds = opened.setdefault(r["cube"], open_cube(_OPENED_AT.get(r["cube"], r["cube"])))
        case, specs = recorded_case(ds, query.flat_of(ds, r["index"]), trust_plugins)
        case = case.model_copy(update={"resolution": case.resolution.model_copy(update={"n_theta": n_theta})})
        record = run_case(case, specs=specs)
        r.update({k: record[k] for k in ("pv_nm", "rms_nm", "pv_interp_nm", "n_theta")})
        if progress is not None:
            progress(i + 1, len(todo))
    return n_theta
