"""The tests' catalogs: a copy of catalogs/ with small surfaces and short or sluggish machines
appended, so that a case of every kind runs in seconds."""

from __future__ import annotations

import shutil
from pathlib import Path

from support.places import REPO

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
