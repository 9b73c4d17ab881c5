"""The figures of a Fresnel study ([2] figs. 10, 12, 13): the facets and the quasi-spiral
over the part, the axes over the first turns, and the timesteps against the constant step
and the lower bound (:mod:`ftsweep.kinds.fresnel.study`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ftsweep.inputs import catalogs
from ftsweep.stages.paths import fresnel as ff
from ftsweep.store.io import save_figure


def plot(s: dict[str, Any], folder: Path) -> list[Path]:
    """Figures of a study ([2] figs. 10, 12, 13): ``fresnel-<surface>-path.png`` (facets over
    the part with the quasi-spiral, every 20th turn), ``-axes.png`` (C, X, Y, Z over the
    first turns) and ``-timesteps.png`` (the first turn's optimised timesteps, and the mean
    timestep of every turn against the constant one)."""
    folder.mkdir(parents=True, exist_ok=True)
    stem = folder / f"fresnel-{s['surface']}"
    out = []
    for suffix, draw in (
        ("-path.png", _plot_path),
        ("-axes.png", _plot_axes),
        ("-timesteps.png", _plot_steps),
    ):
        out.append(save_figure(draw(s), stem.with_name(stem.name + suffix)))
    return out


def _plot_path(s: dict[str, Any]) -> Any:
    """The facets over the part (edges white) and the quasi-spiral, every 20th turn."""
    import matplotlib.pyplot as plt

    fplan, specs = s["_plan"], s["_specs"]
    k = fplan.path.points_per_turn
    fig, ax = plt.subplots(1, 2, figsize=(11, 5))
    aperture = catalogs.aperture_of(specs.surface)
    hx, hy = aperture.half_extent_um
    gx, gy = np.meshgrid(np.linspace(-hx, hx, 301), np.linspace(-hy, hy, 301))
    fn = catalogs.base_callable(specs.surface)
    fc = ff.sliced(fn(gx, gy)[0], fplan.f_ref_um, fplan.facet_height_um)[0]
    fc = np.where(aperture.contains(gx, gy), fc, np.nan)
    im = ax[0].pcolormesh(gx * 1e-3, gy * 1e-3, fc, shading="auto", cmap="viridis")
    fig.colorbar(im, ax=ax[0], label="f_c [µm]")
    for edge in fplan.path.edges[:-1]:
        closed = np.vstack([edge, edge[:1]]) * 1e-3
        ax[0].plot(closed[:, 0], closed[:, 1], "w-", lw=0.8)
    ax[0].set(title=f"{s['n_facets']} facets of {s['facet_height_um']:g} µm (edges white)", xlabel="X [mm]")
    ax[0].set_ylabel("Y [mm]")
    xy = fplan.path.xy[:-1].reshape(-1, k, 2)[::20].reshape(-1, 2) * 1e-3
    ax[1].plot(xy[:, 0], xy[:, 1], lw=0.5)
    ax[1].set(title="quasi-spiral (every 20th turn), workpiece frame", xlabel="X [mm]", ylabel="Y [mm]")
    for a in ax:
        a.set_aspect("equal")
    fig.tight_layout()
    return fig


def _plot_axes(s: dict[str, Any]) -> Any:
    """C, X, Y, Z over the first three turns, at the program's timesteps."""
    import matplotlib.pyplot as plt

    fplan, steps = s["_plan"], s["_steps"]
    n = min(3 * fplan.path.points_per_turn, steps.steps.size)
    t = np.concatenate([[0.0], np.cumsum(steps.steps[:n])])
    fig, ax = plt.subplots(4, 1, figsize=(9, 8), sharex=True)
    series = (np.degrees(fplan.phi), fplan.x_um * 1e-3, fplan.y_um * 1e-3, fplan.tool_z_um)
    for a, v, label in zip(ax, series, ("C [deg]", "X [mm]", "Y [mm]", "Z [µm]"), strict=True):
        a.plot(t, v[: n + 1])
        a.set_ylabel(label)
    ax[0].set_title(f"axis trajectories over the first three turns ({s['timing']} timesteps)")
    ax[-1].set_xlabel("t [s]")
    fig.tight_layout()
    return fig


def _plot_steps(s: dict[str, Any]) -> Any:
    """The first turn's timesteps, and every turn's mean against the constant one and the bound."""
    import matplotlib.pyplot as plt

    k, steps = s["_plan"].path.points_per_turn, s["_steps"]
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    ax[0].plot(np.arange(k), steps.steps[:k] * 1e3)
    ax[0].set(title=f"first turn: {s['timing']} timesteps", xlabel="step k", ylabel="T [ms]")
    mean = steps.steps.reshape(-1, k).mean(axis=1)
    ax[1].plot(mean * 1e3, label=f"{s['timing']}, mean per turn")
    bound = s["_bound"].step_s.reshape(-1, k).mean(axis=1)
    ax[1].plot(bound * 1e3, ls=":", label="bound's steps, mean per turn")
    ax[1].axhline(steps.constant * 1e3, color="k", ls="--", label="constant")
    ax[1].set(title="timestep history", xlabel="turn", ylabel="T [ms]", yscale="log")
    ax[1].legend()
    fig.tight_layout()
    return fig
