"""The conformance suite of the program-kind contract, zarr's ``StoreTests`` pattern: every
kind passes the same tests. A kind's package (this one's in ``tests/kinds/test_conformance.py``, a
plug-in's in its own tests) subclasses :class:`KindTests` once per kind, naming a one-case
sweep, and pytest runs the whole suite for it: plan → simulate → export → verify round trip,
programs in controllers' dialects, the record holds exactly the kind's declared fields, a
case's key is stable through its spec's serialisation, threads give the same record, and a
finished sweep resumes with nothing computed. It needs pytest (the ``test`` extra).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, NamedTuple, Optional

import pytest
import xarray as xr
from click.testing import CliRunner

from ftsweep import registry
from ftsweep.cli.main import main
from ftsweep.engine import result
from ftsweep.engine.case import Case
from ftsweep.exports import dialects
from ftsweep.simulate import run_case
from ftsweep.sweeps.run import run_sweep
from ftsweep.sweeps.spec import case_at, load_sweep
from ftsweep.tools.export import format_of_kind, formats
from ftsweep.tools.select import open_cube, recorded_case

__all__ = ["KindTests"]


class Cube(NamedTuple):
    """The one-case sweep of a kind: its spec file, its cube and the catalog folder it read
    (None: the installed catalogs or ``FTSWEEP_CATALOGS``)."""

    spec: Path
    out: Path
    folder: Optional[Path]


def _env(folder: Optional[Path]) -> dict[str, str]:
    """The environment of a command reading the sweep's catalogs."""
    return {} if folder is None else {"FTSWEEP_CATALOGS": str(folder)}


class KindTests:
    """Every program kind passes these; subclasses set ``kind``, ``sweep`` (YAML of a
    one-case sweep) and ``suffix`` (the exported file's), and may override the
    ``catalog_folder`` fixture."""

    kind: str
    sweep: str
    suffix = ".txt"

    @pytest.fixture(scope="class")
    @classmethod
    def catalog_folder(cls) -> Optional[Path]:
        """The catalog folder the sweep reads (None: ``FTSWEEP_CATALOGS`` or the installed
        catalogs); a subclass overrides this fixture to point at its own."""
        return None

    @pytest.fixture(scope="class")
    @classmethod
    def cube(cls, tmp_path_factory: pytest.TempPathFactory, catalog_folder: Optional[Path]) -> Cube:
        """The one-case sweep of :attr:`sweep`, run synchronously into a cube."""
        folder = tmp_path_factory.mktemp(cls.__name__)
        spec = folder / "one.yaml"
        spec.write_text(cls.sweep)
        out = folder / "one.zarr"
        report = run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_folder)
        assert report.done == 1, report.rows
        return Cube(spec, out, catalog_folder)

    def test_the_kind_is_registered_and_has_a_file_format(self) -> None:
        entry = registry.kind(self.kind)
        assert entry.name == self.kind and entry.axes and entry.fields
        assert format_of_kind(self.kind) in formats()

    def test_its_sweep_cases_ask_the_kind(self, cube: Cube) -> None:
        spec_path, _, folder = cube
        _, spec = load_sweep(str(spec_path), folder)
        case = case_at(spec, 0)
        assert case.layout.kind == self.kind
        kind, surface = registry.kind(self.kind), _surface(case, folder)
        cutting = _cutting(case, folder)
        feed = kind.feed(case, cutting, case.nose_radius_of(cutting), surface, folder, None)
        cost, _ = kind.cost(case, surface, folder, feed)
        assert cost > 0

    def test_a_case_key_is_stable_through_its_spec(self, cube: Cube) -> None:
        _, out, _ = cube
        case, _ = recorded_case(open_cube(out), 0)
        again = Case.model_validate_json(case.model_dump_json())
        assert again.key() == case.key() and again == case

    @pytest.fixture(scope="class")
    @classmethod
    def record(cls, cube: Cube) -> dict[str, Any]:
        """The sweep's case run in this process, in batches of 20,000 nodes, on one thread."""
        spec_path, _, folder = cube
        _, spec = load_sweep(str(spec_path), folder)
        return run_case(case_at(spec, 0), folder, batch_nodes=20_000)

    def test_the_record_holds_exactly_the_declared_fields(self, cube: Cube, record: dict[str, Any]) -> None:
        """The case's record has the kind's declared fields, in their declared order, and the
        cube the variables stored of them, none of another kind's."""
        names = result.result_names(registry.kind(self.kind))
        assert list(record) == [n for n in names if n in record] and set(record) == set(names)
        _, out, _ = cube
        ds = xr.open_zarr(out)
        declared = set(result.stored(registry.kind(self.kind)))
        others = set().union(*(result.stored(k) for k in registry.kinds().values())) - declared
        assert declared <= set(ds.data_vars) and not others & set(ds.data_vars)
        assert float(ds["pv_nm"].values.ravel()[0]) > 0

    def test_plan_simulate_export_verify_round_trip(self, cube: Cube, tmp_path: Path) -> None:
        _, out, folder = cube
        path = tmp_path / f"part{self.suffix}"
        res = CliRunner().invoke(main, ["export", str(out), "--case", "0", "-o", str(path)], env=_env(folder))
        assert res.exit_code == 0, res.output
        res = CliRunner().invoke(main, ["verify", str(path), "--json"], env=_env(folder))
        assert res.exit_code == 0, res.output
        record = json.loads(res.stdout)
        assert record["layout"] == self.kind
        assert abs(record["pv_nm"] - record["predicted_pv_nm"]) <= record["pv_tolerance_nm"]

    @pytest.mark.parametrize("dialect", ["iso-sts", "linuxcnc", "pmac-pvt"])
    def test_its_programs_go_out_in_controller_dialects_and_verify(
        self, cube: Cube, tmp_path: Path, dialect: str
    ) -> None:
        """A path kind with a dialect adapter exports a program its strict reader reads back
        and verify passes, the P-V as written within 1 % of the cube's; a dialect whose
        interpolation is not the machine's and a kind without an adapter are refused by name."""
        _, out, folder = cube
        env = _env(folder)
        path = tmp_path / f"part-{dialect}.nc"
        res = CliRunner().invoke(
            main, ["export", str(out), "--case", "0", "--dialect", dialect, "-o", str(path)], env=env
        )
        ds = xr.open_zarr(out)
        case, _ = recorded_case(open_cube(out), 0)
        machine = _machine(case, folder)
        interpolation = machine.interpolation
        # a kind without programs in dialects is told so first: no machine would change that
        if registry.kind(self.kind).file_format().dialect is None:
            assert res.exit_code == 1 and "own format only" in res.output
            assert not path.exists()
            return
        if machine.controller is not None and machine.controller.dialect != dialect:
            assert res.exit_code == 1 and f"controller, which does not read {dialect}" in res.output
            assert not path.exists()
            return
        if dialects.INTERPOLATION[dialect] != interpolation:
            assert res.exit_code == 1 and f"interpolates {interpolation}" in res.output
            assert not path.exists()
            return
        assert res.exit_code == 0, res.output
        res = CliRunner().invoke(main, ["verify", str(path), "--json"], env=env)
        assert res.exit_code == 0, res.output
        record = json.loads(res.stdout)
        assert record["dialect"] == dialect and record["layout"] == self.kind
        assert record["pv_nm"] == pytest.approx(float(ds["pv_nm"].values.ravel()[0]), rel=0.01)

    def test_the_same_case_exported_twice_is_the_same_file(
        self, cube: Cube, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
    ) -> None:
        """Exports at two different times: the exported file is the same, byte for byte (its
        sidecar differs in its time stamp and its sequence in the cube's export ledger alone),
        and the latest verifies as the latest."""
        import itertools
        import time

        _, out, folder = cube
        clock = itertools.count(1_700_000_000, 3600)
        monkeypatch.setattr(time, "strftime", lambda fmt, t=None: time.asctime(time.gmtime(next(clock))))
        path, env = tmp_path / f"again{self.suffix}", _env(folder)
        files, sidecars = [], []
        for _ in range(2):
            args = ["export", str(out), "--case", "0", "-o", str(path), "--force"]
            res = CliRunner().invoke(main, args, env=env)
            assert res.exit_code == 0, res.output
            files.append(path.read_bytes())
            sidecars.append(json.loads(path.with_name(path.name + ".json").read_text()))
        assert files[0] == files[1]
        assert sidecars[0]["created"] != sidecars[1]["created"]
        assert sidecars[1]["ledger"]["sequence"] == sidecars[0]["ledger"]["sequence"] + 1
        stamps = ("created", "ledger")
        assert {k: v for k, v in sidecars[0].items() if k not in stamps} == {
            k: v for k, v in sidecars[1].items() if k not in stamps
        }
        res = CliRunner().invoke(main, ["verify", str(path), "--json"], env=env)
        assert res.exit_code == 0, res.output
        assert json.loads(res.stdout)["latest"].startswith(f"the latest export of {path.name}")

    def test_select_and_report_read_its_cube(self, cube: Cube, tmp_path: Path) -> None:
        _, out, folder = cube
        env = _env(folder)
        res = CliRunner().invoke(
            main, ["select", str(out), "--budget-points", "100000000", "--json"], env=env
        )
        assert res.exit_code == 0, res.output
        assert json.loads(res.stdout)["layout"] == self.kind
        res = CliRunner().invoke(
            main, ["report", str(out), "--out", str(tmp_path), "--map-bins", "16"], env=env
        )
        assert res.exit_code == 0, res.output
        assert (tmp_path / "index.html").stat().st_size > 0 and (
            tmp_path / "error_map.png"
        ).stat().st_size > 0

    def test_threads_give_the_same_record(self, cube: Cube, record: dict[str, Any]) -> None:
        """A case on several threads (batches in parallel, a table compensated in parts) is
        the same case: every field equal, value for value, to the one-thread record."""
        spec_path, _, folder = cube
        _, spec = load_sweep(str(spec_path), folder)
        case = case_at(spec, 0)
        totals: list[int] = []
        one = record
        many = run_case(case, folder, batch_nodes=20_000, threads=3, progress=lambda d, t: totals.append(t))
        assert totals and totals[-1] >= 2  # batches did run side by side
        values = {k for k in one if not k.startswith("seconds")}
        assert values == {k for k in many if not k.startswith("seconds")}
        differ = [k for k in values if json.dumps(one[k], default=str) != json.dumps(many[k], default=str)]
        assert not differ, differ

    def test_a_finished_sweep_resumes_with_nothing_computed(self, cube: Cube) -> None:
        spec_path, out, folder = cube
        report = run_sweep(str(spec_path), out, scheduler="synchronous", catalog_folder=folder)
        assert report.queued == 0 and not report.damaged and report.skipped == 1


def _cutting(case: Case, folder: Optional[Path]) -> Any:
    from ftsweep.inputs import catalogs

    return catalogs.entry("cutting", case.cutting, folder)


def _machine(case: Case, folder: Optional[Path]) -> Any:
    from ftsweep.inputs import catalogs

    return catalogs.entry("machines", case.machine, folder)


def _surface(case: Case, folder: Optional[Path]) -> Any:
    from ftsweep.inputs import catalogs

    return catalogs.entry("surfaces", case.surface, folder)
