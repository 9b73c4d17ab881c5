"""The tolerance loop of a shop: the smallest layout that meets a P-V tolerance.

Start coarse (a log scan of aspect ratios at a modest point count), refine around the best
aspect ratio by log-bisection, then change the point count. Bilinear error falls as the
square of the pitch, so P-V ∝ 1/N and the next count is N·P-V/T (with a small margin),
capped at the controller's capacity. Once one count meets the tolerance and a smaller one
does not, a bisection between them finds the smallest that does. Every evaluation is
written to a one-dimensional cube (dimension ``evaluation``) as soon as it finishes, through
the store protocol of sweeps (:mod:`ftsweep.store.cube`): an atomically created template with one
chunk per evaluation (as many slots as the search can take, unused ones stay pending), status
flags written last, the catalog entries used, and resume: re-running the same search on its
cube reuses every finished evaluation and computes only the rest.
"""

from __future__ import annotations

import hashlib
import json
import math
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any, Optional

import numpy as np
import xarray as xr

from ftsweep import registry
from ftsweep.engine.case import Case, CaseError, Resolution, program_request
from ftsweep.inputs import catalogs
from ftsweep.simulate import run_case
from ftsweep.store import cube
from ftsweep.store.cube import SCHEMA_VERSION, CubeError, CubeWriter
from ftsweep.store.lock import cube_lock
from ftsweep.store.storage import PathLike, Place, place
from ftsweep.sweeps.spec import axis_attrs
from ftsweep.version import __version__, git_revision


def _aspect_range(layout: str) -> tuple[float, float]:
    """The aspect ratios a search spans (the kind's; tables only)."""
    span = registry.kind(layout).aspect_range
    if span is None:
        raise ValueError(
            f"optimize searches aspect ratios of tables (ring, mesh); a {layout} program has none"
        )
    return span


def _key(points: float, aspect: float) -> tuple[int, float]:
    return int(points), round(float(aspect), 9)


def _optimize_attrs(path: PathLike, any_version: bool = False) -> dict[str, Any]:
    """Attributes of an existing evaluation cube; anything else at ``path`` is never replaced."""
    try:
        attrs = dict(cube.open_group(path).attrs)
    except Exception:  # zarr raises several types for "not a group"
        attrs = {}
    if attrs.get("kind") != "optimize":
        raise CubeError(f"{path} exists and is not an ftsweep evaluation cube; choose another --out")
    if not any_version and attrs.get("ftsweep_cube_schema") != SCHEMA_VERSION:
        raise CubeError(f"{path} was written by an older ftsweep; give --restart to recompute it")
    return attrs


def _changed(old_json: Any, new: dict[str, Any]) -> str:
    old = json.loads(old_json) if isinstance(old_json, str) else {}
    return ", ".join(sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))) or "the search"


def max_evaluations(max_rounds: int) -> int:
    """Evaluations a search can take: the 9-point scan, 3 refinement steps of 2, and per round
    of point counts one new count refined by one step (3)."""
    return 9 + 2 * 3 + 3 * max_rounds


class Optimizer:
    """Runs and records evaluations; ``best_meeting`` and ``best`` read the record."""

    def __init__(
        self,
        surface: str,
        layout: str,
        tolerance_nm: float,
        out: Place,
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
        self.run_id = f"{time.strftime('%Y%m%dT%H%M%S')}-{uuid.uuid4().hex[:8]}"
        self.writer: Optional[CubeWriter] = None

    def open_store(self, spec: dict[str, Any], slots: int, restart: bool) -> int:
        """Create the evaluation cube, or resume the one of the same search (``spec``): its
        finished evaluations fill the cache and the record. Returns how many were reused."""
        spec_json = json.dumps(spec, sort_keys=True)
        spec_hash = hashlib.sha256(spec_json.encode()).hexdigest()[:16]
        if cube.unfinished(self.out):  # its writer was killed while creating it
            self.out.remove_all()
        if self.out.exists():
            attrs = _optimize_attrs(self.out, any_version=restart)
            if restart:
                self.out.remove_all()
            elif attrs.get("optimize_spec_hash") != spec_hash:
                changed = _changed(attrs.get("optimize_spec"), spec)
                raise CubeError(
                    f"{self.out} holds another search (changed: {changed}); give --restart to replace "
                    "it or choose another --out"
                )
        if not self.out.exists():
            entries = catalogs.recorded_entries(self.surface, self.machine, self.cutting, self.folder)
            cube.create(self.out, self._template(slots, spec_json, spec_hash, entries))
        self.writer = CubeWriter(self.out)
        return self._load_finished()

    def _template(self, slots: int, spec_json: str, spec_hash: str, entries: dict[str, Any]) -> xr.Dataset:
        dims, shape = ("evaluation",), (slots,)
        data = cube.case_variables(dims, shape, self.layout)
        aspect_units = axis_attrs("aspect", self.layout)["units"]
        for var, units, long_name in (
            ("points_target", "1", "target number of control points"),
            ("aspect_target", aspect_units, "target aspect ratio"),
        ):
            data[var] = (dims, np.full(shape, np.nan), {"units": units, "long_name": long_name})
        for var, long_name in (
            ("stage", "loop stage of the evaluation"),
            ("record_json", "the evaluation's full record (JSON)"),
        ):
            data[var] = (dims, np.full(shape, "", dtype=object), {"long_name": long_name})
        order = ("evaluation", np.arange(slots), {"units": "1", "long_name": "evaluation order"})
        ds = xr.Dataset(data, coords={"evaluation": order})
        ds.attrs.update(
            ftsweep_version=__version__,
            git_revision=git_revision(),
            kind="optimize",
            surface=self.surface,
            layout_method=self.layout,
            ftsweep_cube_schema=SCHEMA_VERSION,
            tolerance_nm=self.tol,
            machine=self.machine,
            cutting=self.cutting,
            compensation=self.compensation,
            resolution=json.dumps(self.resolution.model_dump(mode="json")),
            optimize_spec=spec_json,
            optimize_spec_hash=spec_hash,
            catalog_entries=json.dumps(entries, sort_keys=True),
            status_meanings=cube.STATUS_MEANINGS,
            created=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        )
        return ds

    def _load_finished(self) -> int:
        status = cube.read_status(self.out)
        texts = np.asarray(cube.open_group(self.out)["record_json"][...])  # type: ignore[index]
        for i in np.flatnonzero(status != cube.PENDING):
            rec = json.loads(str(texts[i]))
            self.cache[_key(rec["points_target"], rec["aspect_target"])] = rec
            self.records.append(rec)
        return len(self.records)

    def evaluate(self, points: float, aspect: float, stage: str) -> dict[str, Any]:
        key = _key(points, aspect)
        if key in self.cache:
            return self.cache[key]
        case = Case(
            surface=self.surface,
            layout=program_request(kind=self.layout, points=points, aspect=aspect),
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
        self._store(len(self.records) - 1, rec)
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

    def _store(self, slot: int, rec: dict[str, Any]) -> None:
        """Write evaluation ``slot`` into its chunk of the cube, status last."""
        assert self.writer is not None, "open_store() first"
        if slot >= self.writer.shape[0]:
            raise CubeError(
                f"the search took more than the {self.writer.shape[0]} evaluations its cube holds"
            )
        plain = {k: v for k, v in rec.items() if not isinstance(v, np.ndarray)}
        self.writer.write_values(
            slot,
            {
                "points_target": rec["points_target"],
                "aspect_target": rec["aspect_target"],
                "stage": rec["stage"],
                "record_json": json.dumps(plain, default=float),
            },
        )
        if rec["status"] == "done":
            self.writer.write_done(slot, rec, self.run_id)
        else:
            self.writer.write_failed(slot, rec["message"], self.run_id)

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


def _search_record(opt: Optimizer, start_points: float, max_rounds: int, seed: str) -> dict[str, Any]:
    """What identifies a search (its evaluation cube resumes only the same one)."""
    search = {
        "surface": opt.surface,
        "layout": opt.layout,
        "tolerance_nm": opt.tol,
        "start_points": start_points,
        "machine": opt.machine,
        "cutting": opt.cutting,
        "compensation": opt.compensation,
        "resolution": opt.resolution.model_dump(mode="json"),
        "max_rounds": max_rounds,
    }
    if seed != "scan":  # the default stays out, so earlier evaluation cubes still resume
        search["seed"] = seed
    return search


def _seeded(
    opt: Optimizer, spec: Any, seed: str, start_points: float, ratio: float
) -> tuple[float, float, Any]:
    """The point count, aspect ratio and record the point-count search starts from: a log scan
    of nine aspect ratios at ``start_points`` refined around the best (``scan``), or the
    layout the kind's ``seed`` (its first-order estimate) predicts for the tolerance, refined
    (``estimate``)."""
    lo, hi = _aspect_range(opt.layout)
    cap = float(opt.capacity)
    if seed == "estimate":
        from ftsweep.stages.layouts.estimate import cusp_nm

        own = registry.kind(opt.layout)
        if not own.estimates:
            raise ValueError(f"a {registry.noun(opt.layout)} has no estimate to seed the search: --seed scan")
        cut = catalogs.entry("cutting", opt.cutting, opt.folder)
        cusp = cusp_nm(cut.feed_um, cut.nose_radius_um)
        n, aspect, _ = own.seed(spec, opt.tol, int(cap), cusp, (lo, hi), opt.folder)
        n = min(n, cap)
        aspect, rec = opt.refine_aspect(n, aspect, math.sqrt(ratio), 2)
        return n, aspect, rec
    n = min(start_points, cap)
    aspect, rec = opt.best_aspect(n, np.geomspace(lo, hi, 9), "scan")
    aspect, rec = opt.refine_aspect(n, aspect, math.sqrt(ratio), 3)
    return n, aspect, rec


def optimize(
    surface: str,
    layout: Optional[str],
    tolerance_nm: float,
    out: Optional[PathLike] = None,
    start_points: float = 50_000,
    machine: str = "fts-1m",
    cutting: str = "reference",
    compensation: str = "exact",
    resolution: Optional[Resolution] = None,
    restart: bool = False,
    catalog_folder: Optional[Path] = None,
    on_eval: Optional[Callable[[dict[str, Any]], None]] = None,
    max_rounds: int = 8,
    seed: str = "scan",
) -> dict[str, Any]:
    """Find the smallest layout meeting ``tolerance_nm``; returns the answer and the log.

    ``seed``: ``scan`` starts with a log scan of nine aspect ratios at ``start_points``;
    ``estimate`` starts at the point count and aspect ratio
    the kind's ``seed`` (its first-order estimate) predicts for the tolerance (no
    simulation), refined from there.
    """
    if seed not in ("scan", "estimate"):
        raise ValueError(f"unknown seed {seed!r}; expected 'scan' or 'estimate'")
    spec = catalogs.entry("surfaces", surface, catalog_folder)
    layout = layout or spec.layout
    _aspect_range(layout)  # a path program has no aspect search: said before anything is written
    if not tolerance_nm > 0:
        raise ValueError(f"the tolerance must be positive, got {tolerance_nm}")
    out = place(out if out else Path("outputs") / f"optimize-{surface}-{layout}.zarr")
    with cube_lock(out, f"ftsweep optimize {surface}"):
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
        search = _search_record(opt, float(start_points), max_rounds, seed)
        reused = opt.open_store(search, max_evaluations(max_rounds), restart)
        lo, hi = _aspect_range(layout)
        ratio = (hi / lo) ** (1 / 8)
        n, aspect, rec = _seeded(opt, spec, seed, float(start_points), ratio)
        opt.search_points(n, aspect, rec, ratio**0.25, max_rounds)
        answer = opt.best_meeting()
        return {
            "met": answer is not None,
            "answer": answer if answer is not None else opt.best(),
            "evaluations": len(opt.records),
            "reused": reused,
            "cube": str(out),
            "tolerance_nm": tolerance_nm,
            "capacity_points": opt.capacity,
        }
