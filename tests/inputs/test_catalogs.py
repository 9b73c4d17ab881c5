"""Catalog validation: unknown keys, missing keys and bad values name the file and key."""

from __future__ import annotations

import pytest

from ftsweep.inputs import catalogs
from ftsweep.inputs.catalogs import CatalogError, Cutting, Machine, SurfaceSpec, load_catalog


def write(tmp_path, text):
    p = tmp_path / "cat.yaml"
    p.write_text(text)
    return p


def test_shipped_catalogs_load():
    assert {"sinewave2d", "lens_array"} <= set(catalogs.entries("surfaces"))
    m = catalogs.entry("machines", "fts-1m")
    assert m.capacity_points == 1_000_000 and m.command_rate_hz == 20_000
    assert m.travel_um == 5000 and m.peak_accel_m_s2 == 400 and m.continuous_accel_m_s2 == 250
    assert m.bandwidth_hz == 440 and m.bandwidth_amplitude_um == 100
    c = catalogs.entry("cutting", "reference")
    assert (c.feed_um, c.nose_radius_um, c.spindle_rpm) == (1.0, 83.0, 50.0)


def test_unknown_surface_param_names_file_entry_key_and_allowed(tmp_path):
    p = write(
        tmp_path,
        """
s1:
  family: sinewave2d
  layout: ring
  aperture: {shape: circle, radius_um: 10}
  params: {amplitude_x_um: 1, amplitude_y_um: 1, wavelength_x_um: 5, wavelength_y_um: 5, amplitude_z_um: 3}
""",
    )
    with pytest.raises(CatalogError) as err:
        load_catalog(p, SurfaceSpec)
    msg = str(err.value)
    assert str(p) in msg and "s1" in msg and "amplitude_z_um" in msg and "unknown key" in msg
    assert "wavelength_x_um" in msg  # lists what is allowed


def test_unknown_top_level_key_and_family(tmp_path):
    p = write(tmp_path, "m:\n  capacity_points: 10\n  colour: red\n")
    with pytest.raises(CatalogError, match="colour: unknown key"):
        load_catalog(p, Machine)
    p = write(
        tmp_path,
        "s:\n  family: nurbs\n  layout: ring\n  aperture: {shape: circle, radius_um: 1}\n  params: {}\n",
    )
    with pytest.raises(CatalogError, match="sinewave2d"):  # names the allowed families
        load_catalog(p, SurfaceSpec)


def test_missing_and_non_positive_values(tmp_path):
    p = write(tmp_path, "c:\n  feed_um: 0\n  nose_radius_um: 83\n")
    with pytest.raises(CatalogError) as err:
        load_catalog(p, Cutting)
    msg = str(err.value)
    assert "c.feed_um" in msg and "greater than 0" in msg
    assert "c.spindle_rpm: required key is missing" in msg


def test_cutting_entry_rules_are_checked_at_load_time(tmp_path):
    p = write(tmp_path, "c:\n  feed_um: 200\n  nose_radius_um: 83\n  spindle_rpm: 50\n")
    with pytest.raises(CatalogError, match=r"(?s)c\b.*not below twice the nose radius \(166 µm\)"):
        load_catalog(p, Cutting)
    p = write(tmp_path, "c:\n  feed_um: .nan\n  nose_radius_um: 83\n  spindle_rpm: .inf\n")
    with pytest.raises(CatalogError) as err:
        load_catalog(p, Cutting)
    assert "c.feed_um" in str(err.value) and "c.spindle_rpm" in str(err.value)


def test_unknown_aperture_key(tmp_path):
    p = write(
        tmp_path,
        """
s:
  family: lens_array
  layout: mesh
  aperture: {shape: rectangle, width_um: 10, height_um: 10, radius_um: 3}
  params: {radius_um: 252.5, sag_um: 5, pitch_um: 150, count_x: 1, count_y: 1}
""",
    )
    with pytest.raises(CatalogError, match=r"radius_um: unknown key \(allowed: shape, width_um, height_um\)"):
        load_catalog(p, SurfaceSpec)


def test_missing_file_and_bad_yaml(tmp_path):
    with pytest.raises(CatalogError, match="does not exist"):
        load_catalog(tmp_path / "none.yaml", Machine)
    with pytest.raises(CatalogError, match="not valid YAML"):
        load_catalog(write(tmp_path, "a: [1, 2\n"), Machine)
