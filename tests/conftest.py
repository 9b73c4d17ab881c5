"""Shared fixtures: a private copy of the catalogs with extra test surfaces."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from hypothesis import settings

# the tests open cubes with xarray's own zarr engine too, where ftsweep's backend entry point
# is not looked for: the accessor is registered outright (ftsweep.tools.xarray_backend)
import ftsweep.tools.accessor  # noqa: F401, E402

# numba compiles on a kernel's first call (or loads it from cache); that one-off cost is not
# what a property test measures, so examples get no deadline.
settings.register_profile("ftsweep", deadline=None, max_examples=60)
# HYPOTHESIS_PROFILE=thorough: thousands of fresh examples (the byte-mutation properties of
# exported files draw the same ones every run otherwise, so CI never fails by the draw)
settings.register_profile("thorough", deadline=None, max_examples=2000)
THOROUGH = os.environ.get("HYPOTHESIS_PROFILE") == "thorough"
settings.load_profile("thorough" if THOROUGH else "ftsweep")

REPO = Path(__file__).resolve().parent.parent

EXTRA_SURFACES = """
flat:
  description: A plane (sinewave2d of zero amplitude); machines to pure feed cusps.
  family: sinewave2d
  layout: ring
  aperture: {shape: circle, radius_um: 300.0}
  params: {amplitude_x_um: 0.0, amplitude_y_um: 0.0, wavelength_x_um: 100.0, wavelength_y_um: 100.0}
small_sine:
  description: A small sinewave part for fast end-to-end tests.
  family: sinewave2d
  layout: ring
  aperture: {shape: circle, radius_um: 300.0}
  params: {amplitude_x_um: 0.5, amplitude_y_um: 0.5, wavelength_x_um: 100.0, wavelength_y_um: 100.0,
           phase_x_deg: 90.0, phase_y_deg: 90.0}
small_lens:
  description: A 3 x 3 lens array for fast end-to-end tests.
  family: lens_array
  layout: mesh
  aperture: {shape: rectangle, width_um: 450.0, height_um: 450.0}
  params: {radius_um: 252.5, sag_um: 5.0, pitch_um: 150.0, count_x: 3, count_y: 3}
"""


EXTRA_MACHINES = """
sluggish-fts:
  description: An FTS with a 1 Hz bandwidth, so every layout is infeasible (for tests).
  capacity_points: 1000000
  command_rate_hz: 20000.0
  travel_um: 5000.0
  peak_accel_m_s2: 400.0
  continuous_accel_m_s2: 250.0
  bandwidth_hz: 1.0
  bandwidth_amplitude_um: 100.0
short-fts:
  description: A 0.8 µm stroke, shorter than small_sine's 2 µm span, so it is cut in layers (for tests).
  capacity_points: 1000000
  command_rate_hz: 20000.0
  travel_um: 0.8
  peak_accel_m_s2: 400.0
  continuous_accel_m_s2: 250.0
  bandwidth_hz: 440.0
  bandwidth_amplitude_um: 0.8
  layer_margin_um: 0.1
  layer_change_s: 1.0
tiny-fts:
  description: A controller holding only 30,000 points (for tests).
  capacity_points: 30000
  command_rate_hz: 20000.0
  travel_um: 5000.0
  peak_accel_m_s2: 400.0
  continuous_accel_m_s2: 250.0
  bandwidth_hz: 440.0
  bandwidth_amplitude_um: 100.0
"""


def make_catalog_dir(folder: Path) -> Path:
    """Copy catalogs/ to ``folder`` with the extra test surfaces and machines appended."""
    shutil.copytree(REPO / "catalogs", folder)
    with (folder / "surfaces.yaml").open("a") as fh:
        fh.write(EXTRA_SURFACES)
    with (folder / "machines.yaml").open("a") as fh:
        fh.write(EXTRA_MACHINES)
    return folder


@pytest.fixture()
def catalog_dir(tmp_path: Path) -> Path:
    """A copy of catalogs/ with the extra test surfaces and machines appended."""
    return make_catalog_dir(tmp_path / "catalogs")


@pytest.fixture(scope="module")
def module_catalog_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """:func:`catalog_dir` shared by the tests of one module (they must not edit it)."""
    return make_catalog_dir(tmp_path_factory.mktemp("catalogs") / "catalogs")
