"""Measured parts read as they come (ftsweep.inputs.measurements): point clouds in stated
units, .npy and NetCDF height maps, ISO 25178-72 X3P; missing heights stay missing; a
malformed or hostile file is refused with a line naming the file and what is wrong."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from ftsweep.inputs import measurements
from ftsweep.inputs.measurements import MeasurementError, read_measurement


def _x3p(
    path: Path, z_m: np.ndarray, pitch_m: float, valid: np.ndarray | None = None, xml_extra: str = ""
) -> Path:
    """A minimal X3P: main.xml with the axes, the matrix size and the data link."""
    ny, nx = z_m.shape
    valid_link = "<ValidPointsLink>bin/valid.bin</ValidPointsLink>" if valid is not None else ""
    xml = f"""<?xml version="1.0" encoding="UTF-8"?>{xml_extra}
<p:ISO5436_2 xmlns:p="http://www.opengps.eu/2008/ISO5436_2"><Record1><Revision>ISO5436 - 2000</Revision>
<FeatureType>SUR</FeatureType><Axes>
<CX><AxisType>I</AxisType><DataType>D</DataType><Increment>{pitch_m!r}</Increment><Offset>-0.001</Offset></CX>
<CY><AxisType>I</AxisType><DataType>D</DataType><Increment>{pitch_m!r}</Increment><Offset>-0.001</Offset></CY>
<CZ><AxisType>A</AxisType><DataType>D</DataType></CZ></Axes></Record1>
<Record3><MatrixDimension><SizeX>{nx}</SizeX><SizeY>{ny}</SizeY><SizeZ>1</SizeZ></MatrixDimension>
<DataLink><PointDataLink>bin/data.bin</PointDataLink>{valid_link}</DataLink></Record3></p:ISO5436_2>"""
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("main.xml", xml)
        zf.writestr("bin/data.bin", z_m.astype("<f8").tobytes())
        if valid is not None:
            zf.writestr(
                "bin/valid.bin", np.packbits(valid.ravel().astype(np.uint8), bitorder="little").tobytes()
            )
    return path


def test_a_point_cloud_in_millimetres_reads_in_micrometres_with_its_gaps(tmp_path):
    path = tmp_path / "part.csv"
    path.write_text("# units: mm\nx,y,z\n0.5,0.25,0.001\n-0.5,0,nan\n1.0,1.0,\n")
    m = read_measurement(path)
    assert m.x.tolist() == [500.0, -500.0, 1000.0] and m.y.tolist() == [250.0, 0.0, 1000.0]
    assert m.z[0] == pytest.approx(1.0) and np.isnan(m.z[1:]).all()
    assert m.units == "mm (the file)" and len(m.sha256) == 64


@pytest.mark.parametrize(
    "text, units, says",
    [
        ("1 2 3\n", None, "state the units"),
        ("# units: mm\n1 2 3\n", "um", "the file says units mm, the command um"),
        ("# units: um\n1 2 3\n1 2 3 4\n", None, "line 3: 4 values"),
        ("# units: um\n1 2 3\n1 x 3\n", None, "line 3: '1 x 3' are not three numbers"),
        ("# units: um\nnan 2 3\n", None, "needs a finite x and y"),
        ("# units: furlong\n1 2 3\n", None, "unknown unit 'furlong'"),
        ("# units: um\n1 2 nan\n", None, "no measured height"),
    ],
)
def test_a_malformed_point_cloud_is_refused_naming_what_is_wrong(tmp_path, text, units, says):
    path = tmp_path / "bad.xyz"
    path.write_text(text)
    with pytest.raises(MeasurementError, match=says):
        read_measurement(path, units=units)


def test_a_file_over_the_size_bound_is_refused_before_it_is_read(tmp_path, monkeypatch):
    path = tmp_path / "big.csv"
    path.write_text("# units: um\n" + "1 2 3\n" * 100)
    monkeypatch.setattr(measurements, "MAX_BYTES", 100)
    monkeypatch.setattr(Path, "read_bytes", lambda self: pytest.fail("read"))
    with pytest.raises(MeasurementError, match="over the 100 a measurement may have"):
        read_measurement(path)


def test_an_npy_map_needs_its_pixel_and_units_and_refuses_pickles(tmp_path):
    z = np.arange(12.0).reshape(3, 4)
    np.save(tmp_path / "m.npy", z)
    with pytest.raises(MeasurementError, match="--pixel-um"):
        read_measurement(tmp_path / "m.npy")
    m = read_measurement(tmp_path / "m.npy", units="nm", pixel_um=10.0)
    assert m.z.shape == (3, 4) and m.z[2, 3] == pytest.approx(0.011)
    assert m.x[0].tolist() == [-15.0, -5.0, 5.0, 15.0] and m.y[:, 0].tolist() == [-10.0, 0.0, 10.0]
    np.save(tmp_path / "o.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(MeasurementError, match="not a numeric .npy array"):
        read_measurement(tmp_path / "o.npy", units="um", pixel_um=1.0)


def test_a_netcdf_map_takes_its_coordinates_units(tmp_path):
    ds = xr.Dataset(
        {"height": (("y", "x"), np.array([[1.0, np.nan], [3.0, 4.0]]), {"units": "nm"})},
        coords={"x": ("x", [0.0, 0.1], {"units": "mm"}), "y": ("y", [0.0, 0.2], {"units": "mm"})},
    )
    ds.to_netcdf(tmp_path / "m.nc")
    m = read_measurement(tmp_path / "m.nc")
    assert m.x[0].tolist() == [0.0, 100.0] and m.y[:, 0].tolist() == [0.0, 200.0]
    assert m.z[1, 1] == pytest.approx(0.004) and np.isnan(m.z[0, 1])


def test_an_x3p_map_reads_in_micrometres_with_its_invalid_points_missing(tmp_path):
    z = np.linspace(0.0, 1e-6, 12).reshape(3, 4)  # metres
    valid = np.ones((3, 4), bool)
    valid[1, 2] = False
    m = read_measurement(_x3p(tmp_path / "m.x3p", z, 2e-6, valid))
    assert m.z.shape == (3, 4) and m.z[2, 3] == pytest.approx(1.0) and np.isnan(m.z[1, 2])
    assert np.isfinite(m.z).sum() == 11
    assert m.x[0, :2] == pytest.approx([-1000.0, -998.0]) and m.y[1, 0] == pytest.approx(-998.0)


def test_a_hostile_x3p_is_refused(tmp_path):
    z = np.zeros((2, 2))
    entity = '<!DOCTYPE r [<!ENTITY a "aaaa">]>'
    with pytest.raises(MeasurementError, match="DOCTYPE or entities"):
        read_measurement(_x3p(tmp_path / "e.x3p", z, 1e-6, xml_extra=entity))
    short = tmp_path / "s.x3p"
    _x3p(short, z, 1e-6)
    data = tmp_path / "t.x3p"  # its main.xml, with a data member too short for its points
    with zipfile.ZipFile(short) as src, zipfile.ZipFile(data, "w") as dst:
        dst.writestr("main.xml", src.read("main.xml"))
        dst.writestr("bin/data.bin", b"\0" * 8)
    with pytest.raises(MeasurementError, match="holds 8 bytes, 2 × 2 points need 32"):
        read_measurement(data)
    (tmp_path / "n.x3p").write_bytes(b"not a zip")
    with pytest.raises(MeasurementError, match="not one"):
        read_measurement(tmp_path / "n.x3p")


def test_only_the_first_line_of_values_may_be_a_header(tmp_path):
    path = tmp_path / "two.csv"
    path.write_text("# units: um\nx,y,z\nx,y,z\n1,2,3\n")
    with pytest.raises(MeasurementError, match="line 3: 'x y z' are not three numbers"):
        read_measurement(path)


def _datx(
    path: Path, z: np.ndarray, unit: str, pixel_m: float, no_data: float = 1e38, place: str = "Mx"
) -> Path:
    """A .datx as Zygo's software lays it out: the surface under Data/Surface/<name> (Mx) or
    Measurement/Surface (NX2), its unit, no-data value and X/Y converters (compound records
    whose third field holds the lateral resolution [m] as its second value)."""
    h5py = pytest.importorskip("h5py")
    text = h5py.string_dtype()
    converter = np.dtype(
        [("Category", text), ("BaseUnit", text), ("Parameters", h5py.vlen_dtype(np.float64))]
    )
    with h5py.File(path, "w") as f:
        name = "Data/Surface/{00000000-0000}" if place == "Mx" else "Measurement/Surface"
        surface = f.create_dataset(name, data=z)
        for axis in ("X", "Y"):
            record = np.empty(1, dtype=converter)
            record[0] = ("LateralCat", "Pixels", np.array([0.0, pixel_m, 0.0, 0.0]))
            surface.attrs[f"{axis} Converter"] = record
        surface.attrs["Unit"] = np.array([unit], dtype=text)
        surface.attrs["No Data"] = np.array([no_data])
        surface.attrs["Wavelength"] = np.array([632.8e-9])
        surface.attrs["Interferometric Scale Factor"] = np.array([0.5])
        surface.attrs["Obliquity Factor"] = np.array([1.0])
    return path


@pytest.mark.parametrize("place", ["Mx", "NX2"])
def test_a_datx_map_reads_in_micrometres_with_its_no_data_pixels_missing(tmp_path, place):
    z = np.arange(12, dtype=float).reshape(3, 4) * 10.0  # nm; row 0 is the image's top
    z[0, 0] = 1e38
    m = read_measurement(_datx(tmp_path / "part.datx", z, "NanoMeters", 5e-6, place=place))
    assert m.x.shape == (3, 4) and np.allclose(np.diff(m.x[0]), 5.0) and np.allclose(np.diff(m.y[:, 0]), 5.0)
    assert np.isnan(m.z[-1, 0]) and m.z[0, 0] == pytest.approx(0.08)  # flipped: y up the rows
    assert np.isfinite(m.z).sum() == 11 and "NanoMeters" in m.units


def test_a_datx_in_fringes_is_scaled_by_its_wavelength_and_factors(tmp_path):
    m = read_measurement(_datx(tmp_path / "f.datx", np.full((2, 2), 0.1), "Fringes", 1e-5))
    assert np.allclose(m.z, 0.1 * 632.8e-3 * 0.5)  # µm


def test_a_datx_without_lateral_calibration_needs_the_pixel(tmp_path):
    path = _datx(tmp_path / "nocal.datx", np.zeros((2, 2)), "MicroMeters", 0.0)
    with pytest.raises(MeasurementError, match="no lateral resolution: give --pixel-um"):
        read_measurement(path)
    assert np.allclose(np.diff(read_measurement(path, pixel_um=2.0).x[0]), 2.0)


def test_a_hostile_datx_is_refused(tmp_path):
    h5py = pytest.importorskip("h5py")
    outside = _datx(tmp_path / "elsewhere.datx", np.zeros((2, 2)), "MicroMeters", 1e-6)
    linked = tmp_path / "linked.datx"
    with h5py.File(linked, "w") as f:
        f["Measurement/Surface"] = h5py.ExternalLink(str(outside), "/Data/Surface/{00000000-0000}")
    with pytest.raises(MeasurementError, match="linked inside the file"):
        read_measurement(linked)
    (tmp_path / "text.datx").write_text("not HDF5")
    with pytest.raises(MeasurementError, match="not an HDF5 .datx file"):
        read_measurement(tmp_path / "text.datx")
    odd = _datx(tmp_path / "odd.datx", np.zeros((2, 2)), "Furlongs", 1e-6)
    with pytest.raises(MeasurementError, match="height unit 'Furlongs'"):
        read_measurement(odd)
