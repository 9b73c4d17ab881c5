"""A kind from outside the package (tests/support/toy_kind.py, registered by one line) passes the
conformance suite every kind passes: it sweeps into a cube, is selected, reported, exported
and verified, with no module of ftsweep changed for it."""

from __future__ import annotations

import pytest
from support.kinds import KindTests
from support.toy_kind import SQUARE

from ftsweep import registry


@pytest.fixture(scope="module", autouse=True)
def _registered():
    registry.register(SQUARE)  # the one line a kind outside the package needs
    yield
    registry.unregister(SQUARE.name)


class TestSquareMesh(KindTests):
    kind = "square"
    sweep = "surface: small_lens\nlayout: square\naxes: {pitch_um: [5.0]}\n"


def test_a_sweep_of_it_is_selected_by_the_points_budget(module_catalog_dir, tmp_path):
    """Two pitches swept into a cube; select takes the best that fits the budget."""
    import json

    from click.testing import CliRunner

    from ftsweep.cli.main import main
    from ftsweep.sweeps.run import run_sweep

    spec = tmp_path / "two.yaml"
    spec.write_text("surface: small_lens\nlayout: square\naxes: {pitch_um: [5.0, 7.5]}\n")
    report = run_sweep(
        str(spec), tmp_path / "two.zarr", scheduler="synchronous", catalog_folder=module_catalog_dir
    )
    assert report.done == 2
    env = {"FTSWEEP_CATALOGS": str(module_catalog_dir)}
    picks = {}
    for budget in (100_000, 5_000):  # 91 × 91 = 8,281 points at 5 µm, 61 × 61 = 3,721 at 7.5 µm
        res = CliRunner().invoke(
            main, ["select", str(tmp_path / "two.zarr"), "--budget-points", str(budget), "--json"], env=env
        )
        assert res.exit_code == 0, res.output
        picks[budget] = json.loads(res.stdout)
    assert picks[100_000]["pitch_actual_um"] == 5.0 and picks[100_000]["layout"] == "square"
    assert picks[5_000]["n_points"] == 3721 and picks[5_000]["pv_nm"] > picks[100_000]["pv_nm"]


def test_its_axis_units_and_choices_come_from_its_declaration(module_catalog_dir, tmp_path):
    from ftsweep.cli.predict import predict
    from ftsweep.sweeps.spec import axis_attrs, load_sweep

    assert axis_attrs("pitch_um", "square") == {"units": "um", "long_name": "pitch of the square mesh"}
    layout = next(p for p in predict.params if p.name == "layout")
    assert "square" in layout.type.choices
    spec = tmp_path / "bad.yaml"
    spec.write_text("surface: small_lens\nlayout: square\naxes: {pitch_um: [5.0], points: [100]}\n")
    with pytest.raises(Exception, match="points belongs to table sweeps"):
        load_sweep(str(spec), module_catalog_dir)


def test_it_adds_its_own_predict_option(module_catalog_dir):
    """``predict --layout square --square-pitch-um 5`` runs the toy kind: its option comes from
    its declaration, not from a module of ftsweep; another kind refuses it, naming its owner."""
    import json

    from click.testing import CliRunner

    from ftsweep.cli.main import main

    env = {"FTSWEEP_CATALOGS": str(module_catalog_dir)}
    args = ["predict", "--surface", "small_lens", "--layout", "square", "--square-pitch-um", "7.5", "--json"]
    res = CliRunner().invoke(main, args, env=env)
    assert res.exit_code == 0, res.output
    record = json.loads(res.stdout)
    assert record["layout"] == "square" and record["n_points"] == 61 * 61 and record["pitch_actual_um"] == 7.5
    help_text = CliRunner().invoke(main, ["predict", "--help"], env=env).output
    assert "Options of --layout square:" in help_text and "Square mesh: pitch" in help_text
    assert "--square-pitch-um" in help_text.split("Options of --layout square:")[1]
    ring = ["predict", "--surface", "small_lens", "--layout", "ring", "--drho-um", "20", "--dtheta-deg", "5"]
    refused = CliRunner().invoke(main, [*ring, "--square-pitch-um", "7.5"], env=env)
    assert refused.exit_code != 0 and "--square-pitch-um belongs to square mesh" in refused.output
