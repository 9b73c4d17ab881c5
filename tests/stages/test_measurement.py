"""Registration and Zernike breakdown of a measured part (ftsweep.stages.measurement), on
synthetic measurements of known truth: a design moved by known set-up terms, with a known
form error added, noise and dropouts; the fit recovers the terms within their stated
uncertainty and leaves the form error as its residual."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ftsweep.stages.measurement import register, zernike_basis, zernike_fit
from ftsweep.stages.sampling import sphere, zernike

RADIUS = 2000.0  # the aperture [µm]
FREEFORM = partial(
    zernike, norm_radius_um=RADIUS, terms_um={5: 0.8, 7: 0.5, 9: 0.3, 11: 0.2}, base_radius_um=50_000.0
)


def _grid(n: int = 121) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    x, y = np.meshgrid(np.linspace(-RADIUS, RADIUS, n), np.linspace(-RADIUS, RADIUS, n))
    return x, y, x * x + y * y <= RADIUS * RADIUS


def _moved(surface, x, y, dx=0.0, dy=0.0, gamma=0.0, piston=0.0, tx=0.0, ty=0.0, power=0.0):
    """Eq. (1) of the module: the design moved by the set-up terms."""
    u, v = x - dx, y - dy
    xp, yp = np.cos(gamma) * u + np.sin(gamma) * v, -np.sin(gamma) * u + np.cos(gamma) * v
    return surface(xp, yp)[0] + piston + tx * x + ty * y + power * (x * x + y * y)


def _measured(z: np.ndarray, noise_um: float, dropout: float, seed: int = 7) -> np.ndarray:
    rng = np.random.default_rng(seed)
    out = z + rng.normal(0.0, noise_um, z.shape)
    out[rng.random(z.shape) < dropout] = np.nan
    return out


def test_a_freeform_measured_off_centre_and_turned_is_registered_within_its_uncertainty():
    x, y, inside = _grid()
    truth = dict(dx=3.0, dy=-2.0, gamma=2e-3, piston=0.15, tx=2e-5, ty=-1e-5)
    z = _measured(_moved(FREEFORM, x, y, **truth), noise_um=0.002, dropout=0.1)
    fit = register(FREEFORM, x, y, z, inside, rotation=True)
    found = {
        "decentre_x_um": truth["dx"],
        "decentre_y_um": truth["dy"],
        "rotation_rad": truth["gamma"],
        "piston_um": truth["piston"],
        "tilt_x": truth["tx"],
        "tilt_y": truth["ty"],
    }
    for name, value in found.items():
        assert abs(fit.terms[name] - value) <= 4 * fit.sigma[name], (name, fit.terms[name], fit.sigma[name])
    assert fit.sigma["decentre_x_um"] < 0.05 and fit.sigma["rotation_rad"] < 1e-4
    # the residual is the noise: 2 nm RMS, NaN where nothing was measured
    assert np.nanstd(fit.residual) == pytest.approx(0.002, rel=0.05)
    assert np.isnan(fit.residual[~inside]).all() and np.isnan(fit.residual[np.isnan(z)]).all()


def test_the_residual_of_a_registered_part_is_its_form_error():
    """A form error the set-up terms cannot make (trefoil, spherical aberration) stays in the
    residual whole; the set-up terms are still found."""
    x, y, inside = _grid()
    form = 0.05 * zernike_basis(x.ravel(), y.ravel(), RADIUS, 11)[:, [8, 10]].sum(axis=1).reshape(x.shape)
    z = _measured(_moved(FREEFORM, x, y, dx=1.5, dy=0.5, piston=0.1) + form, noise_um=0.001, dropout=0.05)
    fit = register(FREEFORM, x, y, z, inside, rotation=True)
    assert abs(fit.terms["decentre_x_um"] - 1.5) <= 4 * fit.sigma["decentre_x_um"] + 0.02
    left = fit.residual - form
    assert np.nanstd(left) < 0.0015  # the noise, and what the fit took of the form error
    coef = zernike_fit(x, y, fit.residual, RADIUS, 15)
    assert coef[9] == pytest.approx(0.05, abs=0.003) and coef[11] == pytest.approx(0.05, abs=0.003)


def test_a_sphere_is_registered_by_piston_tilt_and_power():
    x, y, inside = _grid()
    design = partial(sphere, radius_um=20_000.0)
    z = _measured(_moved(design, x, y, piston=-0.3, tx=5e-5, power=2e-8), noise_um=0.003, dropout=0.2)
    fit = register(design, x, y, z, inside, decentre=False, power=True)
    assert abs(fit.terms["power_per_um"] - 2e-8) <= 4 * fit.sigma["power_per_um"]
    assert abs(fit.terms["tilt_x"] - 5e-5) <= 4 * fit.sigma["tilt_x"]
    assert set(fit.terms) == {"piston_um", "tilt_x", "tilt_y", "power_per_um"}


def test_terms_the_design_cannot_tell_apart_are_refused_by_name():
    x, y, inside = _grid(41)
    design = partial(sphere, radius_um=20_000.0)
    with pytest.raises(ValueError, match="cannot be told apart.*rotation_rad moves no height"):
        register(design, x, y, design(x, y)[0], inside, rotation=True)  # a sphere has no rotation


def test_too_few_measured_points_are_refused():
    x, y, inside = _grid(41)
    z = np.full(x.shape, np.nan)
    z[0, 0] = 1.0
    with pytest.raises(ValueError, match="1 measured point"):
        register(FREEFORM, x, y, z, np.ones_like(inside), rotation=True)


@given(coef=st.lists(st.floats(-1.0, 1.0), min_size=10, max_size=10))
def test_zernike_fit_returns_the_coefficients_of_any_sum_of_its_terms(coef):
    x, y, _ = _grid(61)
    z = (zernike_basis(x.ravel(), y.ravel(), RADIUS, 10) @ np.array(coef)).reshape(x.shape)
    found = zernike_fit(x, y, z, RADIUS, 10)
    assert np.allclose([found[j] for j in range(1, 11)], coef, atol=1e-9)
