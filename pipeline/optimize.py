"""The tolerance loop of a shop: the smallest layout that meets a P-V tolerance.

Start coarse (a log scan of aspect ratios at a modest point count), refine around the best
aspect ratio by log-bisection, then change the point count. Bilinear error falls as the
square of the pitch, so P-V ∝ 1/N and the next count is N·P-V/T (with a small margin),
capped at the controller's capacity. Once one count meets the tolerance and a smaller one
does not, a bisection between them finds the smallest that does. Every evaluation is
appended to a one-dimensional cube (dimension ``evaluation``) as soon as it finishes.
"""

from __future__ import annotations

import json
import math
import shutil
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any, Optional

import numpy as np
import xarray as xr

from ftsweep import __version__, catalogs
from ftsweep.case import Case, CaseError, LayoutRequest, Resolution, run_case
from ftsweep.cube import SCHEMA_VERSION, CubeError, git_revision, metric_values, metrics_for
from ftsweep.lock import cube_lock
from ftsweep.sweep import axis_attrs

ASPECT_RANGE = {"ring": (0.3, 400.0), "mesh": (0.08, 16.0)}


class Optimizer:
    """Runs and records evaluations; ``best_meeting`` and ``best`` read the record."""

    def __init__(
        self,
        surface: str,
        layout: str,
        tolerance_nm: float,
        out: Path,
        machine: str,
        cutting: str,
        compensation: str,
        resolution: Resolution,
        catalog_folder: Optional[Path],
        on_eval: Optional[Callable[[dict[str, Any]], None]] = None,
    ) -> None:
        self.surface, self.layout, self.tol = surface, layout, tolerance_nm
        self.out, self.machine, self.cutting = out, machine, cutting
        self.compensation, self.resolution, self.folder = compensation, resolution, catalog_folder
        self.capacity = catalogs.entry("machines", machine, catalog_folder).capacity_points
        self.records: list[dict[str, Any]] = []
        self.cache: dict[tuple[int, float], dict[str, Any]] = {}
        self.on_eval = on_eval
        # written with every append: appending a dataset replaces the group's attributes
        self.attrs = dict(
            ftsweep_version=__version__,
            git_revision=git_revision(),
            kind="optimize",
            surface=surface,
            layout_method=layout,
            ftsweep_cube_schema=SCHEMA_VERSION,
            tolerance_nm=tolerance_nm,
            machine=machine,
            cutting=cutting,
            compensation=compensation,
            resolution=json.dumps(resolution.model_dump(mode="json")),
            created=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        )

    def evaluate(self, points: float, aspect: float, stage: str) -> dict[str, Any]:
        key = (int(points), round(aspect, 9))
        if key in self.cache:
            return self.cache[key]
        case = Case(
            surface=self.surface,
            layout=LayoutRequest(kind=self.layout, points=points, aspect=aspect),
            machine=self.machine,
            cutting=self.cutting,
            compensation=self.compensation,
            resolution=self.resolution,
        )
        try:
            rec = run_case(case, self.folder)
            rec.update(status="done", message="")
        except CaseError as exc:
            rec = {"status": "failed", "message": str(exc), "pv_nm": math.nan, "feasible": False}
        rec.update(points_target=float(points), aspect_target=float(aspect), stage=stage)
        self.cache[key] = rec
        self.records.append(rec)
        self._append(rec)
        if self.on_eval:
            self.on_eval(rec)
        return rec

    def ok(self, rec: dict[str, Any]) -> bool:
        return rec["status"] == "done" and bool(rec["feasible"]) and rec["n_points"] <= self.capacity

    def score(self, rec: dict[str, Any]) -> float:
        return rec["pv_nm"] if self.ok(rec) else math.inf

    def best_aspect(self, points: float, aspects: np.ndarray, stage: str) -> tuple[float, dict[str, Any]]:
        recs = [self.evaluate(points, a, stage) for a in aspects]
        i = int(np.argmin([self.score(r) for r in recs]))
        return float(aspects[i]), recs[i]

    def refine_aspect(self, points: float, aspect: float, factor: float, steps: int) -> tuple[float, dict]:
        """Log-bisection around ``aspect``: try aspect·factor^±1, keep the best, halve log(factor)."""
        best_a, best = aspect, self.evaluate(points, aspect, "refine")
        for _ in range(steps):
            for cand in (best_a / factor, best_a * factor):
                rec = self.evaluate(points, cand, "refine")
                if self.score(rec) < self.score(best):
                    best_a, best = cand, rec
            factor = math.sqrt(factor)
        return best_a, best

    def _append(self, rec: dict[str, Any]) -> None:
        data = {}
        values = metric_values(rec) if rec["status"] == "done" else {}
        for var, (dtype, units, long_name, fill) in metrics_for(self.layout).items():
            data[var] = (
                ("evaluation",),
                np.array([values.get(var, fill)], dtype=dtype),
                {"units": units, "long_name": long_name},
            )
        for var, units, long_name in (
            ("points_target", "1", "target number of control points"),
            ("aspect_target", axis_attrs("aspect", self.layout)["units"], "target aspect ratio"),
        ):
            data[var] = (("evaluation",), np.array([rec[var]]), {"units": units, "long_name": long_name})
        for var, long_name in (
            ("stage", "loop stage of the evaluation"),
            ("status", "done or failed"),
            ("message", "failure message"),
        ):
            data[var] = (
                ("evaluation",),
                np.array([str(rec[var])], dtype=object),
                {"long_name": long_name},
            )
        ds = xr.Dataset(data, attrs=self.attrs)
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="Consolidated metadata", category=UserWarning)
            if len(self.records) == 1:
                ds.to_zarr(self.out, zarr_format=3, mode="w-", consolidated=True)
            else:
                ds.to_zarr(self.out, zarr_format=3, append_dim="evaluation", consolidated=True)

    def next_points(self, n: float, rec: dict[str, Any], fail_n: float, pass_n: float) -> Optional[float]:
        """The next point count to try after evaluating ``rec`` at ``n``, or None to stop:
        bisection in log N between the largest failing and the smallest passing count, else a
        step by P-V ∝ 1/N, doubling past a failed case, never beyond the capacity."""
        cap = float(self.capacity)
        if pass_n < math.inf and (fail_n > 0 and pass_n / fail_n < 1.05):
            return None
        if pass_n == math.inf and n >= cap:
            return None  # the capacity is reached without meeting the tolerance
        if pass_n < math.inf and fail_n > 0:
            nxt = math.sqrt(pass_n * fail_n)
        elif self.ok(rec):
            nxt = n * rec["pv_nm"] / self.tol * (1.05 if rec["pv_nm"] > self.tol else 0.95)
        else:
            nxt = n * 2.0
        nxt = min(max(nxt, 1000.0), cap)
        return None if abs(nxt - n) < 0.01 * n and n >= cap else nxt

    def search_points(
        self, n: float, aspect: float, rec: dict[str, Any], factor: float, max_rounds: int
    ) -> None:
        """Raise or lower the point count until the tolerance is met with as few points as
        the rounds allow, refining the aspect ratio by ``factor`` at each new count."""
        fail_n, pass_n = 0.0, math.inf
        for _ in range(max_rounds):
            if self.ok(rec) and rec["pv_nm"] <= self.tol:
                pass_n = min(pass_n, n)
            else:
                fail_n = max(fail_n, n)
            nxt = self.next_points(n, rec, fail_n, pass_n)
            if nxt is None:
                return
            n = nxt
            aspect, rec = self.refine_aspect(n, aspect, factor, 1)

    def best_meeting(self) -> Optional[dict[str, Any]]:
        meeting = [r for r in self.records if self.ok(r) and r["pv_nm"] <= self.tol]
        return min(meeting, key=lambda r: (r["n_points"], r["pv_nm"])) if meeting else None

    def best(self) -> Optional[dict[str, Any]]:
        valid = [r for r in self.records if self.ok(r)]
        return min(valid, key=lambda r: r["pv_nm"]) if valid else None


def optimize(
    surface: str,
    layout: Optional[str],
    tolerance_nm: float,
    out: Optional[Path] = None,
    start_points: float = 50_000,
    machine: str = "fts-1m",
    cutting: str = "reference",
    compensation: str = "exact",
    resolution: Optional[Resolution] = None,
    restart: bool = False,
    catalog_folder: Optional[Path] = None,
    on_eval: Optional[Callable[[dict[str, Any]], None]] = None,
    max_rounds: int = 8,
) -> dict[str, Any]:
    """Find the smallest layout meeting ``tolerance_nm``; returns the answer and the log."""
    spec = catalogs.entry("surfaces", surface, catalog_folder)
    layout = layout or spec.layout
    if not tolerance_nm > 0:
        raise ValueError(f"the tolerance must be positive, got {tolerance_nm}")
    out = Path(out) if out else Path("outputs") / f"optimize-{surface}-{layout}.zarr"
    out = out.absolute()
    with cube_lock(out, f"ftsweep optimize {surface}"):
        if out.exists():
            if not restart:
                raise CubeError(f"{out} exists; give --restart to replace it or choose another --out")
            shutil.rmtree(out)
        out.parent.mkdir(parents=True, exist_ok=True)
        opt = Optimizer(
            surface,
            layout,
            tolerance_nm,
            out,
            machine,
            cutting,
            compensation,
            resolution or Resolution(),
            catalog_folder,
            on_eval,
        )
        lo, hi = ASPECT_RANGE[layout]
        cap = opt.capacity
        n = min(float(start_points), float(cap))
        aspect, rec = opt.best_aspect(n, np.geomspace(lo, hi, 9), "scan")
        ratio = (hi / lo) ** (1 / 8)
        aspect, rec = opt.refine_aspect(n, aspect, math.sqrt(ratio), 3)
        opt.search_points(n, aspect, rec, ratio**0.25, max_rounds)

        answer = opt.best_meeting()
        return {
            "met": answer is not None,
            "answer": answer if answer is not None else opt.best(),
            "evaluations": len(opt.records),
            "cube": str(out),
            "tolerance_nm": tolerance_nm,
            "capacity_points": cap,
        }
