"""A registered measurement as data and as pictures: an xarray Dataset of the measured points
(x, y [µm]) with the form error, what the prediction explains and what it leaves [nm], and
the fit and breakdowns as attributes (written to NetCDF, read back checked); the three maps
side by side on one colour scale, and the breakdown's bar chart.

The file is untrusted when read back: its variables, dimensions and sizes are checked and its
attributes parsed as JSON data, never executed.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Optional

import numpy as np
import xarray as xr

from ftsweep.inputs.measurements import MAX_BYTES
from ftsweep.tools.measure import Explained, MeasuredPart

MAPS = {
    "form_error_nm": "measured form error (registered)",
    "explained_nm": "predicted form error (registered as the measurement)",
    "unexplained_nm": "what the prediction leaves: the machine's share",
}
TITLES = {
    "form_error_nm": "measured",
    "explained_nm": "predicted",
    "unexplained_nm": "unexplained (the machine's)",
}


def registered_dataset(part: MeasuredPart, split: Optional[Explained] = None) -> xr.Dataset:
    """The registered measurement over dimension ``point``: ``form_error_nm`` and, with the
    prediction's ``split``, ``explained_nm`` and ``unexplained_nm``; the summaries (file hash,
    fitted terms ± σ, breakdowns) as JSON attributes ``measured`` and ``explained``."""
    m = part.measurement
    data = {"form_error_nm": ("point", 1e3 * part.registration.residual, {"units": "nm"})}
    if split is not None:
        data["explained_nm"] = ("point", 1e3 * split.explained, {"units": "nm"})
        data["unexplained_nm"] = ("point", 1e3 * split.unexplained, {"units": "nm"})
    for name, attrs in data.items():
        attrs[2]["long_name"] = MAPS[name]
    ds = xr.Dataset(
        data,
        coords={"x_um": ("point", m.x, {"units": "um"}), "y_um": ("point", m.y, {"units": "um"})},
    )
    ds.attrs["ftsweep_registered"] = 1
    ds.attrs["measured"] = json.dumps(part.summary, sort_keys=True)
    if split is not None:
        ds.attrs["explained"] = json.dumps(split.summary, sort_keys=True)
    return ds


def open_registered(path: Path) -> xr.Dataset:
    """A registered measurement written by :func:`registered_dataset` (NetCDF), checked: its
    size bounded before reading, its variables those named here on one ``point`` dimension,
    its attributes JSON objects."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no registered measurement there")
    if path.stat().st_size > MAX_BYTES:
        raise ValueError(
            f"{path}: {path.stat().st_size:,} bytes, over the {MAX_BYTES:,} a measurement may have"
        )
    try:
        ds = xr.open_dataset(path).load()
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: not a registered measurement ({str(exc)[:200]})") from None
    if ds.attrs.get("ftsweep_registered") != 1 or "form_error_nm" not in ds:
        raise ValueError(f"{path}: not a registered measurement ftsweep wrote (ftsweep measure -o)")
    unknown = sorted(str(v) for v in set(ds.data_vars) - set(MAPS))
    if unknown or set(ds.dims) != {"point"}:
        found = unknown or sorted(str(d) for d in ds.dims)
        raise ValueError(f"{path}: unexpected variables or dimensions ({found})")
    for key in ("measured", "explained"):
        if key in ds.attrs:
            try:
                value = json.loads(str(ds.attrs[key]))
            except json.JSONDecodeError:
                raise ValueError(f"{path}: attribute {key} is not JSON") from None
            if not isinstance(value, dict):
                raise ValueError(f"{path}: attribute {key} is not a JSON object")
    return ds


def plot_maps(ds: xr.Dataset, path: Optional[Path] = None) -> Any:
    """The maps of ``ds`` (measured, predicted, unexplained) side by side on one symmetric
    colour scale [nm]; saved to ``path`` (PNG) when given. Returns the figure."""
    import matplotlib

    if path is not None:
        matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    shown = [name for name in MAPS if name in ds]
    values = np.concatenate([ds[name].values for name in shown])
    scale = float(np.nanmax(np.abs(values))) if np.isfinite(values).any() else 1.0
    fig, axes = plt.subplots(
        1, len(shown), figsize=(3.9 * len(shown) + 1.0, 3.9), squeeze=False, layout="constrained"
    )
    for ax, name in zip(axes[0], shown, strict=True):
        look = ax.scatter(
            ds["x_um"].values / 1e3,
            ds["y_um"].values / 1e3,
            c=ds[name].values,
            s=4,
            cmap="RdBu_r",
            vmin=-scale,
            vmax=scale,
            linewidths=0,
        )
        ax.set_aspect("equal")
        ax.set_title(TITLES[name], fontsize=10)
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
    fig.colorbar(look, ax=axes[0].tolist(), label="form error [nm], one scale for all", shrink=0.85)
    if path is not None:
        from ftsweep.store.io import save_figure

        save_figure(fig, path)
    return fig


def plot_terms(ds: xr.Dataset, path: Optional[Path] = None, largest: int = 12) -> Any:
    """The breakdown's bar chart [nm]: the measured form error's ``largest`` terms, and beside
    each what the prediction explains and what it leaves; saved to ``path`` when given."""
    import matplotlib

    if path is not None:
        matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    split = json.loads(str(ds.attrs.get("explained", "{}")))
    rows = split.get("form_error_terms") or json.loads(str(ds.attrs["measured"]))["breakdown"]
    measured = {t["term"]: t["nm"] for t in rows}
    said = {t["term"]: t["nm"] for t in split.get("explained_terms", [])}
    left = {t["term"]: t["nm"] for t in split.get("unexplained_terms", [])}
    names = sorted(measured, key=lambda k: -abs(measured[k]))[:largest]
    at = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(max(6.0, 0.6 * len(names)), 3.8))
    ax.bar(at - 0.27, [measured[n] for n in names], 0.27, label="measured")
    if said:
        ax.bar(at, [said.get(n, np.nan) for n in names], 0.27, label="explained by the prediction")
        ax.bar(at + 0.27, [left.get(n, np.nan) for n in names], 0.27, label="unexplained")
    ax.set_xticks(at, [n.split(" ")[0] for n in names], rotation=45, ha="right", fontsize=8)
    ax.set_ylabel("coefficient [nm]")
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.legend(fontsize=8)
    fig.tight_layout()
    if path is not None:
        from ftsweep.store.io import save_figure

        save_figure(fig, path)
    return fig


def plot_trade(found: xr.Dataset, path: Optional[Path] = None) -> Any:
    """The correction's trade (:func:`ftsweep.tools.correct.trade`): the predicted residual RMS
    [nm] over the gain, one line per low-pass, against the uncorrected one; saved when given."""
    import matplotlib

    if path is not None:
        matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    rms = found["residual_rms_nm"]
    fig, ax = plt.subplots(figsize=(6.0, 4.0), layout="constrained")
    gains = np.atleast_1d(rms["correction_gain"].values)
    for kept in np.atleast_1d(rms["correction_terms"].values):
        line = rms.sel(correction_terms=kept) if "correction_terms" in rms.dims else rms
        ax.plot(gains, np.atleast_1d(line.values), "o-", label=f"{int(kept)} terms kept")
    ax.axhline(found.attrs["uncorrected_rms_nm"], color="0.4", ls="--", label="uncorrected")
    ax.set_xlabel("gain g [-]")
    ax.set_ylabel("predicted residual RMS [nm]")
    ax.set_yscale("log")
    ax.legend(fontsize=8)
    if path is not None:
        from ftsweep.store.io import save_figure

        save_figure(fig, path)
    return fig
