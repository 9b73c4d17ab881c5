"""Cubes at scale: a synthetic cube of many cases (a table sweep's template, every case done
with made-up results written as a sweep's driver merges them), and what it costs to hold and
to read: objects in the store, opening it, and ``select`` on it. It
measures; it asserts nothing about time."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Optional

import numpy as np

from ftsweep.inputs import catalogs
from ftsweep.store import cube
from ftsweep.store.storage import PathLike, place
from ftsweep.sweeps.spec import SweepSpec, coordinates, n_cases
from ftsweep.sweeps.template import template

SURFACE = "sinewave2d"


def synthetic_spec(cases: int) -> SweepSpec:
    """A sweep of about ``cases`` cases of the surface's own table kind (sinewave2d's: rings):
    100 aspect ratios × cases/100 point counts."""
    aspects = 100 if cases >= 100 else cases
    points = max(1, math.ceil(cases / aspects))
    return SweepSpec.model_validate(
        {
            "surface": SURFACE,
            "layout": catalogs.entry("surfaces", SURFACE).layout,
            "axes": {
                "points": {"start": 1e4, "stop": 1e6, "num": points, "scale": "log"},
                "aspect": {"start": 0.5, "stop": 400.0, "num": aspects, "scale": "log"},
            },
        }
    )


def fill(where: PathLike, spec: SweepSpec, seed: int = 0) -> None:
    """Every case of the cube done with made-up, plausible values (P-V falling as 1/N), written
    in one merge as a sweep's driver writes its workers' logs."""
    rng = np.random.default_rng(seed)
    coords = coordinates(spec)
    shape = tuple(v.size for v in coords.values())
    points = np.repeat(coords["points"].astype(float), shape[1])
    cases = []
    for flat in range(int(np.prod(shape))):
        values: dict[str, Any] = {
            var: 1 if np.dtype(dtype).kind in "iu" else float(rng.uniform(0.5, 2.0))
            for var, (dtype, _, _, _) in cube.metrics_for(str(spec.layout)).items()
        }
        values["n_points"] = int(points[flat] * 0.97)
        values["pv_nm"] = float(4e6 / points[flat] * rng.uniform(0.8, 1.2))
        values.update(feasible=1, infeasible_reason="", message="", run_id="synthetic", status=cube.DONE)
        cases.append((flat, values))
    cube.CubeWriter(where).write(cases)


def build(where: PathLike, cases: int) -> dict[str, Any]:
    """Create the synthetic cube of about ``cases`` cases at ``where``; returns its spec and
    the seconds it took."""
    spec = synthetic_spec(cases)
    start = time.perf_counter()
    entries = catalogs.recorded_entries(spec.surface, spec.machine, spec.cutting, None)
    cube.create(where, template(spec, "synthetic", entries))
    fill(where, spec)
    return {"cases": n_cases(spec), "seconds_build": time.perf_counter() - start}


SELECT_CODE = """
import json, sys, time
from ftsweep.tools.select import choose, open_cube
t = time.perf_counter()
ds = open_cube(sys.argv[1])
opened = time.perf_counter() - t
chosen = choose(ds, budget_points=950000)
print(json.dumps({"open_s": opened, "select_s": time.perf_counter() - t - opened,
                  "index": chosen["index"]}))
"""


def measure(where: PathLike) -> dict[str, Any]:
    """Objects in the store; open and select in a fresh process (imports excluded, then
    included as the whole ``ftsweep select`` command)."""
    at = place(where)
    objects = len(at.listing(""))
    inner = subprocess.run(
        [sys.executable, "-c", SELECT_CODE, at.url], capture_output=True, text=True, check=True
    )
    row: dict[str, Any] = json.loads(inner.stdout)
    start = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "ftsweep.cli.main", "select", at.url, "--budget-points", "950000", "--json"],
        capture_output=True,
        text=True,
        check=True,
    )
    row.update(objects=objects, select_command_s=time.perf_counter() - start)
    return row


def cube_scale(cases: int = 100_000, folder: Optional[Path] = None) -> dict[str, Any]:
    """Build a synthetic cube of ``cases`` cases in ``folder`` (a temporary one by default)
    and measure it."""
    with tempfile.TemporaryDirectory(dir=folder) as tmp:
        where = Path(tmp) / "synthetic.zarr"
        row = build(where, cases)
        row.update(measure(where))
    row["objects_per_10_cases"] = 10.0 * row["objects"] / row["cases"]
    return row


def format_cube_scale(row: dict[str, Any]) -> str:
    return "\n".join(
        [
            f"synthetic cube: {row['cases']:,} cases (built in {row['seconds_build']:.1f} s)",
            f"  objects            {row['objects']:,} ({row['objects_per_10_cases']:.3f} per 10 cases)",
            f"  open (load)        {row['open_s']:.2f} s",
            f"  select --budget    {row['select_s']:.2f} s",
            f"  open + select      {row['open_s'] + row['select_s']:.2f} s",
            f"  `ftsweep select`   {row['select_command_s']:.2f} s whole process",
        ]
    )
