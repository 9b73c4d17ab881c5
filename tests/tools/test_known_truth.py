"""Corrective machining on known truth: parts made from ftsweep's own prediction of the case
that cut them plus machine errors of known shape (a tool-radius error, an axial spindle error
motion, a thermal ramp; tests/support/measured.py), set up with a known decentre or tilt,
with noise and dropouts; a freeform (the catalog's Zernike part, a ring table) and a sphere
(the catalog's concave sphere on its square, a mesh).

Each test checks the three claims of the method:

- the registration recovers the set-up terms within 3 of their standard errors, beyond the
  part of the form error that itself looks like a set-up term (no fit can tell those apart:
  it is measured here by registering the design plus the same form error with no set-up);
- what the prediction leaves is the injected machine error (as the registration leaves it),
  to the noise;
- the corrected program (gain 1, 15 terms) is predicted to leave at most a tenth of the
  uncorrected residual.

Run with -s to see the figures the README quotes.
"""

from __future__ import annotations

import numpy as np
import pytest
from support import measured as ms

from ftsweep.engine.case import Case, program_request
from ftsweep.inputs import catalogs
from ftsweep.simulate import run_case
from ftsweep.stages.measurement import register, registered_like
from ftsweep.tools.correct import correct
from ftsweep.tools.measure import explain, measure_part

NOISE_UM = 3e-4  # an interferometer's repeatability, 0.3 nm RMS


def _case(surface, kind, pitch):
    case = Case(surface=surface, layout=program_request(kind=kind, pitch=pitch))
    return case.model_copy(update={"resolution": case.resolution.model_copy(update={"error_map_bins": 32})})


def _check(tmp_path, surface, case, machine, setup, half_um, options):
    """Measure a part of ``case`` with ``machine``'s error and ``setup``, then check the three
    claims; returns the figures."""
    record = run_case(case)
    form = ms.summed(ms.predicted(record), machine)
    shift, tilt = setup
    points = ms.part(surface, half_um, shift, form, tilt=tilt, noise_um=NOISE_UM)
    path = ms.write_cloud(tmp_path / "part.csv", points)
    part = measure_part(path, surface, **options)
    design = catalogs.surface_callable(catalogs.entry("surfaces", surface))
    m, fit = part.measurement, part.registration
    inside = catalogs.aperture_of(catalogs.entry("surfaces", surface)).contains(m.x, m.y)
    # the form error's own look-alike of each set-up term: the design plus the form, no set-up
    alike = register(design, m.x, m.y, design(m.x, m.y)[0] + form(m.x, m.y), inside, **options).terms
    injected = {
        "piston_um": shift[2],
        "tilt_x": tilt[0],
        "tilt_y": tilt[1],
        "decentre_x_um": shift[0],
        "decentre_y_um": shift[1],
    }
    for name, value in fit.terms.items():
        expected = injected[name] + alike[name]
        assert abs(value - expected) <= 3 * fit.sigma[name] + 1e-9, (name, value, expected, fit.sigma[name])
    split = explain(part, record)
    seen = registered_like(design, m.x, m.y, fit, machine(m.x, m.y))
    both = np.isfinite(split.unexplained) & np.isfinite(seen)
    mismatch = float(np.std(split.unexplained[both] - seen[both]))
    assert mismatch < 2 * NOISE_UM  # the noise, and the error map's bilinear reading
    fixed = correct(part, split, case, tmp_path / "corrected")
    s = fixed.summary
    assert s["residual_after_rms_nm"] <= 0.1 * s["residual_before_rms_nm"]
    found = {
        "surface": surface,
        # both over the points the prediction's map covers
        "machine error injected, RMS nm (registered)": 1e3 * float(np.std(seen[both])),
        "unexplained, RMS nm": 1e3 * float(np.std(split.unexplained[both])),
        "unexplained less injected, RMS nm": 1e3 * mismatch,
        "set-up look-alike of the form error": {k: round(v, 6) for k, v in alike.items()},
        "fitted": {k: (round(v, 6), round(fit.sigma[k], 6)) for k, v in fit.terms.items()},
        "residual before, RMS nm": s["residual_before_rms_nm"],
        "residual after, RMS nm": s["residual_after_rms_nm"],
        "residual before, P-V nm": s["residual_before_pv_nm"],
        "residual after, P-V nm": s["residual_after_pv_nm"],
    }
    print(found)  # -s
    return found


def test_a_freeform_cut_by_a_worn_tool_on_a_warm_machine_with_spindle_error_is_corrected(tmp_path):
    surface = "zernike_example"
    machine = ms.summed(
        ms.tool_radius(surface, 80.0),  # the nose 80 µm larger than compensated for
        ms.spindle(0.001, 3),  # 1 nm of 3-per-revolution axial error motion
        ms.thermal(0.060, 1000.0),  # 60 nm of drift over the facing cut
    )
    setup = ((2.0, -1.5, 0.3), (2e-5, -1e-5))  # decentre (µm), piston (µm); tilts
    _check(tmp_path, surface, _case(surface, "ring", (20.0, 5.0)), machine, setup, 1000.0, {})


def test_a_sphere_cut_by_a_worn_tool_on_a_warm_machine_with_spindle_error_is_corrected(tmp_path):
    surface = "concave_sphere"
    machine = ms.summed(
        ms.tool_radius(surface, 40.0),
        ms.spindle(0.001, 3),
        ms.thermal(0.010, 10000.0 * np.sqrt(2.0)),  # from the square's corner to the axis
    )
    setup = ((0.0, 0.0, -0.2), (3e-6, 1e-6))  # on a sphere a decentre is a tilt: tilts set it up
    _check(
        tmp_path,
        surface,
        _case(surface, "mesh", (200.0, 200.0)),
        machine,
        setup,
        10000.0,
        {"decentre": False},
    )


def test_a_freeform_whose_set_up_shows_is_registered_within_its_uncertainty(tmp_path):
    """On the sine-wave part a decentre and a rotation move every crest: their columns are no
    low-order form error (``alike`` near 0), so a warm machine and a spindle error leave the
    set-up terms where they were put, within 3σ, with no look-alike to allow for."""
    surface = "sinewave2d"
    machine = ms.summed(ms.spindle(0.002, 3), ms.thermal(0.030, 1000.0))
    points = ms.part(
        surface,
        1000.0,
        (3.0, -2.0, 0.1),
        machine,
        rotation_rad=2e-3,
        tilt=(1e-5, 2e-5),
        noise_um=NOISE_UM,
        n=161,
    )
    part = measure_part(ms.write_cloud(tmp_path / "sine.csv", points), surface, rotation=True)
    terms, sigma = part.summary["terms"], part.summary["sigma"]
    injected = {
        "decentre_x_um": 3.0,
        "decentre_y_um": -2.0,
        "rotation_rad": 2e-3,
        "tilt_x": 1e-5,
        "tilt_y": 2e-5,
    }
    for name, value in injected.items():
        assert abs(terms[name] - value) <= 3 * sigma[name], (name, terms[name], value, sigma[name])
    assert max(part.summary["alike"].values()) < 0.01
    design = catalogs.surface_callable(catalogs.entry("surfaces", surface))
    m = part.measurement
    seen = registered_like(design, m.x, m.y, part.registration, machine(m.x, m.y))
    assert float(np.nanstd(part.registration.residual - seen)) < 2 * NOISE_UM
    print("sine-wave part:", {k: (terms[k], sigma[k]) for k in injected})  # -s


def test_a_spindles_synchronous_error_is_corrected_only_as_far_as_its_low_order_terms(tmp_path):
    """An axial error motion a·cos(3θ) has the same amplitude at every radius: no finite sum
    of Zernike terms is it, so a low-pass correction takes out its low-order share only (the
    servo would follow it; a figure correction of 15 terms does not hold it). The share left,
    a curve over the amplitude, is printed; the correction never makes it worse."""
    surface = "zernike_example"
    case = _case(surface, "ring", (10.0, 4.0))
    record = run_case(case)
    for amplitude_nm in (0.5, 1.0, 2.0, 4.0):
        machine = ms.spindle(amplitude_nm * 1e-3, 3)
        points = ms.part(
            surface, 1000.0, (0.0, 0.0, 0.0), ms.summed(ms.predicted(record), machine), noise_um=NOISE_UM
        )
        part = measure_part(ms.write_cloud(tmp_path / "p.csv", points), surface)
        split = explain(part, record)
        s = correct(part, split, case, tmp_path / f"spindle-{amplitude_nm}").summary
        print(
            "spindle", amplitude_nm, "nm:", s["residual_before_rms_nm"], "->", s["residual_after_rms_nm"]
        )  # -s
        assert s["residual_after_rms_nm"] < s["residual_before_rms_nm"]


@pytest.mark.parametrize("gain", [0.5])
def test_a_gain_below_one_leaves_its_share_of_the_machines_error(tmp_path, gain):
    """With gain g the corrected residual keeps (1 − g) of the low-passed machine error: its
    RMS is close to (1 − g) times the uncorrected one where the machine's error dominates."""
    surface = "zernike_example"
    case = _case(surface, "ring", (10.0, 4.0))
    record = run_case(case)
    machine = ms.thermal(0.020, 1000.0)
    points = ms.part(
        surface, 1000.0, (0.0, 0.0, 0.0), ms.summed(ms.predicted(record), machine), noise_um=NOISE_UM
    )
    part = measure_part(ms.write_cloud(tmp_path / "p.csv", points), surface, decentre=False)
    split = explain(part, record)
    s = correct(part, split, case, tmp_path / "half", gain=gain).summary
    assert s["residual_after_rms_nm"] == pytest.approx((1 - gain) * s["residual_before_rms_nm"], rel=0.15)
