"""``ftsweep bench`` prints its tables and writes its JSON; it measures and asserts nothing
about time (these tests check the rows exist and hold real figures)."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from ftsweep.cli.main import main
from ftsweep.engine.case import Case, program_request
from ftsweep.tools.bench import (
    against_reference,
    format_against_reference,
    format_whole_process,
    whole_process,
    whole_process_rows,
)


def test_bench_prints_a_row_per_case_and_writes_json(tmp_path):
    out = tmp_path / "bench.json"
    r = CliRunner().invoke(
        main, ["bench", "--case", "sinewave-ring-1.00deg", "--case", "lens-mesh-8um", "--json", str(out)]
    )
    assert r.exit_code == 0, r.output
    assert "sinewave-ring-1.00deg" in r.output and "lens-mesh-8um" in r.output
    data = json.loads(out.read_text())
    assert [row["case"] for row in data["rows"]] == ["sinewave-ring-1.00deg", "lens-mesh-8um"]
    assert all(row["seconds"] > 0 and row["pv_nm"] > 0 for row in data["rows"])


def test_an_unknown_case_is_named():
    r = CliRunner().invoke(main, ["bench", "--case", "nope"])
    assert r.exit_code != 0 and "unknown benchmark case(s) ['nope']" in r.output


def test_whole_process_rows_time_real_commands():
    rows = whole_process(1, ["ftsweep --help", "predict 5k-point ring"])
    assert [r["command"] for r in rows] == ["ftsweep --help", "predict 5k-point ring"]
    assert all(r["seconds"] > 0 for r in rows)
    assert rows[1]["case_seconds"] > 0  # a predict reports its case's own seconds
    assert "predict 5k-point ring" in format_whole_process(rows)


def test_the_whole_process_table_says_when_modules_had_no_bytecode(monkeypatch):
    import ftsweep.tools.bench as bench

    rows = [{"command": "ftsweep --help", "seconds": 0.1, "case_seconds": float("nan")}]
    monkeypatch.setattr(bench, "has_bytecode", lambda: False)
    assert "compiled them from source" in format_whole_process(rows)
    monkeypatch.setattr(bench, "has_bytecode", lambda: True)
    assert "compiled them from source" not in format_whole_process(rows)


@pytest.mark.slow
def test_the_verify_row_checks_an_exported_header():
    name = next(n for n, row in whole_process_rows().items() if row.args[0] == "verify")
    (row,) = whole_process(1, [name])
    assert row["seconds"] > row["case_seconds"] > 0  # verify re-simulated the case


@pytest.mark.slow
def test_the_dpath_verify_row_checks_an_exported_program():
    (row,) = whole_process(1, ["verify 1M-line D-path program"])
    assert row["seconds"] > row["case_seconds"] > 0  # verify re-simulated the program's part


@pytest.mark.slow  # 7-15 s on 2 cores: the full command runs it, the quick one leaves it out
def test_cube_scale_counts_objects_and_times_open_and_select(tmp_path):
    """A synthetic cube in blocks holds a few objects per variable, and its
    every case reads back as written (select picks one of them)."""
    from ftsweep.store import cube
    from ftsweep.tools.cubescale import build, measure, synthetic_spec

    where = tmp_path / "synthetic.zarr"
    made = build(where, 5000)
    assert made["cases"] == 5000
    status = cube.read_status(where)
    assert status.shape == (50, 100) and (status == cube.DONE).all()
    row = measure(where)
    variables = len(list(cube.open_group(where).arrays()))
    # one chunk of metadata and at most two blocks per array (5,000 cases, blocks of 4,096)
    assert variables < row["objects"] <= 3 * variables + 2
    assert row["open_s"] > 0 and row["select_s"] >= 0 and row["select_command_s"] > row["open_s"]
    assert 0 <= row["index"] < 5000
    assert synthetic_spec(100_000).axes.aspect is not None


# ----------------------------------------------------------------------------- documented times
def test_every_time_the_readme_documents_is_found_with_the_command_that_measures_it():
    from ftsweep.tools.documented import documented_times, readme_text

    readme, where = readme_text()
    assert where.endswith("README.md")  # the checkout's own, beside this editable install
    rows = documented_times(readme)
    labels = [r.label for r in rows]
    # the quickstart's sweep → status → export → verify, each with its figure, then the compile pair
    for step in ("ftsweep sweep sinewave-ring", "ftsweep status", "ftsweep export", "ftsweep verify"):
        assert any(label.startswith(step) for label in labels), (step, labels)
    assert all(r.seconds is not None and r.seconds > 0 for r in rows), rows
    tour = "ftsweep predict --surface sinewave2d --layout ring --drho-um 2 --dtheta-deg 0.5"
    assert [r.command for r in rows[-2:]] == [tour, tour]  # the tour's first "$ " line


def test_a_figure_the_text_no_longer_states_shows_as_missing():
    from ftsweep.tools.documented import documented_times, format_documented

    rows = documented_times("# ftsweep\n\n## Quickstart\n\n```bash\nftsweep --help   # the help\n```\n")
    assert rows[0].seconds is None and rows[0].command is None
    table = format_documented([{**r._asdict(), "measured": None} for r in rows])
    assert "the quickstart's timed ftsweep lines" in table and "—" in table


def test_documented_times_are_measured_beside_the_written_figures(tmp_path, monkeypatch):
    """The runner on a stand-in README (two quick commands): each row measured in its own fresh
    folder, the compile figure the first predict recorded against the difference of the pair."""
    from ftsweep.tools import documented
    from ftsweep.tools.bench import ftsweep_command

    readme = (
        "## Quickstart\n\n```bash\nftsweep --help       # the commands: 1.5 s\n```\n\n"
        "a first `predict` of a ring: 12 s against 1 s once cached\n\n## A short tour\n\n```\n"
        "$ ftsweep predict --surface sinewave2d --drho-um 50 --dtheta-deg 10\n```\n"
    )
    rows = documented.measure(documented.documented_times(readme), " ".join(ftsweep_command()))
    assert [r["seconds"] for r in rows[:3]] == [1.5, 12.0, 1.0]
    assert all(r["measured"] > 0 for r in rows[:3])
    estimate = rows[-1]
    assert estimate["measured"] == pytest.approx(rows[1]["measured"] - rows[2]["measured"])
    # the first predict compiled and recorded its figure, less than its whole run
    assert 0 < estimate["seconds"] < rows[1]["measured"]
    table = documented.format_documented(rows)
    assert "ftsweep --help" in table and "compile figure" in table


# ----------------------------------------------------------------------------- a sweep measured
@pytest.mark.integration  # a local Dask cluster
def test_a_measured_sweep_is_replayed_on_more_threads_and_its_cases_run_again_alone(tmp_path):
    spec = tmp_path / "tiny.yaml"
    spec.write_text("surface: sinewave2d\nlayout: ring\naxes: {points: [5000, 9000, 20000], aspect: [4.0]}\n")
    out = tmp_path / "bench.json"
    r = CliRunner().invoke(
        main,
        ["bench", "--case", "sinewave-ring-1.00deg", "--sweep", str(spec), "--workers", "1"]
        + ["--simulate-workers", "4", "--json", str(out)],
    )
    assert r.exit_code == 0, r.output
    assert "replayed on 1 thread(s)" in r.output and "replayed on 4 thread(s)" in r.output
    data = json.loads(out.read_text())
    one, four = data["replays"]
    assert one["cases"] == four["cases"] == 3
    assert one["summed_case_s"] == pytest.approx(data["sweeps"][0]["summed_case_s"])
    assert four["wall_s"] <= one["wall_s"] and one["efficiency"] == pytest.approx(1.0)
    assert len(data["side_by_side"]) == 3
    assert all(row["alone_s"] > 0 and row["ratio"] > 0 for row in data["side_by_side"])
    assert "sweep s" in r.output and "alone s" in r.output
    # where the wall went, in order
    tl, wall = data["sweeps"][0]["timeline"], data["sweeps"][0]["wall_s"]
    assert 0 < tl["set_up_s"] <= tl["connected_s"] <= tl["first_case_s"] <= tl["last_case_s"] <= wall
    assert "cube set up at" in r.output and "cluster connected and warmed at" in r.output
    sweep = data["sweeps"][0]
    # the workers' share of the wall is shorter than the wall: its efficiency is the larger
    assert sweep["efficiency_warmed"] == pytest.approx(
        sweep["summed_case_s"] / ((wall - tl["connected_s"]) * sweep["workers"])
    )
    assert sweep["efficiency_warmed"] >= sweep["efficiency"]
    # the driver made the cube and merged its cases: CPU it spent, said beside the timeline
    assert 0 < sweep["driver_cpu_s"] and f"the driver's CPU {sweep['driver_cpu_s']:.1f} s" in r.output


def test_simulated_workers_need_a_sweep():
    r = CliRunner().invoke(main, ["bench", "--case", "sinewave-ring-1.00deg", "--simulate-workers", "4"])
    assert r.exit_code == 2 and "give --sweep too" in r.output


def test_the_whole_predict_is_timed_beside_the_brute_force_model_of_its_case():
    case = Case(surface="sinewave2d", layout=program_request(kind="ring", points=5000, aspect=8.0))
    r = against_reference(1, "predict 5k-point ring", case)
    assert r["predict_s"] > 0 and r["reference_s"] > 0
    assert r["ratio"] == pytest.approx(r["reference_s"] / r["predict_s"])
    # the same case: predict's P-V adds the exact cusp peaks to the reference's nodes
    assert r["reference_pv_nm"] - 1e-3 <= r["predict_pv_nm"] <= r["reference_pv_nm"] * 1.005
    assert "the reference takes" in format_against_reference(r)


def test_bench_reference_is_wired_to_its_own_json(tmp_path, monkeypatch):
    import ftsweep.tools.bench as bench_module

    row = {"case": "c", "predict_s": 1.0, "predict_case_s": 0.5, "predict_pv_nm": 9.0}
    row.update({"reference_s": 30.0, "reference_pv_nm": 9.0, "ratio": 30.0})
    monkeypatch.setattr(bench_module, "against_reference", lambda repeat: row)
    out = tmp_path / "bench.json"
    r = CliRunner().invoke(main, ["bench", "--reference", "--json", str(out)])
    assert r.exit_code == 0, r.output
    assert "the reference takes 30.0× the whole predict" in r.output
    assert json.loads(out.read_text()) == {"against_reference": row}
