"""A measured part registered to its catalog design (ftsweep.tools.measure), on two surfaces
of the catalog: the Zernike freeform over its circle and the concave sphere over its square,
each measured as a point cloud moved by known set-up terms with a known form error."""

from __future__ import annotations

import numpy as np
import pytest

from ftsweep.inputs import catalogs
from ftsweep.stages.measurement import registered_like, zernike_basis
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


def test_the_prediction_explains_its_share_and_the_machines_error_is_left():
    """A part measured as its design moved, plus the error ftsweep predicts for the case that
    cut it, plus a machine's error the prediction knows nothing of (trefoil, 5 nm) and noise:
    the registered prediction is what it explains, and what is left is the machine's error."""
    import tempfile
    from pathlib import Path

    from ftsweep.engine.case import Case, program_request
    from ftsweep.simulate import run_case
    from ftsweep.tools.measure import explain, predicted_at

    case = Case(surface="zernike_example", layout=program_request(kind="ring", pitch=(60.0, 15.0)))
    case = case.model_copy(update={"resolution": case.resolution.model_copy(update={"error_map_bins": 32})})
    record = run_case(case)

    def machine(x, y):
        return 0.005 * zernike_basis(x, y, 1000.0, 9)[:, 8]

    def form(x, y):
        return predicted_at(record, x, y) + machine(x, y)

    with tempfile.TemporaryDirectory() as folder:
        path = _cloud(
            Path(folder) / "cut.csv", "zernike_example", 1000.0, (1.0, 0.5, 0.1), form, noise_um=5e-4
        )
        part = measure_part(path, "zernike_example", rotation=True)
    split = explain(part, record)
    m = part.measurement
    use = np.isfinite(split.unexplained)
    assert use.sum() > 4000
    # the machine's error as the registration leaves it (less what the set-up terms take)
    design = catalogs.surface_callable(catalogs.entry("surfaces", "zernike_example"))
    seen = registered_like(design, m.x, m.y, part.registration, machine(m.x, m.y))
    left = split.unexplained[use] - seen[use]
    assert float(np.std(left)) < 1e-3  # the noise (0.5 nm)
    # the share: the registered prediction's variance over the form error's
    said = registered_like(design, m.x, m.y, part.registration, predicted_at(record, m.x, m.y))
    p2, m2 = float(np.nanvar(said)), float(np.nanvar(seen))
    assert split.summary["explained_share"] == pytest.approx(p2 / (p2 + m2), abs=0.02)
    assert 0.1 < split.summary["explained_share"] < 0.9  # both have their share
    z9 = next(t["nm"] for t in split.summary["unexplained_terms"] if t["term"].startswith("Z9 "))
    assert z9 == pytest.approx(5.0, abs=0.5)
    print("predicted P-V", record["pv_nm"], "nm; explained share", split.summary["explained_share"])  # -s


def test_the_corrected_cut_leaves_at_most_a_tenth_of_the_machines_error(tmp_path):
    """A part cut on a fine layout (a small predicted error) by a machine that adds 20 nm of
    astigmatism and 10 nm of coma: the corrected program (gain 1, 15 Zernike terms) is
    predicted to leave at most a tenth of the uncorrected residual."""
    from ftsweep.engine.case import Case, program_request
    from ftsweep.simulate import run_case
    from ftsweep.tools.correct import correct
    from ftsweep.tools.measure import explain, predicted_at

    case = Case(surface="zernike_example", layout=program_request(kind="ring", pitch=(10.0, 4.0)))
    case = case.model_copy(update={"resolution": case.resolution.model_copy(update={"error_map_bins": 32})})
    record = run_case(case)

    def machine(x, y):
        basis = zernike_basis(x, y, 1000.0, 8)
        return 0.02 * basis[:, 5] + 0.01 * basis[:, 7]

    def form(x, y):
        return predicted_at(record, x, y) + machine(x, y)

    path = _cloud(tmp_path / "cut.csv", "zernike_example", 1000.0, (1.0, 0.5, 0.1), form, noise_um=5e-4)
    part = measure_part(path, "zernike_example", rotation=True)
    split = explain(part, record)
    fixed = correct(part, split, case, tmp_path / "corrected")
    s = fixed.summary
    print("residual before", s["residual_before_rms_nm"], "nm RMS, after", s["residual_after_rms_nm"])  # -s
    assert s["residual_before_rms_nm"] > 10.0  # the registration takes some of the coma
    assert s["residual_after_rms_nm"] <= 0.1 * s["residual_before_rms_nm"]
    assert fixed.case.surface == "zernike_example-corrected" and len(s["measurement_sha256"]) == 64


def test_a_sphere_cut_with_a_machine_error_is_corrected_over_its_square(tmp_path):
    """The catalog's concave sphere on its 20 mm square (a mesh), cut with a machine error that
    the set-up cannot take (a saddle, T1·T1, and T2·T0, 30 nm each): the corrected program
    leaves at most a tenth of the uncorrected residual."""
    from ftsweep.engine.case import Case, program_request
    from ftsweep.simulate import run_case
    from ftsweep.tools.correct import correct
    from ftsweep.tools.measure import explain, predicted_at

    case = Case(surface="concave_sphere", layout=program_request(kind="mesh", pitch=(200.0, 200.0)))
    case = case.model_copy(update={"resolution": case.resolution.model_copy(update={"error_map_bins": 32})})
    record = run_case(case)

    def machine(x, y):
        u, v = x / 10000.0, y / 10000.0
        return 0.03 * u * v + 0.03 * (2 * u * u - 1)

    def form(x, y):
        return predicted_at(record, x, y) + machine(x, y)

    path = _cloud(tmp_path / "sphere.csv", "concave_sphere", 10000.0, (0.0, 0.0, -0.2), form, noise_um=5e-4)
    part = measure_part(path, "concave_sphere", decentre=False)
    split = explain(part, record)
    fixed = correct(part, split, case, tmp_path / "corrected")
    s = fixed.summary
    print("sphere: residual before", s["residual_before_rms_nm"], "nm RMS, after", s["residual_after_rms_nm"])
    assert s["residual_before_rms_nm"] > 10.0
    assert s["residual_after_rms_nm"] <= 0.1 * s["residual_before_rms_nm"]


def test_a_registered_measurement_reads_back_checked_and_a_forged_one_is_refused(tmp_path):
    import json

    import xarray as xr

    from ftsweep.tools.measureviews import open_registered, registered_dataset

    path = _cloud(tmp_path / "ff.csv", "zernike_example", 1000.0, (0.0, 0.0, 0.0), lambda x, y: 0 * x, n=21)
    part = measure_part(path, "zernike_example")
    good = tmp_path / "good.nc"
    registered_dataset(part).to_netcdf(good)
    ds = open_registered(good)
    assert json.loads(ds.attrs["measured"])["sha256"] == part.summary["sha256"]
    assert np.allclose(ds["form_error_nm"].values, 1e3 * part.registration.residual, equal_nan=True)
    forged = registered_dataset(part).assign(script=("point", np.zeros(ds.sizes["point"])))
    forged.to_netcdf(tmp_path / "extra.nc")
    with pytest.raises(ValueError, match="unexpected variables"):
        open_registered(tmp_path / "extra.nc")
    bad = registered_dataset(part)
    bad.attrs["measured"] = "__import__('os')"
    bad.to_netcdf(tmp_path / "attr.nc")
    with pytest.raises(ValueError, match="attribute measured is not JSON"):
        open_registered(tmp_path / "attr.nc")
    xr.Dataset({"z": ("point", np.zeros(3))}).to_netcdf(tmp_path / "other.nc")
    with pytest.raises(ValueError, match="not a registered measurement ftsweep wrote"):
        open_registered(tmp_path / "other.nc")
