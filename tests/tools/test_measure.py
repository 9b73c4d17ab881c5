"""A measured part registered to its catalog design (ftsweep.tools.measure), on two surfaces
of the catalog: the Zernike freeform over its circle and the concave sphere over its square,
each measured as a point cloud moved by known set-up terms with a known form error."""

from __future__ import annotations

import numpy as np
import pytest

from ftsweep.inputs import catalogs
from ftsweep.stages.measurement import zernike_basis
from ftsweep.tools.measure import measure_part


def _cloud(path, surface, half_um, shift, form, noise_um=0.001, n=81):
    """A point cloud in mm of ``surface`` moved by ``shift`` (dx, dy [µm], piston [µm]) plus
    ``form(x, y)`` [µm], noise and 5 % dropouts."""
    design = catalogs.surface_callable(catalogs.entry("surfaces", surface))
    x, y = (a.ravel() for a in np.meshgrid(*(np.linspace(-half_um, half_um, n),) * 2))
    dx, dy, piston = shift
    rng = np.random.default_rng(3)
    z = design(x - dx, y - dy)[0] + piston + form(x, y) + rng.normal(0, noise_um, x.size)
    z[rng.random(x.size) < 0.05] = np.nan
    rows = "\n".join(f"{a / 1e3:.9g},{b / 1e3:.9g},{c / 1e3:.12g}" for a, b, c in zip(x, y, z, strict=True))
    path.write_text("# units: mm\nx,y,z\n" + rows + "\n")
    return path


def test_the_freeform_is_registered_and_its_injected_coma_found(tmp_path):
    def trefoil(x, y):
        return 0.04 * zernike_basis(x, y, 1000.0, 9)[:, 8]

    path = _cloud(tmp_path / "ff.csv", "zernike_example", 1000.0, (2.0, -1.0, 0.2), trefoil)
    part = measure_part(path, "zernike_example", rotation=True)
    s = part.summary
    assert abs(s["terms"]["decentre_x_um"] - 2.0) <= 4 * s["sigma"]["decentre_x_um"]
    assert abs(s["terms"]["decentre_y_um"] + 1.0) <= 4 * s["sigma"]["decentre_y_um"]
    z9 = next(t["nm"] for t in s["breakdown"] if t["term"].startswith("Z9 "))
    assert z9 == pytest.approx(40.0, abs=3.0) and len(s["sha256"]) == 64
    assert s["rms_nm"] == pytest.approx(40.0, rel=0.1)  # the trefoil's unit-RMS term, and noise


def test_the_sphere_is_registered_over_its_square_with_a_chebyshev_breakdown(tmp_path):
    def saddle(x, y):
        return 0.05 * (2 * x / 20000.0) * (2 * y / 20000.0)  # T1(u)·T1(v), 50 nm

    path = _cloud(tmp_path / "sp.csv", "concave_sphere", 10000.0, (0.0, 0.0, -0.1), saddle)
    part = measure_part(path, "concave_sphere", decentre=False, power=True)
    s = part.summary
    cheb = {t["term"]: t["nm"] for t in s["breakdown"]}
    assert cheb["T1(u)·T1(v)"] == pytest.approx(50.0, abs=2.0)
    assert abs(s["terms"]["piston_um"] + 0.1) <= 4 * s["sigma"]["piston_um"] + 1e-3


def test_the_measure_command_says_the_terms_and_the_form_error(tmp_path):
    import json

    from click.testing import CliRunner

    from ftsweep.cli.main import main

    path = _cloud(tmp_path / "ff.csv", "zernike_example", 1000.0, (2.0, -1.0, 0.2), lambda x, y: 0 * x)
    res = CliRunner().invoke(main, ["measure", str(path), "--surface", "zernike_example", "--rotation"])
    assert res.exit_code == 0, res.output
    assert "decentre_x_um " in res.output and "form error   P-V" in res.output
    res = CliRunner().invoke(main, ["measure", str(path), "--surface", "zernike_example", "--json"])
    assert res.exit_code == 0 and json.loads(res.stdout)["rms_nm"] < 2.0  # the 1 nm noise
    bad = tmp_path / "bad.csv"
    bad.write_text("1 2 3\n")
    res = CliRunner().invoke(main, ["measure", str(bad), "--surface", "zernike_example"])
    assert res.exit_code == 1 and "state the units" in res.output and "Traceback" not in res.output
