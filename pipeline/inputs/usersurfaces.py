"""Surfaces users bring: gridded height maps and plug-in functions.

Both become ordinary surface callables ``fn(x, y) -> (f, ∂f/∂x, ∂f/∂y)`` (µm in, µm out)
for the stages. They live in pipeline/ because they read files and import user code.

* Height maps: a grid of heights read from NetCDF or Zarr (through xarray) or from .npy
  with the spacing given in the catalog, evaluated by an interpolating bicubic spline
  (scipy's RectBivariateSpline), whose derivatives give the slopes. The aperture must lie
  inside the data and the data must be finite there.
* Plug-ins: ``module:function`` taking x, y arrays in µm (and the entry's ``params`` as
  keywords) and returning heights, or (heights, ∂f/∂x, ∂f/∂y). Without slopes, central
  differences of the function supply them. A plug-in is checked on load by evaluating a
  small grid over the aperture.
"""

from __future__ import annotations

import functools
import importlib
import json
from pathlib import Path
from typing import Any

import numpy as np

from ftsweep.stages.sampling.surfaces import Aperture, SurfaceFn, bspline2d


class SurfaceLoadError(ValueError):
    """A user surface cannot be used; the message says what is wrong and where."""


# ----------------------------------------------------------------------------- height maps
def read_grid(
    path: Path,
    variable: str | None,
    x_name: str,
    y_name: str,
    spacing_um: tuple[float, float] | None,
    origin_um: tuple[float, float] | None,
    scale_to_um: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """x [µm], y [µm] and heights [µm] (shape (ny, nx)) of a gridded file."""
    if not path.exists():
        raise SurfaceLoadError(f"height map file {path} does not exist")
    if path.suffix == ".npy":
        if spacing_um is None:
            raise SurfaceLoadError(
                f"{path}: a .npy height map needs spacing_um [dx, dy] in the catalog entry"
            )
        try:
            # data, never code: object arrays (pickles) are refused
            z = np.load(path, allow_pickle=False)
        except ValueError as exc:
            raise SurfaceLoadError(f"{path}: not a numeric .npy array ({exc})") from None
        if z.dtype.kind not in "biuf":
            raise SurfaceLoadError(f"{path}: heights must be numbers, got an array of {z.dtype}")
        if z.ndim != 2:
            raise SurfaceLoadError(f"{path}: expected a 2-D array (rows y, columns x), got shape {z.shape}")
        ny, nx = z.shape
        dx, dy = spacing_um
        x0, y0 = origin_um if origin_um is not None else (-0.5 * (nx - 1) * dx, -0.5 * (ny - 1) * dy)
        return x0 + dx * np.arange(nx), y0 + dy * np.arange(ny), z * scale_to_um
    import xarray as xr

    try:
        ds = xr.open_zarr(path) if path.suffix == ".zarr" or path.is_dir() else xr.open_dataset(path)
    except Exception as exc:  # engines raise many types
        raise SurfaceLoadError(f"{path}: cannot be read as NetCDF or Zarr ({exc})") from None
    names = list(ds.data_vars)
    name = variable or (names[0] if len(names) == 1 else None)
    if name is None or name not in ds:
        raise SurfaceLoadError(
            f"{path}: name the height variable with 'variable' (found: {', '.join(names)})"
        )
    da = ds[name]
    if set(da.dims) != {x_name, y_name}:
        raise SurfaceLoadError(f"{path}: variable '{name}' has dims {da.dims}, expected ({y_name}, {x_name})")
    da = da.transpose(y_name, x_name)
    return (
        np.asarray(da[x_name], dtype=float),
        np.asarray(da[y_name], dtype=float),
        np.asarray(da.values, dtype=float) * scale_to_um,
    )


def height_map_surface(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, aperture: Aperture, source: str
) -> SurfaceFn:
    """A bicubic-spline surface through the grid, checked against the aperture."""
    from scipy.interpolate import RectBivariateSpline

    for name, axis in (("x", x), ("y", y)):
        if axis.size < 4 or np.any(np.diff(axis) <= 0):
            raise SurfaceLoadError(f"{source}: the {name} coordinates must increase, with at least 4 points")
    half_w, half_h = aperture.half_extent_um
    if -half_w < x[0] or half_w > x[-1] or -half_h < y[0] or half_h > y[-1]:
        raise SurfaceLoadError(
            f"{source}: the aperture (x ±{half_w:g} µm, y ±{half_h:g} µm) is larger than the data "
            f"(x {x[0]:g}…{x[-1]:g} µm, y {y[0]:g}…{y[-1]:g} µm)"
        )
    xx, yy = np.meshgrid(x, y)
    inside = aperture.contains(xx, yy)
    bad = inside & ~np.isfinite(z)
    if bad.any():
        iy, ix = np.argwhere(bad)[0]
        raise SurfaceLoadError(
            f"{source}: {int(bad.sum())} heights inside the aperture are not finite (NaN/inf), e.g. at "
            f"x = {x[ix]:g} µm, y = {y[iy]:g} µm; fill or crop the data"
        )
    # outside the aperture missing data may stay missing: the spline needs numbers there only
    z = np.where(np.isfinite(z), z, np.nanmean(z[inside]))
    # FITPACK fits the interpolating spline once; a numba kernel evaluates it (scipy's own
    # scattered evaluation costs microseconds a point, too slow for millions of nodes)
    spline = RectBivariateSpline(x, y, z.T, kx=3, ky=3, s=0)
    tx, ty, c = spline.get_knots()[0], spline.get_knots()[1], spline.get_coeffs()
    coef = c.reshape(tx.size - 4, ty.size - 4)
    return functools.partial(bspline2d, knots_x=tx, knots_y=ty, coefficients=coef)


# ----------------------------------------------------------------------------- plug-ins
def _import_function(target: str, source: str) -> Any:
    """The callable named ``module:function``."""
    module_name, sep, func_name = target.partition(":")
    if not sep or not module_name or not func_name:
        raise SurfaceLoadError(f"{source}: function must read 'module:function', got {target!r}")
    if "/" in module_name or "\\" in module_name or module_name.endswith(".py"):
        raise SurfaceLoadError(
            f"{source}: {module_name!r} is a file path; name an importable module ('module:function') "
            "and put its folder on PYTHONPATH"
        )
    try:
        fn = getattr(importlib.import_module(module_name), func_name)
    except (ImportError, AttributeError) as exc:
        raise SurfaceLoadError(f"{source}: cannot import {target!r}: {exc}") from None
    if not callable(fn):
        raise SurfaceLoadError(f"{source}: {target!r} is not callable")
    return fn


def _check_test_output(
    parts: list[Any], expected: int, shape: tuple[int, ...], target: str, source: str
) -> None:
    """A plug-in's output on the load-time test grid: heights, or (heights, ∂f/∂x, ∂f/∂y) as a
    tuple (``expected`` arrays), each finite and of the grid's shape."""
    if len(parts) != expected:
        raise SurfaceLoadError(
            f"{source}: {target} returned {len(parts)} arrays; return heights, or (heights, df/dx, df/dy)"
        )
    for i, part in enumerate(parts):
        arr = np.asarray(part)
        if arr.shape != shape:
            raise SurfaceLoadError(
                f"{source}: {target} returned shape {arr.shape} for inputs of shape {shape}; it must "
                "return arrays of the shape of x and y"
            )
        if not np.all(np.isfinite(arr)):
            raise SurfaceLoadError(
                f"{source}: {target} returned non-finite values (output {i}) on the test grid"
            )


def load_plugin(
    target: str, params: dict[str, Any], aperture: Aperture, source: str, fd_step_um: float = 1e-3
) -> SurfaceFn:
    """The surface callable of ``module:function``, validated on a small grid."""
    fn = _import_function(target, source)

    def call(px: np.ndarray, py: np.ndarray) -> Any:
        try:
            return fn(px, py, **params)
        except Exception as exc:
            # user code: whatever it raises becomes this surface's failure, named
            raise SurfaceLoadError(f"{source} raised {type(exc).__name__}: {exc}") from None

    half = aperture.outer_radius_um
    g = np.linspace(-half, half, 7)
    gx, gy = np.meshgrid(g, g)
    try:
        out = fn(gx, gy, **params)
    except Exception as exc:
        raise SurfaceLoadError(
            f"{source}: {target} raised {type(exc).__name__}: {exc} on a test grid"
        ) from None
    with_slopes = isinstance(out, tuple)
    _check_test_output(list(out) if with_slopes else [out], 3 if with_slopes else 1, gx.shape, target, source)

    if with_slopes:

        def surface(px: np.ndarray, py: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            f, fx, fy = call(px, py)
            return np.asarray(f, float), np.asarray(fx, float), np.asarray(fy, float)
    else:

        def surface(px: np.ndarray, py: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            h = fd_step_um
            f = np.asarray(call(px, py), float)
            fx = (np.asarray(call(px + h, py), float) - np.asarray(call(px - h, py), float)) / (2 * h)
            fy = (np.asarray(call(px, py + h), float) - np.asarray(call(px, py - h), float)) / (2 * h)
            return f, fx, fy

    return surface


@functools.lru_cache(maxsize=8)
def _cached_surface(kind: str, spec_json: str, aperture_json: str, folder: str) -> SurfaceFn:
    params = json.loads(spec_json)
    aperture = Aperture(**json.loads(aperture_json))
    if kind == "height_map":
        path = Path(params["path"])
        if not path.is_absolute():
            path = Path(folder) / path
        x, y, z = read_grid(
            path,
            params.get("variable"),
            params["x_name"],
            params["y_name"],
            params.get("spacing_um"),
            params.get("origin_um"),
            params["scale_to_um"],
        )
        return height_map_surface(x, y, z, aperture, str(path))
    return load_plugin(
        params["function"], params.get("params", {}), aperture, f"plug-in {params['function']}"
    )


def build(kind: str, params: dict[str, Any], aperture: Aperture, folder: Path) -> SurfaceFn:
    """The (per-process cached) surface callable of a height_map or plugin entry."""
    return _cached_surface(
        kind, json.dumps(params, sort_keys=True), json.dumps(aperture._asdict()), str(folder)
    )
