"""Measured parts read as they come from the instrument: point clouds (x y z text, stated units),
gridded height maps (.npy with a stated pixel and units, NetCDF with its coordinates' units,
ISO 25178-72 X3P). Every file is untrusted data: its size is bounded before it is read, no
object array or code is loaded, and a missing height (NaN, an X3P point marked invalid) stays
missing.

Everything is returned in µm: lateral positions x, y and heights z.
"""

from __future__ import annotations

import hashlib
import re
import zipfile
from pathlib import Path
from typing import NamedTuple, Optional
from xml.etree import ElementTree

import numpy as np

# the largest measurement file read [bytes]: a 4k × 4k map of doubles is 128 MiB
MAX_BYTES = 512 * 2**20
# the largest main.xml of an X3P [bytes]: its metadata, never its data
MAX_XML_BYTES = 2**20
UNITS = {"nm": 1e-3, "um": 1.0, "µm": 1.0, "mm": 1e3, "m": 1e6}
_UNITS_LINE = re.compile(r"^#\s*units\s*[:=]\s*(\S+)\s*$", re.I)
_X3P_TYPES = {"D": "<f8", "F": "<f4", "L": "<i4", "I": "<i2"}


class MeasurementError(ValueError):
    """A measurement cannot be read; the message names the file and what is wrong."""


class Measurement(NamedTuple):
    """Measured heights ``z`` [µm] at ``x``, ``y`` [µm] (arrays of one shape: (ny, nx) for a
    grid, (n,) for a point cloud; NaN where nothing was measured), the file's SHA-256 and
    what its units were read from."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    sha256: str
    units: str


def _scale(unit: str, path: Path) -> float:
    try:
        return UNITS[unit.strip().lower().replace("micron", "um")]
    except KeyError:
        raise MeasurementError(f"{path}: unknown unit {unit!r} (one of {', '.join(UNITS)})") from None


def _bounded(path: Path) -> bytes:
    if not path.is_file():
        raise MeasurementError(f"measurement file {path} does not exist")
    size = path.stat().st_size
    if size > MAX_BYTES:
        raise MeasurementError(f"{path}: {size:,} bytes, over the {MAX_BYTES:,} a measurement may have")
    return path.read_bytes()


def read_measurement(
    path: Path, units: Optional[str] = None, pixel_um: Optional[float] = None
) -> Measurement:
    """The measurement in ``path``, by its suffix: .csv .txt .xyz (a point cloud; ``units`` or
    a ``# units: um`` line states its unit), .npy (a grid; ``pixel_um`` and ``units`` state
    its pitch and height unit), .nc (a grid whose coordinates x, y and variable carry units),
    .x3p (ISO 25178-72, metres), .datx (Zygo's HDF5, :mod:`ftsweep.inputs.datx`; ``pixel_um``
    where it states no lateral resolution)."""
    data = _bounded(path)
    digest = hashlib.sha256(data).hexdigest()
    suffix = path.suffix.lower()
    if suffix in (".csv", ".txt", ".xyz"):
        x, y, z, said = _point_cloud(data, path, units)
    elif suffix == ".npy":
        x, y, z, said = _npy(path, units, pixel_um)
    elif suffix == ".nc":
        x, y, z, said = _netcdf(path)
    elif suffix == ".x3p":
        x, y, z, said = _x3p(data, path)
    elif suffix == ".datx":
        x, y, z, said = _datx(data, path, pixel_um)
    else:
        raise MeasurementError(
            f"{path}: not a measurement ftsweep reads (.csv .txt .xyz .npy .nc .x3p .datx)"
        )
    if not np.isfinite(z).any():
        raise MeasurementError(f"{path}: no measured height in it")
    return Measurement(x, y, z, digest, said)


def _point_cloud(
    data: bytes, path: Path, units: Optional[str]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """x y z rows, separated by commas or blanks; comments (#) and one header line of names
    allowed; an empty or 'nan' z is a missing height."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise MeasurementError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    stated: Optional[str] = None
    rows: list[tuple[float, float, float]] = []
    first = True
    for number, line in enumerate(text.splitlines(), start=1):
        if m := _UNITS_LINE.match(line.strip()):
            stated = m.group(1)
            continue
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        fields = [f.strip() for f in re.split(r"[,\s;]+", line)]
        if first and not _number(fields[0]):
            first = False
            continue  # the header of column names, on the first line of values only
        first = False
        rows.append(_row(fields, number, path))
    if units and stated and _scale(units, path) != _scale(stated, path):
        raise MeasurementError(f"{path}: the file says units {stated}, the command {units}")
    unit = units or stated
    if unit is None:
        raise MeasurementError(f"{path}: state the units (a '# units: um' line, or --units)")
    if not rows:
        raise MeasurementError(f"{path}: no x y z row in it")
    xyz = np.array(rows) * _scale(unit, path)
    return xyz[:, 0], xyz[:, 1], xyz[:, 2], f"{unit} ({'the file' if stated else 'stated'})"


def _number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _row(fields: list[str], number: int, path: Path) -> tuple[float, float, float]:
    if len(fields) == 2:
        fields = [*fields, "nan"]
    if len(fields) != 3:
        raise MeasurementError(f"{path} line {number}: {len(fields)} values, an x y z row has 3")
    try:
        x, y, z = (float(f) if f else np.nan for f in fields)
    except ValueError:
        raise MeasurementError(f"{path} line {number}: {' '.join(fields)!r} are not three numbers") from None
    if not (np.isfinite(x) and np.isfinite(y)):
        raise MeasurementError(f"{path} line {number}: a measured point needs a finite x and y")
    return x, y, z


def _grid_axes(
    nx: int, ny: int, pitch: tuple[float, float], origin: tuple[float, float]
) -> tuple[np.ndarray, np.ndarray]:
    xs = origin[0] + pitch[0] * np.arange(nx)
    ys = origin[1] + pitch[1] * np.arange(ny)
    x, y = np.meshgrid(xs, ys)
    return x, y


def _centred(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A grid without a stated origin is centred on its middle."""
    return x - 0.5 * (x.min() + x.max()), y - 0.5 * (y.min() + y.max())


def _npy(
    path: Path, units: Optional[str], pixel_um: Optional[float]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    if units is None or pixel_um is None or not pixel_um > 0:
        raise MeasurementError(
            f"{path}: a .npy height map needs its height unit and pixel (--units, --pixel-um)"
        )
    try:
        z = np.load(path, allow_pickle=False)  # data, never code
    except ValueError as exc:
        raise MeasurementError(f"{path}: not a numeric .npy array ({exc})") from None
    if z.dtype.kind not in "iuf" or z.ndim != 2:
        raise MeasurementError(f"{path}: a height map is a 2-D array of numbers, got {z.dtype} {z.shape}")
    ny, nx = z.shape
    x, y = _centred(*_grid_axes(nx, ny, (pixel_um, pixel_um), (0.0, 0.0)))
    return x, y, z.astype(float) * _scale(units, path), f"{units} (stated), pixel {pixel_um} µm"


def _datx(
    data: bytes, path: Path, pixel_um: Optional[float]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    from ftsweep.inputs.datx import read_datx

    try:
        z, pixel, said = read_datx(data, path, pixel_um)
    except ValueError as exc:
        raise MeasurementError(str(exc)) from None
    ny, nx = z.shape
    x, y = _centred(*_grid_axes(nx, ny, (pixel, pixel), (0.0, 0.0)))
    return x, y, z, said


def _netcdf(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    import xarray as xr

    try:
        with xr.open_dataset(path) as ds:
            names = [v for v in ds.data_vars if ds[v].ndim == 2]
            if len(names) != 1:
                raise MeasurementError(f"{path}: one 2-D height variable expected, found {names}")
            z = ds[names[0]]
            ydim, xdim = z.dims
            scale = {d: _scale(str(ds[d].attrs.get("units", "")), path) for d in (ydim, xdim)}
            x, y = np.meshgrid(ds[xdim].values * scale[xdim], ds[ydim].values * scale[ydim])
            hs = _scale(str(z.attrs.get("units", "")), path)
            return x, y, z.values.astype(float) * hs, f"{z.attrs.get('units')} (the file)"
    except (OSError, ValueError, KeyError) as exc:
        if isinstance(exc, MeasurementError):
            raise
        raise MeasurementError(f"{path}: not a NetCDF height map ({exc})") from None


def _x3p(data: bytes, path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """ISO 25178-72: a zip of main.xml (axes: increments and offsets in metres, the data type
    of CZ, the matrix size) and the binary points (x fastest), an optional bit mask of valid
    points (1 = valid, least significant bit first)."""
    import io

    try:
        archive = zipfile.ZipFile(io.BytesIO(data))
    except zipfile.BadZipFile:
        raise MeasurementError(f"{path}: an X3P file is a zip archive; this is not one") from None
    sizes = {i.filename: i.file_size for i in archive.infolist()}
    if sizes.get("main.xml", MAX_XML_BYTES + 1) > MAX_XML_BYTES:
        raise MeasurementError(f"{path}: no main.xml, or one over {MAX_XML_BYTES:,} bytes")
    xml = archive.read("main.xml")
    if b"<!DOCTYPE" in xml or b"<!ENTITY" in xml:
        raise MeasurementError(f"{path}: main.xml declares a DOCTYPE or entities, which X3P has no use for")
    try:
        root = ElementTree.fromstring(xml)
    except ElementTree.ParseError as exc:
        raise MeasurementError(f"{path}: main.xml is not XML ({exc})") from None
    axes = {name: _axis(root, name, path) for name in ("CX", "CY", "CZ")}
    nx, ny = (_integer(root, f".//MatrixDimension/{n}", path) for n in ("SizeX", "SizeY"))
    link = _text(root, ".//DataLink/PointDataLink", path)
    kind = axes["CZ"][2]
    count = nx * ny * np.dtype(_X3P_TYPES[kind]).itemsize
    if sizes.get(link) != count:
        raise MeasurementError(
            f"{path}: {link} holds {sizes.get(link)} bytes, {nx} × {ny} points need {count}"
        )
    z = np.frombuffer(archive.read(link), dtype=_X3P_TYPES[kind]).astype(float).reshape(ny, nx)
    z = z * axes["CZ"][0] + axes["CZ"][1] if kind in "LI" else z
    valid = root.find(".//ValidPointsLink")
    if valid is not None and valid.text:
        bits = archive.read(valid.text.strip())
        if len(bits) * 8 < nx * ny:
            raise MeasurementError(f"{path}: its valid-points mask is shorter than its {nx * ny} points")
        mask = np.unpackbits(np.frombuffer(bits, np.uint8), bitorder="little")[: nx * ny].reshape(ny, nx)
        z[mask == 0] = np.nan
    x, y = _grid_axes(nx, ny, (axes["CX"][0], axes["CY"][0]), (axes["CX"][1], axes["CY"][1]))
    return x * 1e6, y * 1e6, z * 1e6, "m (ISO 25178-72)"


def _text(root: ElementTree.Element, where: str, path: Path) -> str:
    found = root.find(where)
    if found is None or not (found.text or "").strip():
        raise MeasurementError(f"{path}: main.xml has no {where.strip('./')}")
    return (found.text or "").strip()


def _integer(root: ElementTree.Element, where: str, path: Path) -> int:
    text = _text(root, where, path)
    if not text.isdigit() or not 0 < int(text) <= 2**15:
        raise MeasurementError(f"{path}: {where.strip('./')} = {text!r}, not a size from 1 to 32768")
    return int(text)


def _axis(root: ElementTree.Element, name: str, path: Path) -> tuple[float, float, str]:
    """(increment [m], offset [m], data type) of axis ``name`` of Record1."""
    kind = (root.findtext(f".//Axes/{name}/DataType") or "D").strip()
    if name == "CZ" and kind not in _X3P_TYPES:
        raise MeasurementError(f"{path}: CZ data type {kind!r} (one of {', '.join(_X3P_TYPES)})")
    inc = float(root.findtext(f".//Axes/{name}/Increment") or ("1" if name == "CZ" else "nan"))
    off = float(root.findtext(f".//Axes/{name}/Offset") or "0")
    if not (np.isfinite(inc) and inc > 0 and np.isfinite(off)):
        raise MeasurementError(f"{path}: axis {name} needs a positive increment in metres")
    return inc, off, kind
