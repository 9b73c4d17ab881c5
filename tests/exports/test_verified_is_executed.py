"""The verified file is the executed file: for every exported kind a fresh export
verifies; an edit the machine would execute fails even with every checksum and hash forged to
agree; files never make ftsweep import code; a finished sweep of every kind resumes with
nothing computed."""

from __future__ import annotations

import hashlib
import json
import re
import sys
import zlib
from pathlib import Path

import pytest
from click.testing import CliRunner

from ftsweep.cli.main import main
from ftsweep.exports.files import CRC_LINE, sidecar_digest
from ftsweep.kinds.table.header import CHECKSUM_MACRO, checksum
from ftsweep.kinds.table.verify import read_header
from ftsweep.sweeps.run import run_sweep

SPHERE_D = """
surface: concave_sphere
layout: dpath
machine: sts-xzc
cutting: dpath-finish
dpath: {transition: optimised}
axes: {spacing_um: [500.0], points_per_cut: [41]}
"""
# kind -> sweep spec (YAML); every one a single small case
SWEEPS = {
    "ring": "surface: small_sine\nlayout: ring\naxes: {points: [15000], aspect: [4.0]}\n",
    "mesh": "surface: small_lens\nlayout: mesh\naxes: {points: [12000], aspect: [1.0]}\n",
    "spiral-angle": "surface: small_sine\nlayout: spiral\naxes: {points_per_rev: [60]}\n",
    "spiral-arc": "surface: small_sine\nlayout: spiral\naxes: {arc_um: [20.0]}\n",
    "spiral-chord": "surface: small_sine\nlayout: spiral\naxes: {chord_um: [0.05]}\n",
    "layered-table": "surface: small_sine\nlayout: ring\nmachine: short-fts\n"
    "axes: {points: [15000], aspect: [4.0]}\n",
    "layered-spiral": "surface: small_sine\nlayout: spiral\nmachine: short-fts\n"
    "axes: {points_per_rev: [60]}\n",
    "dpath": SPHERE_D,
}
SUFFIX = {"ring": ".h", "mesh": ".h", "layered-table": ".h"}


def invoke(args: list[str], catalogs: Path):  # type: ignore[no-untyped-def]
    return CliRunner().invoke(main, args, env={"FTSWEEP_CATALOGS": str(catalogs)})


@pytest.fixture(scope="module")
def catalogs_with_fresnel(module_catalog_dir):
    with (module_catalog_dir / "cutting.yaml").open("a") as fh:
        fh.write("\ncoarse-fresnel:\n  feed_um: 8.0\n  nose_radius_um: 40.0\n  spindle_rpm: 30.0\n")
    return module_catalog_dir


@pytest.fixture(scope="module")
def cubes(tmp_path_factory, catalogs_with_fresnel):
    """One finished one-case cube per sweepable kind."""
    folder = tmp_path_factory.mktemp("cubes")
    out = {}
    for kind, text in SWEEPS.items():
        spec = folder / f"{kind}.yaml"
        spec.write_text(text)
        out[kind] = folder / f"{kind}.zarr"
        report = run_sweep(
            str(spec), out[kind], scheduler="synchronous", catalog_folder=catalogs_with_fresnel
        )
        assert report.done == 1, report.rows
    return out


@pytest.fixture(scope="module")
def exports(cubes, tmp_path_factory, catalogs_with_fresnel):
    """A fresh export of every kind (Fresnel from ``ftsweep fresnel -o``); tests copy them."""
    folder = tmp_path_factory.mktemp("exports")
    out = {}
    for kind, cube_path in cubes.items():
        path = folder / f"{kind}{SUFFIX.get(kind, '.txt')}"
        res = invoke(["export", str(cube_path), "--case", "0", "-o", str(path)], catalogs_with_fresnel)
        assert res.exit_code == 0, res.output
        out[kind] = path
    path = folder / "fresnel.txt"
    res = invoke(
        [
            "fresnel",
            "--cutting",
            "coarse-fresnel",
            "--points-per-turn",
            "120",
            "--facet-height-um",
            "10",
            "--plots",
            str(folder),
            "-o",
            str(path),
        ],
        catalogs_with_fresnel,
    )
    assert res.exit_code == 0, res.output
    out["fresnel"] = path
    return out


def copy_of(exports: dict[str, Path], kind: str, folder: Path) -> Path:
    src = exports[kind]
    for suffix in ("", ".json"):
        (folder / f"{kind}{src.suffix}{suffix}").write_bytes(Path(f"{src}{suffix}").read_bytes())
    return folder / src.name


# ----------------------------------------------------------------------------- forging
def forge_header(header: Path, text: str) -> None:
    """Write ``text`` with its CRC macro recomputed from what ftsweep's parser reads, and
    the sidecar's CRC and header hash updated: every checksum agrees with the edit."""
    header.write_text(text)
    macros, ints = read_header(header)
    crc = checksum(macros, ints, json.loads(dict(macros)["INT_TYPE"]))
    text = re.sub(rf"(_{CHECKSUM_MACRO}) 0x[0-9a-f]+UL", rf"\g<1> 0x{crc:08x}UL", text)
    header.write_text(text)
    side = header.with_name(header.name + ".json")
    meta = json.loads(side.read_text())
    meta.update(crc32=crc, header_sha256=hashlib.sha256(text.encode()).hexdigest())
    side.write_text(json.dumps(meta, indent=2))


def forge_program(path: Path, rows: list[str]) -> None:
    """Write ``rows`` as the program with its CRC line recomputed over every other line and
    the sidecar's CRC and program hash updated."""
    at = next(i for i, row in enumerate(rows) if row.startswith("# CRC32:"))
    crc = zlib.crc32("\n".join(rows[:at] + rows[at + 1 :]).encode()) & 0xFFFFFFFF
    rows[at] = CRC_LINE.format(crc)
    text = "\n".join(rows) + "\n"
    path.write_text(text)
    side = path.with_name(path.name + ".json")
    meta = json.loads(side.read_text())
    meta.update(crc32=crc, program_sha256=hashlib.sha256(text.encode()).hexdigest())
    side.write_text(json.dumps(meta, indent=2))


def macro_line(text: str, name: str) -> str:
    return next(line for line in text.splitlines() if re.match(rf"#define \w+_{name} ", line))


def double_pitch(text: str) -> str:
    line = macro_line(text, "PITCH0")
    value = line.split()[2]
    return text.replace(line, line.replace(f" {value} ", f" {float(value) * 2!r} ", 1))


def pitch_expression(text: str) -> str:
    # C compiles this as twice the pitch; a parser dropping everything from the first /* to
    # the last */ reads the old value, so the CRC does not change
    line = macro_line(text, "PITCH0")
    return text.replace(line, line + " * 2 /* x */")


def table_cell(text: str) -> str:
    start = text.index("= {", text.index("_table[")) + 3
    row_start = text.index("{", start + 1) + 1
    end = text.index(",", row_start)
    return text[:row_start] + str(int(text[row_start:end]) + 4) + text[end:]


def layer_offset(text: str) -> str:
    line = macro_line(text, "LAYER_OFFSETS_UM")
    values = line[line.index("{") + 1 : line.index("}")].split(", ")
    values[1] = repr(float(values[1]) + 0.2)
    return text.replace(line, line[: line.index("{") + 1] + ", ".join(values) + line[line.index("}") :])


HEADER_EDITS = [
    ("ring", double_pitch, "macro PITCH0"),
    ("mesh", double_pitch, "macro PITCH0"),
    ("ring", pitch_expression, "macro PITCH0"),
    ("ring", table_cell, "table cell [0][0]"),
    ("mesh", table_cell, "table cell [0][0]"),
    ("layered-table", layer_offset, "macro LAYER_OFFSETS_UM"),
    ("layered-table", table_cell, "table cell [0][0]"),
]


@pytest.mark.parametrize(
    "kind, edit, named", HEADER_EDITS, ids=[f"{k}-{e.__name__}" for k, e, _ in HEADER_EDITS]
)
def test_a_consistently_forged_header_fails_naming_what_differs(
    kind, edit, named, exports, tmp_path, catalogs_with_fresnel
):
    header = copy_of(exports, kind, tmp_path)
    forge_header(header, edit(header.read_text()))
    res = invoke(["verify", str(header)], catalogs_with_fresnel)
    assert res.exit_code == 1, res.output
    assert named in res.output and "do not load it" in res.output, res.output
    # one message line, last (a log's plain progress lines may come before it)
    assert res.output.count("Error") == 1 and res.output.strip().splitlines()[-1].startswith("Error: ")


def data_start(rows: list[str]) -> int:
    return next(i for i, row in enumerate(rows) if row.startswith(("C_deg", "t_s"))) + 1


def shift_column(rows: list[str], index: int, column: int, delta_mm: float) -> list[str]:
    values = rows[index].split(" ")
    values[column] = f"{float(values[column]) + delta_mm:.9f}"
    rows[index] = " ".join(values)
    return rows


def z_line(rows: list[str], delta_nm: float, which: str = "middle") -> list[str]:
    start = data_start(rows)
    return shift_column(rows, (start + len(rows)) // 2, -1, delta_nm * 1e-6)


def dpath_transition(rows: list[str]) -> list[str]:
    """−1 µm in Z at a point of the first transition (between the first two cuts)."""
    start = data_start(rows)
    c = [float(row.split()[1]) for row in rows[start:]]
    steps = [b - a for a, b in zip(c, c[1:], strict=False)]
    # the first transition: where the C step first differs from the cut's own step
    k = next(i for i in range(1, len(steps)) if abs(steps[i] - steps[0]) > 1e-6) + 1
    return shift_column(rows, start + k, 3, -1e-3)


def edit_line(prefix: str, change):  # type: ignore[no-untyped-def]
    def edit(rows: list[str]) -> list[str]:
        i = next(i for i, row in enumerate(rows) if row.startswith(prefix))
        rows[i] = change(rows[i])
        return rows

    edit.__name__ = prefix.strip("# :").replace(" ", "_")
    return edit


def moved_offset(row: str) -> str:
    values = row.split()
    values[2] = f"{float(values[2]) + 0.0002:.9f}"  # +0.2 µm
    return " ".join(values)


def moved_segment(row: str) -> str:
    values = row.split()
    values[5] = f"{float(values[5]) + 720.0:.9f}"
    return " ".join(values)


PROGRAM_EDITS = [
    ("spiral-angle", lambda r: z_line(r, 100.0), "Z_mm"),
    ("spiral-arc", lambda r: z_line(r, -300.0), "Z_mm"),
    ("spiral-chord", lambda r: z_line(r, 100.0), "Z_mm"),
    ("layered-spiral", lambda r: z_line(r, 100.0), "Z_mm"),
    ("layered-spiral", edit_line("# offset_mm:", moved_offset), "offset_mm"),
    ("layered-spiral", edit_line("# segment:", moved_segment), "segment"),
    ("dpath", lambda r: z_line(r, 30.0), "Z_mm"),
    ("dpath", dpath_transition, "Z_mm"),
    ("fresnel", lambda r: z_line(r, 30.0), "Z_mm"),
    ("fresnel", edit_line("# timing:", lambda row: row.replace("s in all", "s  in all")), "timing"),
    ("fresnel", edit_line("# tool:", lambda row: row.replace("nose radius", "nose  radius")), "tool"),
]


@pytest.mark.parametrize(
    "kind, edit, named", PROGRAM_EDITS, ids=[f"{k}-{n}-{i}" for i, (k, _, n) in enumerate(PROGRAM_EDITS)]
)
def test_a_consistently_forged_program_fails_naming_the_line(
    kind, edit, named, exports, tmp_path, catalogs_with_fresnel
):
    path = copy_of(exports, kind, tmp_path)
    forge_program(path, edit(path.read_text().splitlines()))
    res = invoke(["verify", str(path)], catalogs_with_fresnel)
    assert res.exit_code == 1, res.output
    assert named in res.output and "do not run it" in res.output, res.output
    # one message line, last (a log's plain progress lines may come before it)
    assert res.output.count("Error") == 1 and res.output.strip().splitlines()[-1].startswith("Error: ")


def test_program_crc_covers_the_layer_lines(exports, tmp_path, catalogs_with_fresnel):
    """An unforged edit of an informational or layer line fails on the CRC itself."""
    path = copy_of(exports, "layered-spiral", tmp_path)
    rows = edit_line("# offset_mm:", moved_offset)(path.read_text().splitlines())
    path.write_text("\n".join(rows) + "\n")
    res = invoke(["verify", str(path)], catalogs_with_fresnel)
    assert res.exit_code == 1 and "CRC32 mismatch" in res.output, res.output


@pytest.mark.parametrize("kind", ["spiral-angle", "dpath", "fresnel"])
def test_a_sidecar_naming_other_bytes_is_refused(kind, exports, tmp_path, catalogs_with_fresnel):
    """The sidecar's SHA-256 of the program must be that of the bytes read (hashed as read,
    the very bytes whose lines are checked)."""
    path = copy_of(exports, kind, tmp_path)
    side = path.with_name(path.name + ".json")
    meta = json.loads(side.read_text())
    assert meta["program_sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    meta["program_sha256"] = hashlib.sha256(path.read_bytes() + b"\n").hexdigest()
    side.write_text(json.dumps(meta, indent=2))
    res = invoke(["verify", str(path)], catalogs_with_fresnel)
    assert res.exit_code == 1 and "does not belong to" in res.output, res.output


# ----------------------------------------------------------------------------- trust
PROBE_MODULE = "ftsweep_probe_issue26"


def test_a_sidecar_naming_a_plugin_is_refused_without_importing_it(
    exports, tmp_path, catalogs_with_fresnel, monkeypatch
):
    (tmp_path / f"{PROBE_MODULE}.py").write_text("import numpy as np\n\ndef f(x, y):\n    return 0.0 * x\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    header = copy_of(exports, "ring", tmp_path)
    side = header.with_name(header.name + ".json")
    meta = json.loads(side.read_text())
    surface = meta["catalog_entries"]["surface"]
    surface.update(family="plugin", params={"function": f"{PROBE_MODULE}:f", "params": {}})
    side.write_text(json.dumps(meta, indent=2))
    text = header.read_text()
    line = macro_line(text, "SIDECAR_SHA256")
    forge_header(header, text.replace(line.split()[2], json.dumps(sidecar_digest(meta))))
    res = invoke(["verify", str(header)], catalogs_with_fresnel)
    assert res.exit_code == 1, res.output
    assert "--trust-plugins" in res.output and PROBE_MODULE in res.output
    assert PROBE_MODULE not in sys.modules
    # trusted explicitly, the plug-in runs (and the forged surface no longer matches the table)
    res = invoke(["verify", str(header), "--trust-plugins"], catalogs_with_fresnel)
    assert res.exit_code == 1 and "--trust-plugins" not in res.output
    assert PROBE_MODULE in sys.modules
    sys.modules.pop(PROBE_MODULE)


# ----------------------------------------------------------------------------- microprism spiral
def test_angles_read_back_from_a_program_give_the_planned_sampling():
    """The spindle-angle sampling of a path read back from its printed lines (C to 1e-9°)
    is the planned path's: a point printed just short of k·360° stays in revolution k."""
    import numpy as np

    from ftsweep.stages.paths import spiral

    path = spiral.constant_angle(296.98484809834997, 2.0, 200)
    printed = np.radians(np.array([float(f"{v:.9f}") for v in np.degrees(path.phi)]))
    read = path._replace(phi=printed)
    assert read.max_points_per_rev == path.max_points_per_rev == 200


def test_a_fresh_microprism_spiral_export_verifies(tmp_path, catalogs_with_fresnel):
    spec = tmp_path / "prism.yaml"
    spec.write_text(
        "surface: microprism\nlayout: spiral\nmachine: fts-1m\ncutting: microprism\n"
        "axes: {points_per_rev: [200]}\n"
    )
    cube_path = tmp_path / "prism.zarr"
    run_sweep(str(spec), cube_path, scheduler="synchronous", catalog_folder=catalogs_with_fresnel)
    out = tmp_path / "prism.txt"
    res = invoke(["export", str(cube_path), "--case", "0", "-o", str(out)], catalogs_with_fresnel)
    assert res.exit_code == 0, res.output
    res = invoke(["verify", str(out)], catalogs_with_fresnel)
    assert res.exit_code == 0, res.output


# ----------------------------------------------------------------------------- probes
SPIRAL = ["predict", "--surface", "sinewave2d", "--layout", "spiral"]
PROBES = [
    # (args, fragment of the one-line message); every one refused before the work starts
    ([*SPIRAL, "--chord-um", "1e-12"], "over the capacity"),
    ([*SPIRAL, "--points-per-rev", "3000000"], "over the capacity"),
    ([*SPIRAL, "--arc-um", "1e-6"], "over the capacity"),
    ([*SPIRAL, "--points-per-rev", "100", "--nose-radius-um", "1e9"], "range of --nose-radius-um"),
    (["predict", "--surface", "sinewave2d", "--points", "1e300", "--aspect", "1"], "range of --points"),
    (["dpath", "--points-per-cut", "100000"], "more than 20,000,000"),
    (["dpath", "--transition-step-deg", "1e-9"], "more than 20,000,000"),
    (["dpath", "--spacing-um", "nan"], "not a finite number"),
    (["fresnel", "--points-per-turn", "100000000"], "more than the machine holds"),
    (["fresnel", "--facet-height-um", "1e-6"], "more than the machine holds"),
    (["fresnel", "--deviation-deg", "nan"], "not a finite number"),
    (["fresnel", "--safety", "inf"], "not a finite number"),
    (["predict", "--surface", "path_plugin", "--drho-um", "5", "--dtheta-deg", "2"], "is a file path"),
    (["predict", "--surface", "object_map", "--drho-um", "5", "--dtheta-deg", "2"], "not a numeric .npy"),
    (["verify", "{d}/list-sidecar.txt"], "not an ftsweep sidecar"),
]
PROBE_SURFACES = """
path_plugin:
  description: A plug-in named by a file path (for tests).
  family: plugin
  layout: ring
  aperture: {shape: circle, radius_um: 300.0}
  params: {function: "/tmp/some_folder/surface.py:f"}
object_map:
  description: A height map saved as an object array (a pickle; for tests).
  family: height_map
  layout: ring
  aperture: {shape: circle, radius_um: 300.0}
  params: {path: data/object_map.npy, spacing_um: [10.0, 10.0]}
"""


@pytest.mark.parametrize("args, fragment", PROBES, ids=[f"{a[0]}-{i}" for i, (a, _) in enumerate(PROBES)])
def test_every_probe_is_refused_at_once_in_one_line(args, fragment, exports, catalog_dir, tmp_path):
    import time

    import numpy as np

    with (catalog_dir / "surfaces.yaml").open("a") as fh:
        fh.write(PROBE_SURFACES)
    np.save(catalog_dir / "data" / "object_map.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    listed = tmp_path / "list-sidecar.txt"
    listed.write_bytes(exports["spiral-angle"].read_bytes())
    listed.with_name(listed.name + ".json").write_text("[]")
    args = [a.replace("{d}", str(tmp_path)) for a in args]
    invoke(["--help"], catalog_dir)  # imports paid before the clock starts
    start = time.perf_counter()
    res = invoke(args, catalog_dir)
    elapsed = time.perf_counter() - start
    assert res.exit_code != 0 and isinstance(res.exception, SystemExit), res.output
    # one message line (a bad option value is shown under click's usage lines, as for any option)
    last = res.output.strip().splitlines()[-1]
    assert last.startswith("Error: ") and "Traceback" not in res.output, res.output
    assert res.output.count("Error") == 1, res.output
    assert fragment in last and "unexpected error" not in last and "pydantic" not in last, last
    assert len(last) < 400
    # refused before the work (measured 0.00-0.14 s in process on the 2-core machine)
    assert elapsed < 2.0, elapsed
    print(f"{' '.join(args[:3])}: {elapsed:.2f} s")


# ----------------------------------------------------------------------------- smaller probes
RAISING_PLUGIN = '''
import numpy as np

def f(x, y):
    """Fine on the load-time test grid, raises on a ring of radius 120-130 µm."""
    r = np.hypot(x, y)
    if np.any((r > 120) & (r < 130)):
        raise RuntimeError("boom from the plug-in")
    return 0.1 * np.sin(x / 30.0)
'''


def test_a_raising_plugin_fails_its_cases_by_name_and_the_sweep_goes_on(catalog_dir, tmp_path, monkeypatch):
    (tmp_path / "raising_issue26.py").write_text(RAISING_PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    with (catalog_dir / "surfaces.yaml").open("a") as fh:
        fh.write(
            "raiser:\n  description: raises off its test grid (for tests)\n  family: plugin\n  layout: ring\n"
            "  aperture: {shape: circle, radius_um: 300.0}\n  params: {function: 'raising_issue26:f'}\n"
        )
    spec = tmp_path / "r.yaml"
    spec.write_text("surface: raiser\nlayout: ring\naxes: {points: [8000], aspect: [1.0, 4.0]}\n")
    report = run_sweep(str(spec), tmp_path / "r.zarr", scheduler="synchronous", catalog_folder=catalog_dir)
    assert len(report.rows) == 2 and report.failed == 2
    for row in report.rows:
        assert "plug-in raising_issue26:f raised RuntimeError: boom" in row["message"], row["message"]


def test_progress_in_a_log_is_plain_periodic_lines():
    import io

    from ftsweep.progress import Progress

    log = io.StringIO()
    bar = Progress("work", stream=log, interval_s=3600.0)
    for done in range(1, 101):
        bar(done, 100)
    bar.close()
    assert "\r" not in log.getvalue()
    assert log.getvalue().splitlines() == ["work: 100/100"]  # nothing in between within the interval


def test_eta_comes_from_the_cost_estimate_scaled_by_the_cases_measured():
    """Cases arrive costliest first (the tasks' order): the time left is the cost not yet
    finished times the seconds measured per unit of cost, right from the first case; a mean
    of seconds per case would have said several times the time left."""
    from ftsweep.cli.sweep import Eta

    eta = Eta()
    costs = [100.0, 80.0, 50.0, 30.0, 20.0, 10.0, 5.0, 5.0]  # 300 units, 0.1 s a unit
    assert eta.text(sum(costs), remaining=8, threads=2) == "ETA –"  # nothing measured yet
    for cost in costs[:2]:
        eta.finished(cost, 0.1 * cost)
    left = sum(costs[2:]) * 0.1 / 2
    assert eta.seconds_left(sum(costs), threads=2) == pytest.approx(left)  # 6 s, not 27 s
    mean_per_case = (10.0 + 8.0) / 2 * 6 / 2
    assert mean_per_case > 4 * left
    eta.finished(50.0, None)  # a case finished untimed (refused) still leaves the cost undone
    assert eta.seconds_left(sum(costs), threads=2) == pytest.approx(sum(costs[3:]) * 0.1 / 2)
    assert eta.text(sum(costs), remaining=0, threads=2) == "ETA 0 s"


def test_the_bar_and_its_text_are_drawn_from_one_snapshot(monkeypatch):
    """On a terminal every line the bar draws holds the same count in the bar and its text."""
    import io
    import re
    import sys
    from types import SimpleNamespace

    from ftsweep.cli.sweep import SweepProgress

    screen = io.StringIO()
    screen.isatty = lambda: True  # type: ignore[method-assign]
    monkeypatch.setattr(sys, "stderr", screen)
    progress = SweepProgress(0.0)
    report = SimpleNamespace(
        rows=[], queued=18, refused={}, costs=dict.fromkeys(range(18), 1.0), workers=2, threads=2
    )
    for i in range(18):
        row = {"index": i, "status": "done", "seconds": 0.5, "pv_nm": 1.0, "message": ""}
        report.rows.append(row)
        progress(report, [row])
    progress.close()
    drawn = [line for line in re.split(r"[\r\n]", screen.getvalue()) if "|" in line]
    assert len(drawn) >= 18
    for line in drawn:
        n = int(re.search(r"sweep: (\d+)/18", line).group(1))
        assert f"{n:>2} done" in line and f"{18 - n:>2} pending" in line, line


def test_figures_and_files_respect_the_umask_and_write_errors_name_the_file(tmp_path, monkeypatch):
    import errno
    import os

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ftsweep.store import io

    old = os.umask(0o022)
    try:
        fig, ax = plt.subplots()
        ax.plot([0, 1], [0, 1])
        path = io.save_figure(fig, tmp_path / "f.png")
        assert path.stat().st_mode & 0o777 == 0o644

        def full(fd: int) -> None:
            raise OSError(errno.ENOSPC, "No space left on device")

        monkeypatch.setattr(os, "fsync", full)
        with pytest.raises(OSError, match=r"x\.txt: cannot write it \(No space left on device\)"):
            io.write_text_atomic(tmp_path / "x.txt", "data")
        assert not (tmp_path / "x.txt").exists() and not list(tmp_path.glob(".x.txt.*"))
    finally:
        os.umask(old)
