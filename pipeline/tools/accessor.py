"""``ds.ftsweep``: an xarray accessor for result cubes, so notebooks need no glue code.

Registered when ``ftsweep`` is imported::

    import xarray as xr, ftsweep
    ds = xr.open_zarr("outputs/sinewave-ring.zarr")
    ds.ftsweep.best(budget_points=950_000)
    ds.ftsweep.plot_pv()            # P-V against point count, one line per aspect ratio
    ds.ftsweep.plot_aspect()        # P-V against aspect ratio, optimum marked
    ds.ftsweep.plot_heatmap()
    ds.ftsweep.plot_error_map(42)   # needs a sweep run with resolution.error_map_bins
"""

from __future__ import annotations

from typing import Any, Optional

import numpy as np
import xarray as xr

from ftsweep.store.io import new_axes as _axes


def aspect_label(ds: xr.Dataset) -> str:
    """Axis label of the aspect ratio, with its unit for the cube's layout method."""
    from ftsweep import registry

    kind = str(ds.attrs.get("layout_method"))
    first, second = (n.split("_")[0][1:] for n in registry.kind(kind).pitches)
    units = registry.kind(kind).aspect_units.replace("um", "µm")
    unit = "(dimensionless)" if units == "1" else f"[{units}]"
    return f"aspect ratio α = Δ{_greek(first)}/Δ{_greek(second)} {unit}"


def _shown(value: Any) -> str:
    """A coordinate value for a label: a number to 3 digits, a name (the compensation) as it is."""
    return value if isinstance(value, str) else f"{value:.3g}"


def _greek(name: str) -> str:
    return {"rho": "ρ", "theta": "θ"}.get(name, name)


@xr.register_dataset_accessor("ftsweep")
class FtsweepAccessor:
    """Selection and plots of an ftsweep result cube."""

    def __init__(self, ds: xr.Dataset) -> None:
        self._ds = ds

    # ------------------------------------------------------------------ data
    def done(self) -> xr.Dataset:
        """The cube's numeric variables with not-done cases masked (NaN)."""
        numeric = [v for v in self._ds.data_vars if self._ds[v].dtype.kind in "fiub"]
        from ftsweep.store import cube

        return self._ds[numeric].where(self._ds["status"] == cube.DONE)

    def pv(self) -> xr.DataArray:
        """P-V [nm] of the eligible cases (done, feasible, within capacity: those ``select``
        may choose) over (points, aspect), other axes reduced by their minimum."""
        from ftsweep.tools import query

        return query.best_pv_over_aspect(self._ds)

    def best(self, budget_points: Optional[int] = None, tolerance_nm: Optional[float] = None) -> xr.Dataset:
        """The case ``ftsweep select`` chooses (best under a budget, or fewest points meeting
        a tolerance; :mod:`ftsweep.tools.select`) as a selection of the cube: every variable,
        every dimension kept at length 1 with its coordinate (units and names intact), its
        case number in ``attrs["index"]`` (the same case however the cube grows) and its name
        by coordinates in ``attrs["case"]`` (``points=950000 aspect=16``).
        ``best(...).pv_nm.item()`` is the P-V [nm]."""
        from ftsweep.tools import query
        from ftsweep.tools.select import choose

        chosen = choose(self._ds, budget_points=budget_points, tolerance_nm=tolerance_nm)
        at = {d: [i] for d, i in query.position(self._ds, query.flat_of(self._ds, chosen["index"])).items()}
        return self._ds.isel(at).compute().assign_attrs(index=int(chosen["index"]), case=chosen["name"])

    def _kind_noun(self) -> str:
        """The noun of the cube's program kind (the registry's), e.g. for a legend."""
        from ftsweep import registry

        return registry.kind(str(self._ds.attrs.get("layout_method"))).noun

    def _need_aspect(self, what: str) -> None:
        if "aspect" not in self._ds.dims:
            raise ValueError(
                f"{what} reads a sweep's aspect axis; this {self._kind_noun()} cube has none (use "
                "plot_pv, best or ftsweep compare)"
            )

    def optimum(self) -> xr.DataArray:
        """Best aspect ratio per target point count among the eligible cases (the sweep
        summary's and ``select``'s best; NaN where none is eligible), named and with the
        units of the cube's ``aspect`` coordinate (not the P-V's it is chosen by)."""
        self._need_aspect("optimum")
        pv = self.pv()
        found = pv.notnull().any("aspect")
        best = pv.fillna(np.inf).idxmin("aspect").where(found)
        # computed: an answer, not a lazy graph (the cube is small)
        return best.rename("aspect").assign_attrs(self._ds["aspect"].attrs).compute()

    # ------------------------------------------------------------------ plots
    def plot_pv(self, ax: Any = None) -> Any:
        """P-V [nm] against the realised point count, one line per aspect ratio (log axes)."""
        ax = _axes(ax)
        ds = self.done()
        pv = self.pv()
        n = ds["n_points"]
        if "aspect" not in ds.dims:
            # a cube swept by its kind's own axes, not aspect ratios: one line along the axis
            # its point count follows per value of the others
            rule = ds["n_points"].dims[0]
            lines = [d for d in pv.dims if d != rule]
            stacked = pv.stack(line=lines) if lines else pv.expand_dims(line=[0])
            counts = n.stack(line=lines) if lines else n.expand_dims(line=[0])
            cmap = _cmap(stacked.sizes["line"])
            for i in range(stacked.sizes["line"]):
                label = ", ".join(
                    f"{d} = {_shown(stacked['line'].values[i][j])}" for j, d in enumerate(lines)
                )
                order = np.argsort(counts.isel(line=i).values)
                ax.plot(
                    counts.isel(line=i).values[order],
                    stacked.isel(line=i).values[order],
                    "o-",
                    ms=3,
                    color=cmap(i),
                    label=label or rule,
                )
            legend_title = f"{self._kind_noun()}s along {rule}"
        else:
            other = [d for d in n.dims if d not in ("points", "aspect")]
            if other:
                n = n.max(other)
            cmap = _cmap(len(ds["aspect"]))
            for i, a in enumerate(ds["aspect"].values):
                ax.plot(n.isel(aspect=i), pv.isel(aspect=i), "o-", ms=3, color=cmap(i), label=f"α = {a:.3g}")
            legend_title = aspect_label(self._ds)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("control points N (count)")
        ax.set_ylabel("P-V form error [nm]")
        ax.set_title(f"{self._ds.attrs.get('sweep_name', '')}: P-V against point count")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, ncol=2, title=legend_title, title_fontsize=7)
        return ax

    def plot_aspect(self, ax: Any = None) -> Any:
        """P-V [nm] against aspect ratio, one line per target point count, optimum marked."""
        self._need_aspect("plot_aspect")
        ax = _axes(ax)
        pv = self.pv()
        aspect = self._ds["aspect"].values
        cmap = _cmap(len(self._ds["points"]))
        for i, n in enumerate(self._ds["points"].values):
            row = pv.isel(points=i).values
            ax.plot(aspect, row, "o-", ms=3, color=cmap(i), label=f"N ≤ {n:,.0f}")
            if np.any(np.isfinite(row)):
                j = int(np.nanargmin(row))
                ax.plot(aspect[j], row[j], "*", ms=13, color=cmap(i), markeredgecolor="black")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(aspect_label(self._ds))
        ax.set_ylabel("P-V form error [nm]")
        ax.set_title("P-V against aspect ratio (★ optimum per point count)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, title="target points", title_fontsize=7)
        return ax

    def plot_heatmap(self, ax: Any = None) -> Any:
        """Heat map of log10 P-V over (target point count, aspect ratio)."""
        import matplotlib.colors as mcolors

        self._need_aspect("plot_heatmap")
        ax = _axes(ax)
        pv = self.pv().transpose("aspect", "points")
        values = pv.values
        im = ax.pcolormesh(
            np.arange(values.shape[1] + 1),
            np.arange(values.shape[0] + 1),
            values,
            norm=mcolors.LogNorm(),
            cmap="viridis",
            shading="flat",
        )
        ax.set_xticks(
            np.arange(values.shape[1]) + 0.5,
            [f"{n:,.0f}" for n in self._ds["points"].values],
            rotation=45,
            fontsize=7,
        )
        ax.set_yticks(
            np.arange(values.shape[0]) + 0.5, [f"{a:.3g}" for a in self._ds["aspect"].values], fontsize=7
        )
        for j in range(values.shape[1]):
            if np.any(np.isfinite(values[:, j])):
                i = int(np.nanargmin(values[:, j]))
                ax.plot(j + 0.5, i + 0.5, "*", color="white", ms=9, markeredgecolor="black")
        ax.set_xlabel("target control points N (count)")
        ax.set_ylabel(aspect_label(self._ds))
        ax.set_title("P-V [nm] over point count and aspect ratio (★ optimum)")
        ax.figure.colorbar(im, ax=ax, label="P-V form error [nm]")
        return ax

    def plot_error_map(self, index: Optional[int] = None, kind: str = "peak", ax: Any = None) -> Any:
        """The stored coarse error map [nm] of case ``index`` (default: best at the largest budget)."""
        var = f"error_map_{kind}_nm"
        if var not in self._ds:
            raise ValueError(
                "this cube stores no error maps; run the sweep with resolution.error_map_bins, "
                "or use `ftsweep report`, which re-simulates the chosen case"
            )
        if index is None:
            index = self.best(budget_points=int(self._ds["n_points"].max())).attrs["index"]
        from ftsweep.tools import query

        flat = query.flat_of(self._ds, index)
        emap = self._ds[var].isel(query.position(self._ds, flat))
        return plot_map(emap["map_x"].values, emap.values, query.describe(self._ds, flat), kind, ax)

    # ------------------------------------------------------ a registered measurement
    def _registered(self) -> xr.Dataset:
        if self._ds.attrs.get("ftsweep_registered") != 1:
            raise ValueError("not a registered measurement: open one that `ftsweep measure -o` wrote")
        return self._ds

    def measured(self) -> dict[str, Any]:
        """A registered measurement's summary: file hash, fitted terms ± σ, P-V, RMS [nm] and,
        where its prediction was given, the share it explains (:mod:`ftsweep.tools.measure`)."""
        import json

        ds = self._registered()
        found = dict(json.loads(str(ds.attrs["measured"])))
        if "explained" in ds.attrs:
            found["explained"] = json.loads(str(ds.attrs["explained"]))
        return found

    def terms(self) -> Any:
        """A registered measurement's breakdown as a table [nm], one row per term: measured,
        explained by the prediction and unexplained (where given, all three over the points
        the prediction covers, so the first is the sum of the other two)."""
        import pandas as pd

        summary = self.measured()
        # where a prediction was given, every column over the points where it is defined
        rows = summary.get("explained", {}).get("form_error_terms") or summary["breakdown"]
        table = pd.DataFrame(rows).set_index("term").rename(columns={"nm": "measured_nm"})
        for key in ("explained", "unexplained"):
            rows = summary.get("explained", {}).get(f"{key}_terms")
            if rows:
                table[f"{key}_nm"] = pd.DataFrame(rows).set_index("term")["nm"]
        return table

    def plot_measured(self, path: Any = None) -> Any:
        """A registered measurement's maps side by side on one colour scale [nm]."""
        from ftsweep.tools.measureviews import plot_maps

        return plot_maps(self._registered(), path)

    def plot_terms(self, path: Any = None) -> Any:
        """A registered measurement's breakdown as a bar chart [nm]."""
        from ftsweep.tools.measureviews import plot_terms

        return plot_terms(self._registered(), path)


def _cmap(n: int) -> Any:
    import matplotlib

    return matplotlib.colormaps["viridis"].resampled(max(n, 2))


def plot_map(
    centres_um: np.ndarray, values_nm: np.ndarray, case: dict[str, Any], kind: str, ax: Any = None
) -> Any:
    """An error map [nm] over the part (x, y in µm), symmetric colour scale, P-V and pitches in
    the title."""
    ax = _axes(ax, (6.2, 5.2))
    half = 0.5 * (centres_um[1] - centres_um[0])
    extent = (centres_um[0] - half, centres_um[-1] + half, centres_um[0] - half, centres_um[-1] + half)
    lim = float(np.nanmax(np.abs(values_nm))) if np.any(np.isfinite(values_nm)) else 1.0
    im = ax.imshow(values_nm, origin="lower", extent=extent, cmap="RdBu_r", vmin=-lim, vmax=lim)
    ax.figure.colorbar(im, ax=ax, label=f"{kind} form error e = z − f [nm]")
    from ftsweep import registry

    pitch = registry.kind(str(case.get("layout"))).pitch_text(case)
    ax.set_title(f"P-V {case['pv_nm']:.1f} nm, {case['n_points']:,} points, {pitch}", fontsize=9)
    ax.set_xlabel("x [µm]")
    ax.set_ylabel("y [µm]")
    return ax
