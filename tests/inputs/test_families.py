"""Surface families users bring: freeforms, Zernikes, height maps, plug-ins."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from ftsweep.cli.main import main
from ftsweep.engine.case import Case, program_request
from ftsweep.inputs import catalogs
from ftsweep.inputs.catalogs import CatalogError, SurfaceSpec, load_catalog
from ftsweep.inputs.usersurfaces import SurfaceLoadError, height_map_surface
from ftsweep.simulate import run_case
from ftsweep.stages.sampling.surfaces import Aperture, noll_to_nm, radial_section, sinewave2d

ALL = [
    "sinewave2d",
    "lens_array",
    "chebyshev_example",
    "sinusoidal_mesh",
    "zernike_example",
    "bump_map",
    "dimples_plugin",
]


@pytest.mark.parametrize("name", ALL)
@settings(max_examples=5)
@given(seed=st.integers(0, 2**32 - 1))
def test_radial_slope_matches_finite_differences(name, seed):
    """For every family the analytic radial slope agrees with a central difference of the
    height to 1e-6 relative (of the largest slope on the sample)."""
    spec = catalogs.entry("surfaces", name)
    surface = catalogs.surface_callable(spec)
    rng = np.random.default_rng(seed)
    r = rng.uniform(0.02, 0.95, 300) * catalogs.aperture_of(spec).inner_radius_um
    th = rng.uniform(0, 2 * math.pi, 300)
    c, s = np.cos(th), np.sin(th)
    _, gp = radial_section(surface, r, c, s)
    h = 1e-5 if name == "lens_array" else 1e-4  # the lens blend is only C1: keep the step small
    fd = (radial_section(surface, r + h, c, s)[0] - radial_section(surface, r - h, c, s)[0]) / (2 * h)
    assert np.max(np.abs(gp - fd)) <= 1e-6 * np.max(np.abs(gp)) + 1e-12


@pytest.mark.parametrize("name", ALL[2:])
def test_predict_works_on_every_family(name):
    r = CliRunner().invoke(
        main, ["predict", "--surface", name, "--points", "30000", "--aspect", "2", "--json"]
    )
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)
    assert math.isfinite(out["pv_nm"]) and out["pv_nm"] > 0 and out["feasible"]


def test_sinusoidal_mesh_has_the_published_geometry():
    spec = catalogs.entry("surfaces", "sinusoidal_mesh")
    f, _, _ = catalogs.surface_callable(spec)(
        np.linspace(0, 8000, 20001)[None, :] * np.ones((1, 1)), np.zeros((1, 20001))
    )
    assert f.max() <= 1e-9
    # seed 003: the part is h_max = 0.2 mm deep; with the radial wavelength ω = 32/15 mm both
    # sines reach −1 together at the rim (8/ω = 3.75 periods), on the umbrella's 8 troughs
    r = np.linspace(0, 8000, 801)
    phi = np.linspace(0, 2 * np.pi, 721)
    rr, pp = np.meshgrid(r, phi)
    depth = -catalogs.surface_callable(spec)(rr * np.cos(pp), rr * np.sin(pp))[0].min()
    assert depth == pytest.approx(200.0, abs=1e-9)
    # l = 8 umbrella ribs: the rim height repeats 8 times around
    g, _, _ = catalogs.surface_callable(spec)(8000 * np.cos(phi[:-1]), 8000 * np.sin(phi[:-1]))
    minima = (g < np.roll(g, 1)) & (g <= np.roll(g, -1))  # the rim is closed: wrap around
    assert minima.sum() == 8


def test_zernike_noll_order():
    assert [noll_to_nm(j) for j in range(1, 12)] == [
        (0, 0),
        (1, 1),
        (1, -1),
        (2, 0),
        (2, -2),
        (2, 2),
        (3, -1),
        (3, 1),
        (3, -3),
        (3, 3),
        (4, 0),
    ]


@pytest.mark.slow  # 7-15 s on 2 cores: the full command runs it, the quick one leaves it out
def test_height_map_of_the_sinewave_predicts_the_analytic_pv(tmp_path, catalog_dir):
    """Sampled on a 0.5 µm grid, the sine-wave part predicts the analytic P-V within 5 %."""
    g = np.arange(-1010.0, 1010.0001, 0.5)
    x, y = np.meshgrid(g, g)
    params = catalogs.entry("surfaces", "sinewave2d").params.model_dump()
    z, _, _ = sinewave2d(x, y, **params)
    np.save(tmp_path / "sine.npy", z)
    with (catalog_dir / "surfaces.yaml").open("a") as fh:
        fh.write(f"""
sine_map:
  family: height_map
  layout: ring
  aperture: {{shape: circle, radius_um: 1000.0}}
  params: {{path: {tmp_path / "sine.npy"}, spacing_um: [0.5, 0.5], origin_um: [-1010.0, -1010.0]}}
""")
    layout = program_request(kind="ring", pitch=(2.0, 1.0))
    analytic = run_case(Case(surface="sinewave2d", layout=layout), catalog_dir)
    mapped = run_case(Case(surface="sine_map", layout=layout), catalog_dir)
    assert mapped["pv_nm"] == pytest.approx(analytic["pv_nm"], rel=0.05)


@pytest.fixture()
def write_entry(tmp_path):
    def write(text):
        p = tmp_path / "surfaces.yaml"
        p.write_text(text)
        return p

    return write


def test_height_map_with_nans_inside_the_aperture_is_refused():
    g = np.linspace(-100, 100, 41)
    z = np.zeros((41, 41))
    z[20, 22] = np.nan
    with pytest.raises(SurfaceLoadError, match=r"not finite.*x = 10 µm, y = 0 µm"):
        height_map_surface(g, g, z, Aperture("circle", radius_um=90.0), "map.npy")
    z[0, 0] = np.nan  # outside the circle: allowed
    z[20, 22] = 0.0
    height_map_surface(g, g, z, Aperture("circle", radius_um=90.0), "map.npy")


def test_aperture_larger_than_the_data_is_refused():
    g = np.linspace(-100, 100, 41)
    with pytest.raises(SurfaceLoadError, match="larger than the data"):
        height_map_surface(g, g, np.zeros((41, 41)), Aperture("circle", radius_um=150.0), "map.npy")


def test_height_map_from_netcdf(tmp_path, catalog_dir):
    import xarray as xr

    g = np.linspace(-300, 300, 121)
    x, y = np.meshgrid(g, g)
    xr.Dataset({"height": (("y", "x"), 1e-3 * (x + 2 * y))}, coords={"x": g, "y": g}).to_netcdf(
        tmp_path / "tilt.nc"
    )
    with (catalog_dir / "surfaces.yaml").open("a") as fh:
        fh.write(f"""
tilt_nc:
  family: height_map
  layout: ring
  aperture: {{shape: circle, radius_um: 250.0}}
  params: {{path: {tmp_path / "tilt.nc"}, variable: height}}
""")
    spec = catalogs.entry("surfaces", "tilt_nc", catalog_dir)
    f, fx, fy = catalogs.surface_callable(spec, catalog_dir)(np.array([10.0, -50.0]), np.array([20.0, 5.0]))
    np.testing.assert_allclose(f, 1e-3 * np.array([50.0, -40.0]), atol=1e-12)
    np.testing.assert_allclose(fx, 1e-3, atol=1e-12)
    np.testing.assert_allclose(fy, 2e-3, atol=1e-12)


def test_plugin_returning_the_wrong_shape_is_refused(tmp_path, monkeypatch, catalog_dir):
    (tmp_path / "badsurf.py").write_text(
        "import numpy as np\ndef flat_wrong(x, y):\n    return np.zeros(3)\n"
        "def nan_surface(x, y):\n    return np.full(np.shape(x), np.nan)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    for func, message in (
        ("badsurf:flat_wrong", "returned shape"),
        ("badsurf:nan_surface", "non-finite"),
        ("badsurf:missing", "cannot import"),
        ("nomodule:f", "cannot import"),
        ("no-colon", "module:function"),
    ):
        with (catalog_dir / "surfaces.yaml").open("a") as fh:
            name = "p_" + str(abs(hash(func)))
            fh.write(f"""
{name}:
  family: plugin
  layout: ring
  aperture: {{shape: circle, radius_um: 100.0}}
  params: {{function: "{func}"}}
""")
        spec = catalogs.entry("surfaces", name, catalog_dir)
        with pytest.raises(SurfaceLoadError, match=message):
            catalogs.surface_callable(spec, catalog_dir)


def test_plugin_without_slopes_is_differentiated():
    spec = catalogs.entry("surfaces", "dimples_plugin").model_copy(deep=True)
    from ftsweep.inputs.catalogs import PluginParams

    saddle = spec.model_copy(update={"params": PluginParams(function="ftsweep.inputs.examples:saddle")})
    f, fx, fy = catalogs.surface_callable(saddle)(np.array([300.0]), np.array([-200.0]))
    assert f[0] == pytest.approx(2.0 * (300.0**2 - 200.0**2) / 1e6)
    assert fx[0] == pytest.approx(2.0 * 2 * 300.0 / 1e6, rel=1e-6)
    assert fy[0] == pytest.approx(2.0 * 2 * 200.0 / 1e6, rel=1e-6)


def test_unknown_family_names_the_allowed_ones(write_entry):
    p = write_entry(
        "s:\n  family: nurbs\n  layout: ring\n  aperture: {shape: circle, radius_um: 1}\n  params: {}\n"
    )
    with pytest.raises(CatalogError) as err:
        load_catalog(p, SurfaceSpec)
    for family in ("chebyshev_freeform", "sinusoidal_mesh", "zernike", "height_map", "plugin"):
        assert family in str(err.value)


def test_chebyshev_coefficients_must_be_rectangular(write_entry):
    p = write_entry("""
c:
  family: chebyshev_freeform
  layout: ring
  aperture: {shape: circle, radius_um: 1}
  params: {coefficients_um: [[1, 2], [3]], norm_x_um: 1, norm_y_um: 1}
""")
    with pytest.raises(CatalogError, match="rectangular"):
        load_catalog(p, SurfaceSpec)


def test_off_axis_offset_moves_the_freeform():
    from ftsweep.stages.sampling.surfaces import chebyshev_freeform

    kw = dict(
        base_radius_um=5000.0, coefficients_um=[[0.0, 0.0], [0.0, 1.0]], norm_x_um=100.0, norm_y_um=100.0
    )
    a, _, _ = chebyshev_freeform(np.array([30.0]), np.array([-20.0]), **kw)
    b, _, _ = chebyshev_freeform(
        np.array([30.0 + 7.0]), np.array([-20.0 - 3.0]), offset_x_um=7.0, offset_y_um=-3.0, **kw
    )
    assert a[0] == pytest.approx(b[0])
