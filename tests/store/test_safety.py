"""Nothing wrong reaches the controller: verify, non-finite values, cube locks,
task failures, resume integrity, and one-line errors for every probe a user can make."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import socket
import stat
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner
from support.forging import entered_in_ledger

from ftsweep.cli.main import main
from ftsweep.kinds.table.header import CHECKSUM_MACRO, checksum
from ftsweep.kinds.table.verify import read_header
from ftsweep.store import caselog, cube
from ftsweep.store.lock import LockError, acquire, lock_path, release
from ftsweep.sweeps.run import run_sweep
from ftsweep.tools.export import ExportError, export, verify
from ftsweep.tools.select import SelectError, choose, open_cube

BIN = Path(sys.executable).parent

ONE_CASE = """
surface: small_sine
layout: ring
axes: {points: [15000], aspect: [4.0]}
"""
SIX_CASES = """
surface: small_sine
layout: ring
axes: {points: [8000, 20000], aspect: [1.0, 4.0, 16.0]}
cases_per_task: 1
"""


def data_of(path: Path) -> xr.Dataset:
    """A cube's values without wall times and run ids (which differ run to run)."""
    return xr.open_zarr(path).drop_vars(list(cube.TIMING_VARS)).load()


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(text))
    return path


def cli(args: list[str], catalogs: Path | None = None, **kw):  # type: ignore[no-untyped-def]
    env = {"FTSWEEP_CATALOGS": str(catalogs)} if catalogs else {}
    return CliRunner().invoke(main, args, env=env, **kw)


def assert_one_line_error(result, fragment: str | tuple[str, ...]) -> None:  # type: ignore[no-untyped-def]
    """Exit ≠ 0, no traceback, and the output ends in one ``Error:`` line holding ``fragment``
    (or one of a tuple of them)."""
    assert result.exit_code != 0, result.output
    assert isinstance(result.exception, SystemExit), repr(result.exception)  # handled, not a crash
    assert "Traceback" not in result.output
    last = result.output.strip().splitlines()[-1]
    assert last.startswith("Error: "), result.output
    fragments = (fragment,) if isinstance(fragment, str) else fragment
    assert any(f.lower() in last.lower() for f in fragments), last
    assert len(last) <= 1600


# ----------------------------------------------------------------------------- verify
@pytest.fixture(scope="module")
def exported(tmp_path_factory, module_catalog_dir):
    """A one-case cube and its exported header + sidecar (never edited: tests copy them)."""
    folder = tmp_path_factory.mktemp("exported")
    spec = write(folder, "one.yaml", ONE_CASE)
    out = folder / "one.zarr"
    run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=module_catalog_dir)
    header = folder / "fts.h"
    export(out, header, index=0)
    return header


@pytest.fixture()
def header_copy(exported, tmp_path, module_catalog_dir, monkeypatch):
    # verify compares the recorded entries with the catalog: the one the header came from
    monkeypatch.setenv("FTSWEEP_CATALOGS", str(module_catalog_dir))
    for suffix in ("", ".json"):
        shutil.copy(f"{exported}{suffix}", tmp_path / f"fts.h{suffix}")
    return tmp_path / "fts.h"


def _edited(value: str) -> str:
    if value.startswith('"'):
        return value[:-1] + 'x"'
    if value.endswith("UL"):
        return f"0x{(int(value[:-2], 16) + 1) & 0xFFFFFFFF:08x}UL"
    if value.endswith("L"):
        return f"{int(value[:-1]) + 1}L"
    if value.isdigit():
        return str(int(value) + 1)
    return repr(float(value) * 1.01 + 0.5)


def _replace_macro(text: str, name: str, value: str) -> str:
    lines = text.splitlines(keepends=True)
    for i, line in enumerate(lines):
        parts = line.split(maxsplit=2)
        if len(parts) == 3 and parts[0] == "#define" and parts[1].endswith("_" + name):
            comment = line[line.index("/*") :] if "/*" in line else "\n"
            lines[i] = f"#define {parts[1]} {value}" + (" " + comment if "/*" in line else comment)
            return "".join(lines)
    raise AssertionError(f"no macro {name}")


MACROS = [
    "ROWS",
    "COLS",
    "LAYOUT_KIND",
    "LAYOUT_IS_RING",
    "N_POINTS",
    "PITCH0",
    "PITCH1",
    "ORIGIN0",
    "ORIGIN1",
    "UNIT_NM",
    "INT_TYPE",
    "SURFACE",
    "COMPENSATION",
    "FEED_UM",
    "NOSE_RADIUS_UM",
    "SPINDLE_RPM",
    "PREDICTED_PV_NM",
    "GENERATOR",
    "SIDECAR_SHA256",
    CHECKSUM_MACRO,
]


def test_untouched_header_verifies_with_its_pv_tolerance(exported, module_catalog_dir, monkeypatch):
    monkeypatch.setenv("FTSWEEP_CATALOGS", str(module_catalog_dir))
    record = verify(exported)
    assert abs(record["pv_nm"] - record["predicted_pv_nm"]) <= record["pv_tolerance_nm"]
    r = cli(["verify", str(exported)])
    assert r.exit_code == 0, r.output
    assert "macros and table" in r.output and "tolerance" in r.output


@pytest.mark.parametrize("name", MACROS)
def test_every_edited_macro_fails_verify(header_copy, name):
    macros = dict(read_header(header_copy)[0])
    edited = _replace_macro(header_copy.read_text(), name, _edited(macros[name]))
    header_copy.write_text(edited)
    with pytest.raises(ExportError, match="checksum mismatch|INT_TYPE|the table holds|the table is declared"):
        verify(header_copy)
    r = cli(["verify", str(header_copy)])
    assert r.exit_code == 1 and ("do not load it" in r.output or "INT_TYPE" in r.output)


@pytest.mark.parametrize(
    "edit",
    [
        lambda m: m.update(pv_nm=m["pv_nm"] / 2),
        lambda m: m["case"].update(feed_um=7.0),
        lambda m: m["catalog_entries"]["surface"]["params"].update(amplitude_x_um=0.6),
    ],
    ids=["predicted-pv", "feed", "surface-params"],
)
def test_edited_sidecar_fails_verify(header_copy, edit):
    side = header_copy.with_name(header_copy.name + ".json")
    meta = json.loads(side.read_text())
    edit(meta)
    side.write_text(json.dumps(meta, indent=2))
    with pytest.raises(ExportError, match="sidecar|SIDECAR_SHA256"):
        verify(header_copy)


def _forge_table(header: Path, delta: int) -> str:
    """Add ``delta`` to the middle row of the table and write the matching CRC."""
    text = header.read_text()
    macro_list, ints = read_header(header)
    forged = ints.copy()
    forged[ints.shape[0] // 2] += delta
    start = text.index("= {", text.index("_table[")) + 3
    rows = ",\n".join("    {" + ", ".join(str(int(v)) for v in row) + "}" for row in forged)
    text = text[:start] + "\n" + rows + "\n" + text[text.index("};", start) :]
    crc = checksum(macro_list, forged, json.loads(dict(macro_list)["INT_TYPE"]))
    text = _replace_macro(text, CHECKSUM_MACRO, f"0x{crc:08x}UL")
    header.write_text(text)
    return text


def test_table_forged_with_its_crc_fails_on_the_header_hash(header_copy):
    _forge_table(header_copy, 1)
    assert read_header(header_copy)  # still parses, and its CRC matches the forged table
    with pytest.raises(ExportError, match="another table|SHA-256 mismatch"):
        verify(header_copy)
    # with the sidecar's CRC forged too, the header's hash still gives it away
    side = header_copy.with_name(header_copy.name + ".json")
    meta = json.loads(side.read_text())
    meta["crc32"] = int(dict(read_header(header_copy)[0])[CHECKSUM_MACRO].rstrip("UL"), 16)
    side.write_text(json.dumps(meta, indent=2))
    with pytest.raises(ExportError, match="SHA-256 mismatch"):
        verify(header_copy)


def _forge_consistently(header: Path, text: str) -> None:
    """Write ``text`` as the header with its CRC macro, and the sidecar's CRC and header
    hash, all recomputed: every checksum agrees with the edit."""
    header.write_text(text)
    macro_list, ints = read_header(header)
    crc = checksum(macro_list, ints, json.loads(dict(macro_list)["INT_TYPE"]))
    text = _replace_macro(text, CHECKSUM_MACRO, f"0x{crc:08x}UL")
    header.write_text(text)
    side = header.with_name(header.name + ".json")
    meta = json.loads(side.read_text())
    meta["header_sha256"] = hashlib.sha256(text.encode()).hexdigest()
    meta["crc32"] = crc
    side.write_text(json.dumps(meta, indent=2))


def test_consistently_forged_table_fails_on_the_replanned_cells(header_copy):
    """Table, CRC and the sidecar's header hash forged together: the re-planned table names
    the cell."""
    text = _forge_table(header_copy, 500)  # half a micrometre on one ring
    _forge_consistently(header_copy, text)
    with pytest.raises(ExportError, match=r"table cell \[\d+\]\[\d+\] holds"):
        verify(header_copy)


def test_consistently_forged_prediction_fails_on_the_resimulated_pv(header_copy):
    """The predicted P-V forged in the sidecar and the header, every hash and CRC made to
    agree: only the re-simulation can tell."""
    side = header_copy.with_name(header_copy.name + ".json")
    meta = json.loads(side.read_text())
    meta["pv_nm"] = meta["pv_nm"] / 2
    side.write_text(json.dumps(meta, indent=2))
    from ftsweep.exports.files import sidecar_digest

    text = _replace_macro(header_copy.read_text(), "PREDICTED_PV_NM", repr(meta["pv_nm"]))
    text = _replace_macro(text, "SIDECAR_SHA256", json.dumps(sidecar_digest(meta)))
    _forge_consistently(header_copy, text)
    with pytest.raises(ExportError, match="re-simulates to P-V"):
        verify(header_copy)
    # a tolerance wide enough accepts it (its bytes entered in the cube's ledger, as a forger
    # who can write the cube could), so the check above is the P-V comparison itself
    with entered_in_ledger(header_copy):
        assert verify(header_copy, pv_tolerance_nm=1e6)["pv_nm"] > meta["pv_nm"] + 1


@pytest.mark.parametrize(
    "content",
    [
        b"\xff\xfe not text",
        b"int x;\n",
        b"#define A_ROWS 2\n#define A_COLS 2\n",
        b'#define A_ROWS 2\n#define A_COLS x\n#define A_INT_TYPE "int32"\n#define A_UNIT_NM 1.0\n'
        b"#define A_CHECKSUM_CRC32 0x0UL\nstatic const int32_t a_table[A_ROWS][A_COLS] = {{1, 2}, {3, 4}};\n",
        b'#define A_ROWS 2\n#define A_COLS 2\n#define A_INT_TYPE "int32"\n#define A_UNIT_NM 1.0\n'
        b"#define A_CHECKSUM_CRC32 0x0UL\nstatic const int32_t a_table[A_ROWS][A_COLS] = {{1, 2}, {3}};\n",
        b'#define A_ROWS 1\n#define A_COLS 1\n#define A_INT_TYPE "int8"\n#define A_UNIT_NM 1.0\n'
        b"#define A_CHECKSUM_CRC32 0x0UL\nstatic const int32_t a_table[A_ROWS][A_COLS] = {{1}};\n",
    ],
    ids=["binary", "no-macros", "no-table", "bad-cols", "short-table", "bad-int-type"],
)
def test_malformed_headers_give_one_line(tmp_path, content):
    path = tmp_path / "bad.h"
    path.write_bytes(content)
    assert_one_line_error(cli(["verify", str(path)]), "bad.h")


# ----------------------------------------------------------------------------- non-finite
NAN_PLUGIN = '''
import numpy as np

def holes(x, y):
    """A sine part with a hole of NaN between the points of the load-time test grid."""
    f = 0.5 * np.sin(x / 50.0) * np.cos(y / 50.0)
    return np.where((x > 40) & (x < 60) & (y > 40) & (y < 60), np.nan, f)
'''
NAN_SURFACE = """
holey:
  description: A plug-in that is NaN off its load-time test grid (for tests).
  family: plugin
  layout: ring
  aperture: {shape: circle, radius_um: 300.0}
  params: {function: "nanplug_issue16:holes"}
"""


@pytest.fixture()
def holey(tmp_path, catalog_dir, monkeypatch):
    write(tmp_path, "nanplug_issue16.py", NAN_PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    with (catalog_dir / "surfaces.yaml").open("a") as fh:
        fh.write(NAN_SURFACE)
    return catalog_dir


def test_nan_off_the_test_grid_refuses_the_case_and_nothing_is_exported(tmp_path, holey):
    r = cli(["predict", "--surface", "holey", "--drho-um", "5", "--dtheta-deg", "2"], holey)
    assert_one_line_error(r, "not finite")
    assert "µm" in r.output  # names where
    spec = write(tmp_path, "holey.yaml", ONE_CASE.replace("small_sine", "holey"))
    out = tmp_path / "holey.zarr"
    report = run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=holey)
    # the surface gives NaN off its test grid: every run of the case would, so it is refused
    assert report.refused_now == 1 and report.rows[0]["status"] == "refused"
    assert "not finite" in report.rows[0]["message"]
    ds = open_cube(out)
    assert int(ds["status"].values.ravel()[0]) == cube.REFUSED
    with pytest.raises(SelectError, match="no computed, feasible case"):
        choose(ds, budget_points=10**6)
    header = tmp_path / "holey.h"
    assert_one_line_error(cli(["export", str(out), "--case", "0", "-o", str(header)], holey), "refused")
    assert_one_line_error(cli(["select", str(out), "--budget-points", "100000"], holey), "no computed")
    assert not header.exists() and not header.with_name(header.name + ".json").exists()


def test_quantisation_refuses_non_finite_values():
    from ftsweep.kinds.table.header import quantise

    with pytest.raises(ExportError, match="non-finite"):
        quantise(np.array([[1.0, np.nan]]), 1.0, "int32")


def test_selection_never_takes_a_non_finite_pv(tmp_path, catalog_dir):
    spec = write(tmp_path, "six.yaml", SIX_CASES)
    out = tmp_path / "six.zarr"
    run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    pv = zarr_array(out, "pv_nm")
    best = int(np.argmin(pv[...].ravel()))
    pv[np.unravel_index(best, pv.shape)] = np.nan  # as a damaged writer might leave it
    chosen = choose(open_cube(out), budget_points=10**6)
    assert chosen["index"] != best and np.isfinite(chosen["pv_nm"])
    with pytest.raises(SelectError, match="no finite P-V"):
        export(out, tmp_path / "x.h", index=best)


def zarr_array(path: Path, name: str):  # type: ignore[no-untyped-def]
    import zarr

    return zarr.open_array(str(path), path=name, mode="r+")


# ----------------------------------------------------------------------------- export
def test_two_files_of_one_stem_keep_their_own_sidecars(exported, tmp_path, module_catalog_dir, monkeypatch):
    # sidecars are named from the whole file name: a.h and a.hdr do not share a.json
    monkeypatch.setenv("FTSWEEP_CATALOGS", str(module_catalog_dir))
    cube_path = exported.parent / "one.zarr"
    for name in ("a.h", "a.hdr"):
        assert cli(["export", str(cube_path), "--case", "0", "-o", str(tmp_path / name)]).exit_code == 0
    assert sorted(p.name for p in tmp_path.glob("a.*.json")) == ["a.h.json", "a.hdr.json"]
    for name in ("a.h", "a.hdr"):
        verify(tmp_path / name)


def test_a_sidecar_of_the_older_name_is_still_read_with_a_note(exported, tmp_path, module_catalog_dir):
    shutil.copy(exported, tmp_path / "old.h")
    shutil.copy(f"{exported}.json", tmp_path / "old.json")  # as exports named it before
    res = cli(["verify", str(tmp_path / "old.h")], module_catalog_dir)
    assert res.exit_code == 0, res.output
    assert (
        "note         the sidecar has the older name old.json; export again to name it old.h.json"
        in res.output
    )


def test_outputs_respect_the_umask(exported, tmp_path):
    old = os.umask(0o022)
    try:
        export(exported.parent / "one.zarr", tmp_path / "u.h", index=0)
    finally:
        os.umask(old)
    for path in (tmp_path / "u.h", tmp_path / "u.h.json"):
        assert stat.S_IMODE(path.stat().st_mode) == 0o644, path


# ----------------------------------------------------------------------------- locks
def test_lock_refuses_a_live_holder_and_replaces_a_stale_one(tmp_path):
    target = tmp_path / "c.zarr"
    path = acquire(target, "first")
    try:
        with pytest.raises(LockError, match=f"pid {os.getpid()}"):
            acquire(target, "second")
    finally:
        release(path)
    assert not path.exists()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    lock_path(target).write_text(
        json.dumps({"pid": dead.pid, "host": socket.gethostname(), "started": "then", "command": "x"})
    )
    path = acquire(target, "after a crash")
    assert json.loads(path.read_text())["pid"] == os.getpid()
    release(path)
    lock_path(target).write_text(json.dumps({"pid": 1, "host": "another-host", "started": "now"}))
    with pytest.raises(LockError, match="another-host"):
        acquire(target)


def test_a_lock_appears_whole_and_leaves_no_spare_behind(tmp_path, monkeypatch):
    # the record is written aside and linked into place: whoever sees the lock reads its holder
    target = tmp_path / "c.zarr"
    seen = []
    real_link = os.link

    def link_and_look(src, dst, **kw):
        seen.append(Path(src).read_text())
        real_link(src, dst, **kw)
        seen.append(Path(dst).read_text())

    monkeypatch.setattr(os, "link", link_and_look)
    path = acquire(target, "whole")
    assert [json.loads(text)["command"] for text in seen] == ["whole", "whole"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.zarr.lock"]
    with pytest.raises(LockError, match=f"by pid {os.getpid()}"):
        acquire(target, "second")
    release(path)
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("links", [True, False])
def test_a_lock_has_one_mode_however_it_is_made(tmp_path, monkeypatch, links):
    """0o644 less the umask, linked into place or (a file system without hard links) made with
    O_EXCL, whatever the umask lets a plain write give."""
    if not links:

        def no_links(src, dst, **kw):
            raise OSError("hard links not supported")

        monkeypatch.setattr(os, "link", no_links)
    old = os.umask(0o002)  # a plain write would give 0o664
    try:
        path = acquire(tmp_path / "c.zarr", "mode")
    finally:
        os.umask(old)
    assert oct(path.stat().st_mode & 0o777) == "0o644"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.zarr.lock"]
    release(path)


def _start_sweep(spec: Path, out: Path, catalogs: Path, *extra: str) -> subprocess.Popen:
    env = dict(os.environ, FTSWEEP_CATALOGS=str(catalogs))
    return subprocess.Popen(
        [str(BIN / "ftsweep"), "sweep", str(spec), "--out", str(out), "--scheduler", "synchronous", *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )


# a sweep held at its first write into the cube (a fault point: the lock is taken and the cube
# made), until the test says go on with a line on its standard input
HELD_UNTIL_TOLD = """
import sys
from ftsweep.store import faultpoints
from ftsweep.sweeps.run import run_sweep

held = []


def hold(event, key):
    if not held:
        held.append(key)
        print("HELD", flush=True)
        sys.stdin.readline()


faultpoints.WRITE_POINT = hold
run_sweep(sys.argv[1], sys.argv[2], scheduler="synchronous", catalog_folder=sys.argv[3])
"""


@pytest.mark.integration  # three sweep processes
def test_concurrent_sweeps_are_refused_and_the_cube_equals_a_single_run(tmp_path, catalog_dir):
    """While a sweep holds the cube (held at its first write, not kept busy by a workload, so
    a faster or slower machine gives the same result), the same sweep and a --restart of
    another are refused naming the writer; the first, let go, finishes the cube a single run
    makes."""
    spec = write(tmp_path, "six.yaml", SIX_CASES)
    other = write(tmp_path, "other.yaml", SIX_CASES.replace("16.0", "32.0"))
    out = tmp_path / "shared.zarr"
    env = dict(os.environ, FTSWEEP_CATALOGS=str(catalog_dir))
    first = subprocess.Popen(
        [sys.executable, "-c", HELD_UNTIL_TOLD, str(spec), str(out), str(catalog_dir)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        assert first.stdout is not None and first.stdout.readline().strip() == "HELD"
        same = _start_sweep(spec, out, catalog_dir)
        restart = _start_sweep(other, out, catalog_dir, "--restart")
        for proc in (same, restart):
            _, err = proc.communicate(timeout=120)
            assert proc.returncode != 0
            assert "is being written by pid" in err and "Traceback" not in err
            assert err.strip().splitlines()[-1].startswith("Error:")
        assert first.poll() is None  # still held: the refusals did not disturb it
        _, err = first.communicate("go on\n", timeout=300)
        assert first.returncode == 0, err
    finally:
        if first.poll() is None:
            first.kill()
    assert not lock_path(out).exists()
    assert not list(tmp_path.glob(".shared.zarr.tmp-*"))
    single = tmp_path / "single.zarr"
    run_sweep(str(spec), single, scheduler="synchronous", catalog_folder=catalog_dir)
    xr.testing.assert_equal(data_of(out), data_of(single))


# ----------------------------------------------------------------------------- resume integrity
@pytest.fixture()
def six_cube(tmp_path, catalog_dir):
    spec = write(tmp_path, "six.yaml", SIX_CASES)
    out = tmp_path / "six.zarr"
    run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    return spec, out


@pytest.fixture()
def six_case_blocks(tmp_path, catalog_dir, monkeypatch):
    """The six cases in blocks of one case each (cubes block 4,096), to damage one at a time."""
    monkeypatch.setattr(cube, "BLOCK_CASES", 1)
    spec = write(tmp_path, "six.yaml", SIX_CASES)
    out = tmp_path / "six.zarr"
    run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    return spec, out


def test_missing_and_corrupt_chunks_of_done_cases_are_recomputed(six_case_blocks, tmp_path, catalog_dir):
    spec, out = six_case_blocks
    before = data_of(out)
    (out / "pv_nm" / "c" / "0" / "1").unlink()  # a deleted data chunk
    corrupt = out / "rms_nm" / "c" / "1" / "2"
    corrupt.write_bytes(b"\x28\xb5\x2f\xfd garbage")  # a Zstd frame header and then nonsense
    # readers name the corrupt file instead of a codec's error
    with pytest.raises(cube.CubeError, match=str(corrupt)):
        open_cube(out)
    assert_one_line_error(cli(["select", str(out), "--budget-points", "100000"]), str(corrupt))
    report = run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    assert sorted(report.damaged) == [1, 5]
    assert "missing" in report.damaged[1] and "unreadable" in report.damaged[5]
    assert report.skipped == 4 and report.done == 2
    xr.testing.assert_equal(data_of(out), before)


# ----------------------------------------------------------------------------- task failures
def test_task_failure_names_the_case_and_cause(tmp_path, catalog_dir, monkeypatch):
    spec = write(tmp_path, "six.yaml", SIX_CASES)

    def full_disk(self, flat, record, run_id):  # type: ignore[no-untyped-def]
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(caselog.CaseLog, "write_done", full_disk)
    out = tmp_path / "full.zarr"
    r = cli(["sweep", str(spec), "--out", str(out), "--scheduler", "synchronous"], catalog_dir)
    assert_one_line_error(r, "No space left on device")
    assert "case " in r.output.strip().splitlines()[-1] and "N≈" in r.output
    assert int(np.sum(cube.read_status(out) == cube.PENDING)) == 6  # nothing claims to be done
    assert not lock_path(out).exists()


def test_cube_deleted_mid_run_is_reported(tmp_path, catalog_dir):
    spec = write(tmp_path, "six.yaml", SIX_CASES)
    out = tmp_path / "gone.zarr"

    def delete_cube(report, rows):  # type: ignore[no-untyped-def]
        shutil.rmtree(out, ignore_errors=True)

    report = run_sweep(
        str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir, progress=delete_cube
    )
    errors = [r for r in report.rows if r["status"] == "error"]
    assert len(errors) == 5 and all("request" in r and "task error" in r["message"] for r in errors)


@pytest.mark.integration  # waits on an unreachable scheduler
def test_unreachable_scheduler_is_reported_within_seconds(tmp_path, catalog_dir):
    spec = write(tmp_path, "one.yaml", ONE_CASE)
    start = time.perf_counter()
    r = cli(
        ["sweep", str(spec), "--out", str(tmp_path / "x.zarr"), "--scheduler", "tcp://127.0.0.1:1"],
        catalog_dir,
    )
    elapsed = time.perf_counter() - start
    assert_one_line_error(r, "no dask scheduler answered at tcp://127.0.0.1:1")
    assert elapsed < 20, f"took {elapsed:.1f} s"  # the connect timeout is 5 s; startup adds a little
    assert not (tmp_path / "x.zarr").exists()  # the cube it made is not left behind, empty


@pytest.mark.integration  # waits on an unreachable scheduler
def test_an_unreachable_scheduler_leaves_an_existing_cube_as_it_was(tmp_path, catalog_dir):
    """A cube that held finished cases before the run keeps them when the run's cluster never
    comes: only a cube the run itself made is removed."""
    spec = write(tmp_path, "one.yaml", ONE_CASE)
    out = tmp_path / "x.zarr"
    assert (
        cli(["sweep", str(spec), "--out", str(out), "--scheduler", "synchronous"], catalog_dir).exit_code == 0
    )
    grown = write(tmp_path, "one.yaml", ONE_CASE.replace("points: [15000]", "points: [15000, 20000]"))
    r = cli(["sweep", str(grown), "--out", str(out), "--scheduler", "tcp://127.0.0.1:1"], catalog_dir)
    assert_one_line_error(r, "no dask scheduler answered at tcp://127.0.0.1:1")
    status = cli(["status", str(out), "--json"], catalog_dir)
    assert json.loads(status.stdout)["counts"]["done"] == 1  # (status exits 1: a case is still pending)


# ----------------------------------------------------------------------------- probes
BOMB = """
description: &a [&b [&c [&d [&e [x, x, x, x, x, x, x, x, x, x]]]]]
d2: &f [*a, *a, *a, *a, *a, *a, *a, *a, *a, *a]
d3: &g [*f, *f, *f, *f, *f, *f, *f, *f, *f, *f]
d4: &h [*g, *g, *g, *g, *g, *g, *g, *g, *g, *g]
d5: &i [*h, *h, *h, *h, *h, *h, *h, *h, *h, *h]
d6: &j [*i, *i, *i, *i, *i, *i, *i, *i, *i, *i]
d7: &k [*j, *j, *j, *j, *j, *j, *j, *j, *j, *j]
d8: &l [*k, *k, *k, *k, *k, *k, *k, *k, *k, *k]
d9: &m [*l, *l, *l, *l, *l, *l, *l, *l, *l, *l]
surface: small_sine
axes: {points: [8000], aspect: [1.0]}
"""
SPECS = {
    "bomb.yaml": BOMB.replace("d2:", "description2:"),
    "bomb-description.yaml": "description: &a [x, x, x, x, x, x, x, x, x]\n"
    + "".join(f"x{i}: &a{i} [{', '.join(['*a' if i == 0 else f'*a{i - 1}'] * 9)}]\n" for i in range(9))
    + "surface: small_sine\naxes: {points: [8000], aspect: [1.0]}\n",
    "deep.yaml": "surface: small_sine\naxes: {points: [8000], aspect: [1.0]}\ndescription: "
    + "[" * 5000
    + "]" * 5000
    + "\n",
    "huge.yaml": "surface: small_sine\naxes:\n  points: {start: 1000, stop: 900000, num: 100000}\n"
    "  aspect: {start: 0.1, stop: 100, num: 100000}\n",
    "toolong.yaml": "surface: small_sine\naxes:\n  points: {start: 1000, stop: 900000, num: 1000000000}\n"
    "  aspect: [1.0]\n",
}


@pytest.fixture()
def probe_files(tmp_path):
    for name, text in SPECS.items():
        (tmp_path / name).write_text(text)
    (tmp_path / "latin1.yaml").write_bytes("description: Stra\xdfe\nsurface: small_sine\n".encode("latin-1"))
    return tmp_path


# fmt: off
PREDICT = ["predict", "--surface", "small_sine", "--drho-um", "5", "--dtheta-deg", "2"]
SWEEP = ["sweep", "--scheduler", "synchronous"]
PROBES = [
    # (args, fragment of the one-line message); {d} is the probe folder
    ([*PREDICT, "--feed-um", "200"], "not below"),
    ([*PREDICT, "--feed-um", "1e6"], "not below"),
    ([*PREDICT, "--feed-um", "1e6", "--json"], "not below"),
    ([*PREDICT, "--nose-radius-um", "1e9"], "outside the physically meaningful range of --nose-radius-um"),
    ([*PREDICT, "--nose-radius-um", "1e-300"], "(0.001 to 1e+07)"),
    ([*PREDICT[:4], "1e308", *PREDICT[5:]], "range of --drho-um (at most 1e+07 in magnitude)"),
    ([*PREDICT[:2], "sinewave2d", *PREDICT[3:], "--points-per-feed", "100000"], "GiB"),
    ([*PREDICT[:3], "--points", "9e5", "--aspect", "1", "--max-nodes", "1e3"], "max-nodes"),
    (["predict", "--surface", "bad_plugin", "--drho-um", "5", "--dtheta-deg", "2"], "cannot import"),
    (["predict", "--surface", "missing_map", "--drho-um", "5", "--dtheta-deg", "2"], "does not exist"),
    ([*SWEEP, "{d}/bomb.yaml"], "unknown key"),
    ([*SWEEP, "{d}/bomb-description.yaml"], "description"),
    # libyaml up to PyYAML 6.0.3 parses 5,000 levels without recursing (the pure-Python
    # parser ran out of stack: "nested too deeply") and the spec model then names the key
    # that holds them; PyYAML 6.0.4's libyaml refuses the depth itself: both are one line
    ([*SWEEP, "{d}/deep.yaml"], ("description: input should be a valid string", "maximum nesting depth")),
    ([*SWEEP, "{d}/latin1.yaml"], "not UTF-8"),
    ([*SWEEP, "{d}/huge.yaml"], "--max-cases"),
    ([*SWEEP, "{d}/toolong.yaml"], "less than or equal to 100000"),
    (["verify", "{d}/latin1.yaml"], "not an ftsweep header"),
    (["select", "{d}", "--budget-points", "10"], "not a Zarr cube"),
    (["report", "{d}/nothing.zarr"], "no computed, feasible case"),
]
# fmt: on
BAD_SURFACES = """
bad_plugin:
  description: A plug-in whose module does not exist (for tests).
  family: plugin
  layout: ring
  aperture: {shape: circle, radius_um: 300.0}
  params: {function: "no_such_module_issue16:f"}
missing_map:
  description: A height map whose file does not exist (for tests).
  family: height_map
  layout: ring
  aperture: {shape: circle, radius_um: 300.0}
  params: {path: data/no_such_map.npy, spacing_um: [10.0, 10.0]}
"""


@pytest.fixture(scope="module")
def nothing_done(tmp_path_factory, module_catalog_dir):
    """A cube whose only case was refused (over the capacity of the tiny controller)."""
    folder = tmp_path_factory.mktemp("nothing")
    spec = write(folder, "n.yaml", ONE_CASE.replace("[15000]", "[500000]") + "machine: tiny-fts\n")
    out = folder / "nothing.zarr"
    run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=module_catalog_dir)
    assert int(cube.read_status(out).ravel()[0]) == cube.REFUSED
    return out


@pytest.mark.parametrize(
    "args, fragment", PROBES, ids=[" ".join(a[:2]) + f" #{i}" for i, (a, _) in enumerate(PROBES)]
)
def test_every_probe_ends_in_one_line_and_a_nonzero_exit(
    args, fragment, probe_files, catalog_dir, nothing_done
):
    with (catalog_dir / "surfaces.yaml").open("a") as fh:
        fh.write(BAD_SURFACES)
    shutil.copytree(nothing_done, probe_files / "nothing.zarr", dirs_exist_ok=True)
    args = [a.replace("{d}", str(probe_files)) for a in args]
    start = time.perf_counter()
    result = cli(args, catalog_dir)
    assert_one_line_error(result, fragment)
    assert time.perf_counter() - start < 60  # refused up front, not after the work


HELD_DRIVER = """
import sys, threading
from ftsweep.store import faultpoints
from ftsweep.sweeps.run import run_sweep


def hold(event, key):  # the driver held at its first write into the cube, its workers running
    print("HELD", flush=True)
    threading.Event().wait()


faultpoints.WRITE_POINT = hold
run_sweep(sys.argv[1], sys.argv[2], workers=2, catalog_folder=sys.argv[3])
"""


def _descendants(pid: int) -> set[int]:
    """Every process below ``pid`` (from /proc: each process's parent)."""
    parents: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat_line = (entry / "stat").read_text()
            except OSError:
                continue
            parents[int(entry.name)] = int(stat_line.rsplit(")", 1)[1].split()[1])
    found, todo = set(), [pid]
    while todo:
        parent = todo.pop()
        children = {p for p, pp in parents.items() if pp == parent}
        todo.extend(children - found)
        found |= children
    return found


@pytest.mark.integration  # a sweep's driver and its local cluster's workers
@pytest.mark.serial
@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads the process table from /proc")
def test_a_killed_drivers_workers_end_within_seconds(tmp_path, catalog_dir):
    """kill -9 of a sweep's driver held at its first write into the cube (a fault point, not a
    workload's length): no process of its run is left 10 s later."""
    spec = write(tmp_path, "six.yaml", SIX_CASES)
    env = dict(os.environ, FTSWEEP_CATALOGS=str(catalog_dir))
    driver = subprocess.Popen(
        [sys.executable, "-c", HELD_DRIVER, str(spec), str(tmp_path / "six.zarr"), str(catalog_dir)],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        env=env,
    )
    try:
        assert driver.stdout is not None and driver.stdout.readline().strip() == "HELD"
        run = _descendants(driver.pid)
        assert run  # its workers (and multiprocessing's helpers) are running
        driver.kill()
        driver.wait(timeout=30)
        deadline = time.time() + 10.0
        while time.time() < deadline and any(Path(f"/proc/{p}").exists() for p in run):
            time.sleep(0.1)
        alive = [p for p in run if Path(f"/proc/{p}").exists()]
        assert not alive, f"processes of the killed run still alive after 10 s: {alive}"
    finally:
        if driver.poll() is None:
            driver.kill()
