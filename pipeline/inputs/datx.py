"""Zygo ``.datx`` height maps: an HDF5 file (read through h5py, the ``measure`` extra) whose
surface is a 2-D dataset under ``Data/Surface/<name>`` (Mx) or ``Measurement/Surface`` (NX2),
with its attributes:

- ``Unit``: the heights' unit (``NanoMeters``, ``MicroMeters``, ``MilliMeters``, ``Meters``,
  or ``Fringes``, then scaled by ``Wavelength`` [m] × ``Interferometric Scale Factor`` ×
  ``Obliquity Factor``);
- ``No Data``: the value at or above which a pixel was not measured (kept missing, NaN);
- ``X Converter``, ``Y Converter``: compound records whose ``Parameters`` (the third field
  where the fields carry no names) hold the lateral resolution [m/pixel] as their second
  value; a zero resolution (a file without a lateral calibration) must be stated.

Rows run along y from the top of the camera image (y decreasing), columns along x, as
Gwyddion's reader and prysm take them: the map is flipped so that y increases with the row.
The file is untrusted: its size is bounded before it is opened, the dataset's shape before
it is read, and only hard links inside the file are followed (an external link could name
any file on the machine).
"""

from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any, Optional

import numpy as np

MAX_PIXELS = 64 * 2**20
HEIGHT_UNITS = {"nanometers": 1e-3, "micrometers": 1.0, "millimeters": 1e3, "meters": 1e6}
PLACES = ("Data/Surface", "Measurement/Surface")


def read_datx(data: bytes, path: Path, pixel_um: Optional[float]) -> tuple[np.ndarray, float, str]:
    """The heights [µm] (NaN where not measured; y up the rows), the pixel [µm] and where the
    units were read from, of a .datx file's bytes ``data``; ``pixel_um`` stands in for a
    missing lateral calibration. A ValueError names what is wrong."""
    try:
        import h5py
    except ImportError:
        raise ValueError(f"{path}: reading .datx needs h5py: pip install 'ftsweep[measure]'") from None
    try:
        with h5py.File(io.BytesIO(data), "r") as f:
            surface = _surface(f, h5py, path)
            return _heights(surface, path, pixel_um)
    except OSError as exc:
        raise ValueError(f"{path}: not an HDF5 .datx file ({str(exc)[:200]})") from None


def _surface(f: Any, h5py: Any, path: Path) -> Any:
    """The surface dataset, reached through hard links only."""
    for place in PLACES:
        group_name, name = place.rsplit("/", 1)
        if group_name not in f or not isinstance(f.get(group_name, getlink=True), h5py.HardLink):
            continue
        group = f[group_name]
        if name not in group or not isinstance(group.get(name, getlink=True), h5py.HardLink):
            continue
        item = group[name]
        if isinstance(item, h5py.Dataset):
            return item
        for key in item:
            if isinstance(item.get(key, getlink=True), h5py.HardLink) and isinstance(item[key], h5py.Dataset):
                return item[key]
    raise ValueError(
        f"{path}: no surface in it (Data/Surface or Measurement/Surface, linked inside the file)"
    )


def _heights(surface: Any, path: Path, pixel_um: Optional[float]) -> tuple[np.ndarray, float, str]:
    if len(surface.shape) != 2 or surface.dtype.kind not in "iuf":
        raise ValueError(
            f"{path}: the surface is a 2-D array of numbers, got {surface.dtype} {surface.shape}"
        )
    if math.prod(surface.shape) > MAX_PIXELS:
        raise ValueError(f"{path}: {surface.shape} pixels, over the {MAX_PIXELS:,} a map may have")
    attrs = surface.attrs
    z = np.asarray(surface[()], dtype=float)
    no_data = _first(attrs.get("No Data"))
    if no_data is not None:
        z[z >= no_data] = np.nan
    z[~np.isfinite(z)] = np.nan
    unit = str(_text(attrs.get("Unit")) or "").strip()
    if unit.lower() == "fringes":
        keys = ("Wavelength", "Interferometric Scale Factor", "Obliquity Factor")
        factors = [
            v for v in (_first(attrs.get(k)) for k in keys) if v is not None and math.isfinite(v) and v > 0
        ]
        if len(factors) != len(keys):
            raise ValueError(f"{path}: heights in fringes need a wavelength, scale and obliquity factor")
        scale = 1e6 * math.prod(factors)
    elif unit.lower() in HEIGHT_UNITS:
        scale = HEIGHT_UNITS[unit.lower()]
    else:
        known = ", ".join(HEIGHT_UNITS)
        raise ValueError(f"{path}: height unit {unit[:40]!r} is none ftsweep knows ({known}, fringes)")
    pixel = _pixel(attrs, path, pixel_um)
    return np.flipud(z) * scale, pixel, f"{unit} (the file), pixel {pixel:g} µm"


def _pixel(attrs: Any, path: Path, pixel_um: Optional[float]) -> float:
    found = [_resolution(attrs.get(f"{axis} Converter")) for axis in ("X", "Y")]
    stated = [1e6 * v for v in found if v is not None and v > 0]
    if len(stated) == 2:
        if not math.isclose(stated[0], stated[1], rel_tol=1e-6):
            raise ValueError(
                f"{path}: pixels of {stated[0]:g} × {stated[1]:g} µm; ftsweep reads square pixels"
            )
        return stated[0]
    if pixel_um is None or not pixel_um > 0:
        raise ValueError(f"{path}: the file states no lateral resolution: give --pixel-um")
    return float(pixel_um)


def _resolution(converter: Any) -> Optional[float]:
    """The lateral resolution [m/pixel] of an X or Y converter record, or None."""
    if converter is None:
        return None
    record = np.asarray(converter).ravel()
    if record.size == 0:
        return None
    first = record[0]
    names = getattr(first.dtype, "names", None) if hasattr(first, "dtype") else None
    try:
        parameters = first["Parameters"] if names and "Parameters" in names else first[2]
        value = float(np.asarray(parameters, dtype=float).ravel()[1])
    except (IndexError, KeyError, TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def _first(value: Any) -> Optional[float]:
    if value is None:
        return None
    try:
        return float(np.asarray(value, dtype=float).ravel()[0])
    except (IndexError, TypeError, ValueError):
        return None


def _text(value: Any) -> Optional[str]:
    if value is None:
        return None
    first = np.asarray(value).ravel()[0] if np.asarray(value).size else ""
    return first.decode("utf-8", errors="replace") if isinstance(first, bytes) else str(first)
