"""The declared result: run_case, predict --json, cubes and describe use
the names, units and long names ftsweep.engine.result declares, for every program kind."""

from __future__ import annotations

import json

import xarray as xr
from click.testing import CliRunner

from ftsweep import registry
from ftsweep.cli.main import main
from ftsweep.engine import result
from ftsweep.store import cube
from ftsweep.sweeps.run import run_sweep
from ftsweep.tools.query import describe


def _names(kind: str) -> list[str]:
    return result.result_names(registry.kind(kind))


def test_every_declared_field_has_a_long_name_and_numbers_have_units():
    for kind in registry.kinds().values():
        names = [q.name for q in result.declared(kind)]
        assert len(names) == len(set(names)), kind.name  # no field declared twice
        for q in result.declared(kind):
            assert q.long_name, q.name
            assert q.dtype is None or q.units, q.name


def test_predict_json_and_the_cube_use_the_declared_names_and_units(tmp_path, catalog_dir):
    args = ["predict", "--surface", "small_sine", "--drho-um", "10", "--dtheta-deg", "4", "--json"]
    r = CliRunner().invoke(main, args, env={"FTSWEEP_CATALOGS": str(catalog_dir)})
    assert r.exit_code == 0, r.output
    assert set(json.loads(r.stdout)) == set(_names("ring"))
    spec = tmp_path / "s.yaml"
    spec.write_text("surface: small_sine\naxes: {points: [8000], aspect: [2.0]}\n")
    out = tmp_path / "s.zarr"
    run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    ds = xr.open_zarr(out)
    stored = result.stored(registry.kind("ring"))
    assert set(stored) <= set(ds.data_vars)
    assert set(ds.data_vars) - set(stored) == {"status", cube.CASE_NUMBER, *cube.TEXT}
    for name, (_, units, long_name, _) in stored.items():
        assert ds[name].attrs == {"units": units, "long_name": long_name}, name
    # describe reads the same names back, target and realised aspect named apart
    case = describe(ds.load(), 0)
    assert {"drho_um", "dtheta_deg", "aspect_actual", "aspect_target", "points_target"} <= set(case)
    assert case["aspect_actual"] == float(ds["aspect_actual"].values.ravel()[0])


def test_metric_slots_are_named_after_the_statistics():
    from ftsweep.stages.metrics import moments as metrics

    for i, name in enumerate(metrics.STAT_NAMES):
        assert getattr(metrics, name.upper()) == i
