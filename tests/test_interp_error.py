"""The exact-command envelope only when asked (issue 10, item 1): the same results without it,
pv_interp_nm NaN, and unchanged hashes for specs that keep the default."""

from __future__ import annotations

import json
import math

import numpy as np
import xarray as xr
from click.testing import CliRunner

from ftsweep.case import run_case
from ftsweep.cli import main
from ftsweep.export import export, verify
from ftsweep.kinds.requests import program_request
from ftsweep.run import run_sweep
from ftsweep.spec import Case, Resolution

SMALL = """
surface: small_sine
layout: ring
axes: {points: [8000], aspect: [1.0, 4.0]}
"""


def test_without_the_exact_envelope_every_other_result_is_the_same():
    on = run_case(Case(surface="sinewave2d", layout=program_request(kind="ring", pitch=(20.0, 5.0))))
    off = run_case(
        Case(
            surface="sinewave2d",
            layout=program_request(kind="ring", pitch=(20.0, 5.0)),
            resolution=Resolution(interp_error=False),
        )
    )
    assert math.isfinite(on["pv_interp_nm"]) and math.isnan(off["pv_interp_nm"])
    for key, value in on.items():
        if key == "pv_interp_nm" or key.startswith("seconds"):
            continue
        assert off[key] == value, key


def test_the_default_keeps_hashes_and_round_trips():
    assert "interp_error" not in Resolution().model_dump()
    off = Resolution(interp_error=False)
    assert off.model_dump()["interp_error"] is False
    assert Resolution.model_validate_json(off.model_dump_json()) == off
    a = Case(surface="s", layout=program_request(kind="ring", pitch=(1.0, 1.0)))
    b = Case(surface="s", layout=program_request(kind="ring", pitch=(1.0, 1.0)), resolution=off)
    assert a.key() != b.key()


def test_a_sweep_can_leave_it_out(tmp_path, catalog_dir):
    spec = tmp_path / "off.yaml"
    spec.write_text(SMALL + "resolution: {interp_error: false}\n")
    out = tmp_path / "off.zarr"
    report = run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    assert report.done == 2
    ds = xr.open_zarr(out).load()
    assert np.all(np.isnan(ds["pv_interp_nm"].values)) and np.all(np.isfinite(ds["pv_nm"].values))
    # such a cube's selection is still strict JSON: the metric not simulated is null
    r = CliRunner().invoke(main, ["select", str(out), "--budget-points", "8000", "--json"])
    assert r.exit_code == 0, r.output
    chosen = json.loads(r.stdout)
    assert chosen["pv_interp_nm"] is None and chosen["pv_nm"] > 0
    text = CliRunner().invoke(main, ["select", str(out), "--budget-points", "8000"])
    assert text.exit_code == 0, text.output
    assert "interpolation alone not simulated" in text.stdout and "nan" not in text.stdout
    # and its export writes strict JSON (the sidecar's selection names the metric null) that verifies
    header = tmp_path / "off.h"
    sidecar = export(out, header, budget_points=8000)
    assert sidecar["selection"]["pv_interp_nm"] != sidecar["selection"]["pv_interp_nm"]  # NaN in memory
    assert json.loads(header.with_suffix(".json").read_text())["selection"]["pv_interp_nm"] is None
    assert verify(header)["pv_nm"] > 0


ARGS = ["predict", "--surface", "sinewave2d", "--drho-um", "20", "--dtheta-deg", "5", "--no-interp-error"]


def test_predict_json_names_the_skipped_metric_null():
    r = CliRunner().invoke(main, [*ARGS, "--json"])
    assert r.exit_code == 0, r.output
    record = json.loads(r.stdout)
    assert record["pv_interp_nm"] is None and record["pv_nm"] > 0
    text = CliRunner().invoke(main, ARGS)
    assert "interp. P-V  not simulated" in text.stdout
