"""``ftsweep compare``: tables against spiral programs on one surface, from their cubes.

Each cube contributes one line: for every value of its point axis (target N of a table
sweep, or the rule axis of a spiral sweep) its best eligible case, the one ``select`` would
choose there (:func:`ftsweep.query.best_per_points`). The table lists them side by side and
the plot draws P-V against the realised point count, one line per cube (program kind).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ftsweep import query
from ftsweep.select import SelectError, open_cube


def label_of(ds: Any, path: Path) -> str:
    """``kind: rule`` of a cube, e.g. ``ring table`` or ``spiral (chord_um)``."""
    kind = ds.attrs.get("layout_method", "?")
    if kind in ("spiral", "dpath"):
        return f"{kind} ({ds['status'].dims[0]}) {path.stem}"
    return f"{kind} table {path.stem}"


def compare_rows(paths: list[Path]) -> list[dict[str, Any]]:
    """One row per (cube, point-axis value) with a chosen case: cube label, surface, the
    axis value, realised N and the case's P-V, RMS and interpolation-only P-V [nm]."""
    rows: list[dict[str, Any]] = []
    surfaces = set()
    for path in paths:
        ds = open_cube(path).load()
        surfaces.add(ds.attrs.get("surface", "?"))
        label = label_of(ds, Path(path))
        for target, flat in query.best_per_points(ds):
            if flat is None:
                continue
            case = query.describe(ds, flat)
            rows.append(
                {
                    "program": label,
                    "target": target,
                    "n_points": case["n_points"],
                    "pv_nm": case["pv_nm"],
                    "rms_nm": case["rms_nm"],
                    "pv_interp_nm": case["pv_interp_nm"],
                }
            )
    if len(surfaces) > 1:
        raise SelectError(
            f"the cubes are of different surfaces ({', '.join(sorted(surfaces))}): compare one part"
        )
    if not rows:
        raise SelectError("none of the cubes has a computed, feasible case to compare")
    return sorted(rows, key=lambda r: (r["program"], r["n_points"]))


def plot_compare(rows: list[dict[str, Any]], title: str = "") -> Any:
    """P-V [nm] against realised point count, one line per program (log axes)."""
    from ftsweep.accessor import _axes, _cmap

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
    ax.set_xlabel("control points N [1]")
    ax.set_ylabel("P-V form error [nm]")
    ax.set_title(title or "table against path: P-V against point count", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return ax
