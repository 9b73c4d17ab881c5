"""Numbers outside their unit's physically meaningful range are refused where they enter:
command-line options (a usage error, exit 2, naming the option and its range), sweep axes
and catalog fields (naming the field); nothing is written."""

from __future__ import annotations

import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from ftsweep.cli.main import main
from ftsweep.inputs.strict import MAX_COUNT, MAX_LENGTH_UM, MIN_RADIUS_UM, check_physical


def _cli(args: list[str], catalogs) -> object:  # type: ignore[no-untyped-def]
    return CliRunner().invoke(main, args, env={"FTSWEEP_CATALOGS": str(catalogs)})


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--drho-um", "1e308", "--dtheta-deg", "0.5"], "--drho-um (at most 1e+07 in magnitude)"),
        (["--points", "1e308", "--aspect", "1"], "--points (at most 1e+09 in magnitude)"),
        (
            ["--drho-um", "5", "--dtheta-deg", "0.5", "--nose-radius-um", "1e-300"],
            "--nose-radius-um (0.001 to",
        ),
        (["--drho-um", "5", "--dtheta-deg", "1e300"], "--dtheta-deg (at most 1e+12"),
    ],
)
def test_an_absurd_option_is_a_usage_error_naming_it_and_its_range(args, words, module_catalog_dir):
    res = _cli(["predict", "--surface", "sinewave2d", *args], module_catalog_dir)
    assert res.exit_code == 2 and words in res.output, res.output  # type: ignore[attr-defined]
    assert "unexpected" not in res.output and "Traceback" not in res.output  # type: ignore[attr-defined]


def test_an_absurd_sweep_axis_writes_nothing(tmp_path, module_catalog_dir):
    spec = tmp_path / "s.yaml"
    spec.write_text("surface: sinewave2d\nlayout: ring\naxes: {points: [1e308], aspect: [1.0]}\n")
    out = tmp_path / "c.zarr"
    res = _cli(["sweep", str(spec), "--out", str(out), "--scheduler", "synchronous"], module_catalog_dir)
    assert res.exit_code == 1 and "1e+308 is outside the physically meaningful range of points" in res.output
    assert not out.exists() and not (tmp_path / "c.zarr.lock").exists()


def test_a_nose_radius_under_a_nanometre_in_the_catalog_is_named(tmp_path, catalog_dir):
    cutting = catalog_dir / "cutting.yaml"
    cutting.write_text(
        cutting.read_text()
        + "\natomic:\n  feed_um: 1.0e-301\n  nose_radius_um: 1.0e-300\n  spindle_rpm: 50.0\n"
    )
    res = _cli(
        ["predict", "--surface", "sinewave2d", "--drho-um", "5", "--dtheta-deg", "1", "--cutting", "atomic"],
        catalog_dir,
    )
    assert res.exit_code != 0 and "range of nose_radius_um (0.001 to 1e+07)" in res.output, res.output


def test_a_device_given_as_a_sweep_file_is_named_as_one(module_catalog_dir):
    res = _cli(["sweep", "/dev/zero"], module_catalog_dir)
    assert res.exit_code != 0 and "is a device, FIFO or socket, not a YAML file" in res.output, res.output


@settings(max_examples=200, derandomize=True)
@given(st.floats(allow_nan=False, allow_infinity=False))
def test_the_ranges_hold_for_any_number(value):
    length, radius, count = (check_physical(n, value) for n in ("drho_um", "nose_radius_um", "points"))
    assert (length is None) == (abs(value) <= MAX_LENGTH_UM)
    assert (radius is None) == (abs(value) <= MAX_LENGTH_UM and (value == 0 or abs(value) >= MIN_RADIUS_UM))
    assert (count is None) == (abs(value) <= MAX_COUNT)
