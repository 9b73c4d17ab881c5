"""The conformance suite of the program-kind contract (zarr's ``StoreTests``
pattern): one subclass per registered kind (and per spiral rule and layered wrapper), each
naming a one-case sweep; every subclass runs the same tests. Plan → simulate → export →
verify round trip, the record holds exactly the kind's declared fields, a case's key is
stable through its spec's serialisation, and a finished sweep resumes with nothing computed.
Adding a kind adds one subclass here."""

from __future__ import annotations

import json

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


class KindTests:
    """Every program kind passes these; subclasses set ``kind``, ``sweep`` (YAML of a
    one-case sweep) and ``suffix`` (the exported file's)."""

    kind: str
    sweep: str
    suffix = ".txt"

    @pytest.fixture(scope="class")
    @classmethod
    def cube(cls, tmp_path_factory, module_catalog_dir):
        folder = tmp_path_factory.mktemp(cls.__name__)
        spec = folder / "one.yaml"
        spec.write_text(cls.sweep)
        out = folder / "one.zarr"
        report = run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=module_catalog_dir)
        assert report.done == 1, report.rows
        return spec, out, module_catalog_dir

    def test_the_kind_is_registered_and_has_a_file_format(self):
        entry = registry.kind(self.kind)
        assert entry.name == self.kind and entry.axes and entry.fields
        assert format_of_kind(self.kind) in formats()

    def test_its_sweep_cases_ask_the_kind(self, cube):
        spec_path, _, folder = cube
        _, spec = load_sweep(str(spec_path), folder)
        case = case_at(spec, 0)
        assert case.layout.kind == self.kind
        kind, surface = registry.kind(self.kind), _surface(case, folder)
        cutting = _cutting(case, folder)
        feed = kind.feed(case, cutting, case.nose_radius_of(cutting), surface, folder, None)
        cost, _ = kind.cost(case, surface, folder, feed)
        assert cost > 0

    def test_a_case_key_is_stable_through_its_spec(self, cube):
        _, out, _ = cube
        case, _ = recorded_case(open_cube(out), 0)
        again = Case.model_validate_json(case.model_dump_json())
        assert again.key() == case.key() and again == case

    def test_the_record_holds_exactly_the_declared_fields(self, cube):
        _, out, _ = cube
        ds = xr.open_zarr(out)
        declared = set(result.stored(registry.kind(self.kind)))
        others = set().union(*(result.stored(k) for k in registry.kinds().values())) - declared
        assert declared <= set(ds.data_vars) and not others & set(ds.data_vars)
        assert float(ds["pv_nm"].values.ravel()[0]) > 0

    def test_plan_simulate_export_verify_round_trip(self, cube, tmp_path):
        _, out, folder = cube
        path = tmp_path / f"part{self.suffix}"
        res = CliRunner().invoke(
            main, ["export", str(out), "--case", "0", "-o", str(path)], env={"FTSWEEP_CATALOGS": str(folder)}
        )
        assert res.exit_code == 0, res.output
        res = CliRunner().invoke(main, ["verify", str(path), "--json"], env={"FTSWEEP_CATALOGS": str(folder)})
        assert res.exit_code == 0, res.output
        record = json.loads(res.stdout)
        assert record["layout"] == self.kind
        assert abs(record["pv_nm"] - record["predicted_pv_nm"]) <= record["pv_tolerance_nm"]

    @pytest.mark.parametrize("dialect", ["iso-sts", "linuxcnc", "pmac-pvt"])
    def test_its_programs_go_out_in_controller_dialects_and_verify(self, cube, tmp_path, dialect):
        """A path kind with a dialect adapter exports a program its strict reader reads back
        and verify passes, the P-V as written within 1 % of the cube's; a dialect whose
        interpolation is not the machine's and a kind without an adapter are refused by name."""
        _, out, folder = cube
        env = {"FTSWEEP_CATALOGS": str(folder)}
        path = tmp_path / f"part-{dialect}.nc"
        res = CliRunner().invoke(
            main, ["export", str(out), "--case", "0", "--dialect", dialect, "-o", str(path)], env=env
        )
        ds = xr.open_zarr(out)
        case, _ = recorded_case(open_cube(out), 0)
        interpolation = _machine(case, folder).interpolation
        if dialects.INTERPOLATION[dialect] != interpolation:
            assert res.exit_code == 1 and f"interpolates {interpolation}" in res.output
            assert not path.exists()
            return
        if registry.kind(self.kind).file_format().dialect is None:
            assert res.exit_code == 1 and "own format only" in res.output
            assert not path.exists()
            return
        assert res.exit_code == 0, res.output
        res = CliRunner().invoke(main, ["verify", str(path), "--json"], env=env)
        assert res.exit_code == 0, res.output
        record = json.loads(res.stdout)
        assert record["dialect"] == dialect and record["layout"] == self.kind
        assert record["pv_nm"] == pytest.approx(float(ds["pv_nm"].values.ravel()[0]), rel=0.01)

    def test_the_same_case_exported_twice_is_the_same_file(self, cube, tmp_path, monkeypatch):
        """Exports at two different times: the exported file is the same, byte for byte (its
        sidecar differs in its time stamp alone), and both verify."""
        import itertools
        import time

        _, out, folder = cube
        clock = itertools.count(1_700_000_000, 3600)
        monkeypatch.setattr(time, "strftime", lambda fmt, t=None: time.asctime(time.gmtime(next(clock))))
        path, env = tmp_path / f"again{self.suffix}", {"FTSWEEP_CATALOGS": str(folder)}
        files, sidecars = [], []
        for _ in range(2):
            args = ["export", str(out), "--case", "0", "-o", str(path), "--force"]
            res = CliRunner().invoke(main, args, env=env)
            assert res.exit_code == 0, res.output
            files.append(path.read_bytes())
            sidecars.append(json.loads(path.with_name(path.name + ".json").read_text()))
        assert files[0] == files[1]
        assert sidecars[0]["created"] != sidecars[1]["created"]
        assert {k: v for k, v in sidecars[0].items() if k != "created"} == {
            k: v for k, v in sidecars[1].items() if k != "created"
        }
        res = CliRunner().invoke(main, ["verify", str(path), "--json"], env=env)
        assert res.exit_code == 0, res.output

    def test_select_and_report_read_its_cube(self, cube, tmp_path):
        _, out, folder = cube
        env = {"FTSWEEP_CATALOGS": str(folder)}
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

    def test_threads_give_the_same_record(self, cube):
        """A case on several threads (batches in parallel, a table compensated in parts) is
        the same case: every field equal, value for value, to the one-thread record."""
        spec_path, _, folder = cube
        _, spec = load_sweep(str(spec_path), folder)
        case = case_at(spec, 0)
        totals = []
        one = run_case(case, folder, batch_nodes=20_000)
        many = run_case(case, folder, batch_nodes=20_000, threads=3, progress=lambda d, t: totals.append(t))
        assert totals and totals[-1] >= 2  # batches did run side by side
        values = {k for k in one if not k.startswith("seconds")}
        assert values == {k for k in many if not k.startswith("seconds")}
        differ = [k for k in values if json.dumps(one[k], default=str) != json.dumps(many[k], default=str)]
        assert not differ, differ

    def test_a_finished_sweep_resumes_with_nothing_computed(self, cube):
        spec_path, out, folder = cube
        report = run_sweep(str(spec_path), out, scheduler="synchronous", catalog_folder=folder)
        assert report.queued == 0 and not report.damaged and report.skipped == 1


def _cutting(case: Case, folder):  # type: ignore[no-untyped-def]
    from ftsweep.inputs import catalogs

    return catalogs.entry("cutting", case.cutting, folder)


def _machine(case: Case, folder):  # type: ignore[no-untyped-def]
    from ftsweep.inputs import catalogs

    return catalogs.entry("machines", case.machine, folder)


def _surface(case: Case, folder):  # type: ignore[no-untyped-def]
    from ftsweep.inputs import catalogs

    return catalogs.entry("surfaces", case.surface, folder)


class TestRing(KindTests):
    kind = "ring"
    suffix = ".h"
    sweep = "surface: small_sine\nlayout: ring\naxes: {points: [15000], aspect: [4.0]}\n"


class TestMesh(KindTests):
    kind = "mesh"
    suffix = ".h"
    sweep = "surface: small_lens\nlayout: mesh\naxes: {points: [12000], aspect: [1.0]}\n"


class TestLayeredTable(KindTests):
    kind = "ring"
    suffix = ".h"
    sweep = "surface: small_sine\nlayout: ring\nmachine: short-fts\naxes: {points: [15000], aspect: [4.0]}\n"


class TestSpiralAngle(KindTests):
    kind = "spiral"
    sweep = "surface: small_sine\nlayout: spiral\naxes: {points_per_rev: [60]}\n"


class TestSpiralArc(KindTests):
    kind = "spiral"
    sweep = "surface: small_sine\nlayout: spiral\naxes: {arc_um: [20.0]}\n"


class TestSpiralChord(KindTests):
    kind = "spiral"
    sweep = "surface: small_sine\nlayout: spiral\naxes: {chord_um: [0.05]}\n"


class TestLayeredSpiral(KindTests):
    kind = "spiral"
    sweep = "surface: small_sine\nlayout: spiral\nmachine: short-fts\naxes: {points_per_rev: [60]}\n"


class TestDPath(KindTests):
    kind = "dpath"
    sweep = (
        "surface: concave_sphere\nlayout: dpath\nmachine: sts-xzc\ncutting: dpath-finish\n"
        "dpath: {transition: optimised}\naxes: {spacing_um: [500.0], points_per_cut: [41]}\n"
    )


class TestDPathPvt(KindTests):
    kind = "dpath"
    sweep = (
        "surface: concave_sphere\nlayout: dpath\nmachine: xzc-pmac-pvt\ncutting: dpath-finish\n"
        "axes: {spacing_um: [500.0], points_per_cut: [41]}\n"
    )


class TestFresnelPvt(KindTests):
    kind = "fresnel"
    sweep = (
        "surface: chebyshev_example\nlayout: fresnel\nmachine: xyzc-pmac-pvt\ncutting: fresnel-finish\n"
        "axes: {facet_height_um: [10.0], points_per_turn: [60], feed_um: [8.0]}\n"
    )


class TestFresnel(KindTests):
    kind = "fresnel"
    sweep = (
        "surface: chebyshev_example\nlayout: fresnel\nmachine: xyzc-nanoform\ncutting: fresnel-finish\n"
        "axes: {facet_height_um: [10.0], points_per_turn: [60], feed_um: [8.0]}\n"
    )


def test_every_registered_kind_has_a_conformance_subclass():
    covered = {cls.kind for cls in KindTests.__subclasses__()}
    assert set(registry.kinds()) <= covered
