"""Errors that say what to do next: a misspelt command, name, key or axis gets "did you mean",
a number given with its unit says the unit the option takes, a missing cube names the sweep
that makes it, and a catalog folder without catalogs names FTSWEEP_CATALOGS."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from ftsweep.cli.main import main
from ftsweep.inputs.strict import did_you_mean


def _error(args: list[str], env: dict[str, str] | None = None) -> str:
    res = CliRunner().invoke(main, args, env=env)
    assert res.exit_code != 0, res.output
    return res.output


def test_did_you_mean_names_the_closest_known_word_or_nothing():
    assert did_you_mean("aspects", ["points", "aspect", "feed_um"]) == " (did you mean 'aspect'?)"
    assert did_you_mean("teapot", ["points", "aspect", "feed_um"]) == ""
    assert did_you_mean("x" * 10_000, ["points"]) == ""  # a long word is cut before it is compared


@pytest.mark.parametrize(
    ("args", "said"),
    [
        (["swep"], "No such command 'swep' (did you mean 'sweep'?)"),
        (["predict", "--surface", "sinwave2d"], "unknown surface 'sinwave2d' (did you mean 'sinewave2d'?)"),
        (
            ["predict", "--surface", "sinewave2d", "--drho-um", "2um"],
            "takes a number of µm, e.g. 2 (got '2um')",
        ),
        (["predict", "--surface", "sinewave2d", "--dtheta-deg", "1°"], "takes a number of degrees"),
        (["export", "outputs/lens-array-mesh-missing.zarr"], "run `ftsweep sweep SWEEP --out"),
    ],
)
def test_a_mistake_is_answered_with_the_fix(args, said):
    assert said in _error(args)


def test_a_missing_catalog_cube_names_the_sweep_that_makes_it(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # outputs/ here holds no cube
    assert "run `ftsweep sweep lens-array-mesh` first" in _error(["export", "outputs/lens-array-mesh.zarr"])
    out = _error(["select", str(tmp_path / "sinewave-ring.zarr")])
    assert f"run `ftsweep sweep sinewave-ring --out {tmp_path / 'sinewave-ring.zarr'}` first" in out


@pytest.mark.parametrize(
    ("axes", "said"),
    [
        ("axis: {points: [1000], aspect: [1.0]}", "axis: unknown key (did you mean 'axes'?)"),
        ("axes: {points: [1000], aspects: [1.0]}", "axes.aspects: unknown axis (did you mean 'aspect'?)"),
    ],
)
def test_a_misspelt_sweep_key_gets_did_you_mean(tmp_path, axes, said):
    spec = tmp_path / "typo.yaml"
    spec.write_text(f"surface: sinewave2d\nlayout: ring\n{axes}\n")
    assert said in _error(["sweep", str(spec), "--out", str(tmp_path / "typo.zarr")])
    assert not (tmp_path / "typo.zarr").exists()


def test_a_misspelt_catalog_key_gets_did_you_mean(tmp_path):
    from ftsweep.inputs.catalogs import CatalogError, entry

    src = tmp_path / "surfaces.yaml"
    src.write_text(
        "s1:\n  family: sinewave2d\n  layout: ring\n  aperture: {shape: circle, radius_um: 1000}\n"
        "  params: {amplitude_z_um: 1, wavelength_x_um: 100, wavelength_y_um: 100}\n  descripton: x\n"
    )
    with pytest.raises(CatalogError, match=r"descripton: unknown key \(did you mean 'description'\?\)"):
        entry("surfaces", "s1", tmp_path)


def test_an_empty_catalog_folder_names_the_variable_that_chose_it(tmp_path):
    out = _error(["predict", "--surface", "sinewave2d"], env={"FTSWEEP_CATALOGS": str(tmp_path)})
    assert f"FTSWEEP_CATALOGS={tmp_path} names has no surfaces.yaml" in out
