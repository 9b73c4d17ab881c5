"""A measured correction as a surface entry's block (ftsweep.inputs.corrections): the design
less g times the unexplained error's terms 4…N, slopes included; the block checked, a case's
gain and terms standing in for its own, and a sweep's axes of those names refused where the
surface has no correction."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import yaml
from pydantic import ValidationError
from support.places import REPO

from ftsweep.engine.case import Case, CaseError, program_request
from ftsweep.engine.planning import resolve_specs
from ftsweep.inputs import catalogs
from ftsweep.inputs.corrections import MeasuredCorrection, as_cased
from ftsweep.stages.measurement import zernike_basis
from ftsweep.sweeps.spec import SweepSpec, case_at, coordinates

SHA = "ab" * 32


def _corrected_entry(name, terms_um, **extra):
    design = catalogs.entry("surfaces", name).model_dump(mode="json")
    block = {"measurement_sha256": SHA, "gain": 1.0, "terms": 15, "fit": {"piston_um": 0.1}, **extra}
    return {**design, "correction": {**block, **terms_um}}


def _spec(entry):
    from pydantic import TypeAdapter

    return TypeAdapter(catalogs.surface_spec()).validate_python(entry)


def test_the_corrected_surface_is_the_design_less_the_kept_terms_with_their_slopes():
    zernike = {1: 0.3, 2: -0.2, 3: 0.1, 5: 0.02, 8: -0.01, 20: 0.05}  # 20 is beyond the 15 kept
    spec = _spec(_corrected_entry("zernike_example", {"zernike_um": zernike}, gain=0.8))
    design = catalogs.surface_callable(catalogs.entry("surfaces", "zernike_example"))
    corrected = catalogs.surface_callable(spec)
    rng = np.random.default_rng(1)
    x, y = rng.uniform(-900, 900, (2, 200))
    basis = zernike_basis(x, y, 1000.0, 8)
    expected = design(x, y)[0] - 0.8 * (0.02 * basis[:, 4] - 0.01 * basis[:, 7])
    f, fx, fy = corrected(x, y)
    assert np.allclose(f, expected, atol=1e-12, rtol=0)  # piston, tilts and Z20 left out
    h = 1e-3
    assert np.allclose(fx, (corrected(x + h, y)[0] - corrected(x - h, y)[0]) / (2 * h), atol=1e-9)
    assert np.allclose(fy, (corrected(x, y + h)[0] - corrected(x, y - h)[0]) / (2 * h), atol=1e-9)
    assert catalogs.line_sampler(spec) is None  # the family's line evaluator knows no correction


def test_a_rectangles_correction_keeps_its_chebyshev_products_by_degree():
    grid = np.zeros((5, 5))
    grid[0, 0], grid[1, 0], grid[2, 0], grid[1, 1], grid[0, 2] = 0.5, 0.4, 0.03, 0.02, 0.01
    spec = _spec(_corrected_entry("concave_sphere", {"chebyshev_um": grid.tolist()}, terms=5))
    design = catalogs.surface_callable(catalogs.entry("surfaces", "concave_sphere"))
    x, y = np.random.default_rng(2).uniform(-9000, 9000, (2, 100))
    u, v = x / 10000.0, y / 10000.0
    # the first five by degree: T0T0, T1T0, T0T1 (the set-up's), then T2T0 and T1T1
    expected = design(x, y)[0] - (0.03 * (2 * u * u - 1) + 0.02 * u * v)
    assert np.allclose(catalogs.surface_callable(spec)(x, y)[0], expected, atol=1e-12, rtol=0)


@pytest.mark.parametrize(
    ("change", "says"),
    [
        ({"chebyshev_um": [[0.0]]}, "one of zernike_um \\(a circle\\) or chebyshev_um"),
        ({"terms": 40}, "keeps 4…20 terms"),
        ({"terms": 3}, "keeps 4…20 terms"),
        ({"measurement_sha256": "not-a-digest"}, "measurement_sha256"),
        ({"gain": 2.0}, "gain"),
        ({"zernike_um": {0: 1.0, 20: 0.1}}, "Noll indices run from 1"),
    ],
)
def test_a_malformed_correction_is_refused_naming_its_key(change, says):
    given = {"measurement_sha256": SHA, "zernike_um": {4: 0.01, 20: 0.02}, **change}
    with pytest.raises(ValidationError, match=says):
        MeasuredCorrection.model_validate(given)


def test_a_cases_gain_and_terms_stand_in_for_the_blocks(tmp_path):
    spec = _spec(_corrected_entry("zernike_example", {"zernike_um": {4: 0.01, 20: 0.02}}))
    assert as_cased(spec, None, None) is spec
    cased = as_cased(spec, 0.5, 20)
    assert (cased.correction.gain, cased.correction.terms) == (0.5, 20) and spec.correction.gain == 1.0
    with pytest.raises(ValueError, match="keeps 4…20 terms"):
        as_cased(spec, None, 25)
    case = Case(
        surface="zernike_example", layout=program_request(kind="ring", pitch=(20.0, 5.0)), correction_gain=0.5
    )
    with pytest.raises(CaseError, match="surface zernike_example: .* has no measured correction"):
        resolve_specs(case)
    assert (
        "correction_gain"
        not in Case(surface="s", layout=program_request(kind="ring", pitch=(1.0, 1.0))).model_dump()
    )


def test_a_sweep_takes_gain_and_terms_as_axes_of_a_corrected_surface_only(tmp_path):
    entry = _corrected_entry("zernike_example", {"zernike_um": {4: 0.01, 9: 0.02, 20: 0.01}})
    folder = tmp_path / "catalogs"
    shutil.copytree(REPO / "catalogs", folder)
    with (folder / "surfaces.yaml").open("a", encoding="utf-8") as fh:
        fh.write("\n" + yaml.safe_dump({"zernike_fixed": entry}))
    given = {
        "surface": "zernike_fixed",
        "axes": {
            "points": [5000],
            "aspect": [4.0],
            "correction_gain": [0.5, 1.0],
            "correction_terms": [6, 20],
        },
    }
    spec = SweepSpec.model_validate(given, context={"catalog_folder": folder})
    coords = coordinates(spec)
    assert list(coords) == ["points", "aspect", "correction_gain", "correction_terms"]
    case = case_at(spec, 3)
    assert (case.correction_gain, case.correction_terms) == (1.0, 20)
    resolved = resolve_specs(case, folder).surface
    assert (resolved.correction.gain, resolved.correction.terms) == (1.0, 20)
    plain = {**given, "surface": "zernike_example"}
    with pytest.raises(ValidationError, match="axes.correction_\\*: surface zernike_example: .* no measured"):
        SweepSpec.model_validate(plain, context={"catalog_folder": folder})
    deep = {**given, "axes": {**given["axes"], "correction_terms": [30]}}
    with pytest.raises(ValidationError, match="keeps 4…20 terms"):
        SweepSpec.model_validate(deep, context={"catalog_folder": folder})
