"""The default resolution is converged (P-V moves < 3 % when the angular samples are
quadrupled and the evaluation points per feed doubled). Slow: about two minutes.

Run with: pytest -m slow
"""

from __future__ import annotations

import pytest

from ftsweep.engine.case import Case, Resolution, program_request
from ftsweep.inputs import catalogs
from ftsweep.simulate import run_case

REFERENCES = catalogs.entries("references")


@pytest.mark.slow
@pytest.mark.parametrize("name", list(REFERENCES))
def test_default_resolution_is_converged(name):
    ref = REFERENCES[name]
    layout = program_request(kind=ref.layout, pitch=ref.pitch)
    default = Resolution()
    fine = Resolution(
        samples_per_cell=4 * default.samples_per_cell, points_per_feed=2 * default.points_per_feed
    )
    coarse_pv = run_case(Case(surface=ref.surface, layout=layout, resolution=default))["pv_nm"]
    fine_pv = run_case(Case(surface=ref.surface, layout=layout, resolution=fine))["pv_nm"]
    assert abs(fine_pv - coarse_pv) < 0.03 * fine_pv, (coarse_pv, fine_pv)
