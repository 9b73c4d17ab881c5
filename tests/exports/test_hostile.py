"""Hostile inputs drawn at random (hypothesis, the same draws every run unless
HYPOTHESIS_PROFILE=thorough): mutations of every exported format and of signatures with their
hashes re-made as an attacker would, pause and kill points in a cube's merges, and bombs —
macro expansion, compression, size, loops — whose cost is asserted as counted work (tokens
expanded, bytes unpacked, bytes read, blocks executed), never as time, so the suite holds
under any load."""

from __future__ import annotations

import hashlib
import io
import json
import os
import zipfile
import zlib
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pcpp.preprocessor import Preprocessor
from support.forging import mutated_copy
from support.settings import THOROUGH

from ftsweep.exports import dialects, nc
from ftsweep.exports.files import crc_of
from ftsweep.inputs.programs import gcode
from ftsweep.kinds.table.c_view import read_c
from ftsweep.kinds.table.verify import MAX_HEADER_BYTES
from ftsweep.store import caselog
from ftsweep.store import io as store_io
from ftsweep.sweeps.run import run_sweep
from ftsweep.tools.export import ExportError, export, verify

HOSTILE = settings(
    derandomize=not THOROUGH,
    max_examples=2000 if THOROUGH else 12,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
SPIRAL = "surface: small_sine\nlayout: spiral\naxes: {points_per_rev: [60]}\n"
RING = "surface: small_sine\nlayout: ring\naxes: {points: [15000], aspect: [4.0]}\n"
DIALECTS = ("iso-sts", "linuxcnc")  # the G-code dialects of a linear machine


@pytest.fixture(scope="module")
def exported(tmp_path_factory, module_catalog_dir, shop_keys):
    """A header, a signed header with its public key, and a spiral program in each dialect."""
    folder = tmp_path_factory.mktemp("hostile")
    cubes = {}
    for name, text in (("ring", RING), ("spiral", SPIRAL)):
        (folder / f"{name}.yaml").write_text(text)
        cubes[name] = folder / f"{name}.zarr"
        run_sweep(
            str(folder / f"{name}.yaml"),
            cubes[name],
            scheduler="synchronous",
            catalog_folder=module_catalog_dir,
        )
    out = {"pub": shop_keys[1]}
    os.environ["FTSWEEP_CATALOGS"] = str(module_catalog_dir)
    try:
        export(cubes["ring"], folder / "s.h", index=0, sign_key=str(shop_keys[0]))
        out["signed"] = folder / "s.h"
        for dialect in DIALECTS:
            out[dialect] = folder / f"p-{dialect}.nc"
            export(cubes["spiral"], out[dialect], index=0, dialect=dialect)
    finally:
        del os.environ["FTSWEEP_CATALOGS"]
    return out


def _forge_dialect(program: Path) -> None:
    """Re-make a mutated dialect program's CRC comment and the sidecar's hash of it, as an
    attacker with ftsweep's code would (nothing when the CRC line itself is gone)."""
    lines = program.read_bytes().decode("latin-1").split("\n")[:-1]
    dialect = next((d for d in DIALECTS if f"dialect {d}" in lines[0]), None) if lines else None
    if dialect is None:
        return
    try:
        lines, _ = nc._with_crc(lines, dialect)
    except ExportError:
        return
    raw = ("\n".join(lines) + "\n").encode("latin-1")
    program.write_bytes(raw)
    side = program.with_name(program.name + ".json")
    meta = json.loads(side.read_text())
    meta["program_sha256"] = hashlib.sha256(raw).hexdigest()
    meta["crc32"] = crc_of([ln for ln in lines if "CRC32: " not in ln])
    side.write_text(json.dumps(meta, indent=2))


DIALECT_BYTES = st.sampled_from(
    [b"(", b")", b";", b"%", b"\r", b"\n", b"#", b"[", b"]", b"1", b"9", b"-", b".", b" ", b"G", b"X", b"Z"]
)


@HOSTILE
@given(dialect=st.sampled_from(DIALECTS), data=st.data())
def test_a_mutated_dialect_program_is_refused_whenever_its_text_changed(
    exported, tmp_path_factory, module_catalog_dir, dialect, data
):
    original = exported[dialect]
    text, mutated, program = mutated_copy(data, original, DIALECT_BYTES, tmp_path_factory)
    _forge_dialect(program)
    os.environ["FTSWEEP_CATALOGS"] = str(module_catalog_dir)
    try:
        if program.read_bytes() != text:  # every line is compared with the re-planned text
            with pytest.raises(ExportError):
                verify(program)
    finally:
        del os.environ["FTSWEEP_CATALOGS"]


@HOSTILE
@given(data=st.data())
def test_a_mutated_signature_is_refused(exported, tmp_path_factory, module_catalog_dir, data):
    # any byte of FILE.sig inserted, deleted or replaced: the statement, the key ID, the
    # public key or the signature changes, and a trusted key refuses every one
    signed = exported["signed"]
    text = signed.with_name(signed.name + ".sig").read_bytes()
    pos = data.draw(st.integers(0, len(text) - 1))
    op = data.draw(st.sampled_from(["insert", "delete", "replace"]))
    byte = data.draw(st.sampled_from([b"0", b"1", b"a", b"A", b'"', b" ", b"\n", b"=", b"+", b"/", b"{"]))
    mutated = text[:pos] + (byte if op != "delete" else b"") + text[pos + (op != "insert") :]
    folder = tmp_path_factory.mktemp("sig")
    for suffix in ("", ".json"):
        (folder / f"{signed.name}{suffix}").write_bytes(Path(f"{signed}{suffix}").read_bytes())
    (folder / f"{signed.name}.sig").write_bytes(mutated)
    os.environ["FTSWEEP_CATALOGS"] = str(module_catalog_dir)
    try:
        if mutated != text:
            # the file and its sidecar are untouched: only the signature can be what is refused
            with pytest.raises(ExportError, match=r"s\.h\.sig|signature|signed|key"):
                verify(folder / signed.name, trusted=(str(exported["pub"]),))
    finally:
        del os.environ["FTSWEEP_CATALOGS"]


# ------------------------------------------------------------------ bombs, as counted work
# the functions whose work is counted, as they are before any example wraps them (hypothesis
# runs every example under one monkeypatch)
_FDOPEN = os.fdopen
_DECOMPRESSOBJ = zlib.decompressobj
_EXPAND = Preprocessor.expand_macros


@pytest.fixture(scope="module")
def header_text(tmp_path_factory, module_catalog_dir):
    folder = tmp_path_factory.mktemp("bomb")
    (folder / "r.yaml").write_text(RING)
    run_sweep(
        str(folder / "r.yaml"), folder / "r.zarr", scheduler="synchronous", catalog_folder=module_catalog_dir
    )
    os.environ["FTSWEEP_CATALOGS"] = str(module_catalog_dir)
    try:
        export(folder / "r.zarr", folder / "r.h", index=0)
    finally:
        del os.environ["FTSWEEP_CATALOGS"]
    return (folder / "r.h").read_text()


def _count_expansion(monkeypatch) -> dict[str, int]:  # type: ignore[no-untyped-def]
    """The tokens the C preprocessor expands from now on, counted (the count shown to count
    by a clean header's expansion first)."""
    expanded = {"tokens": 0}

    def counting(self, tokens, *args, **kwargs):  # type: ignore[no-untyped-def]
        expanded["tokens"] += len(tokens)
        return _EXPAND(self, tokens, *args, **kwargs)

    monkeypatch.setattr(Preprocessor, "expand_macros", counting)
    return expanded


@HOSTILE
@given(depth=st.integers(2, 60), width=st.integers(2, 8), at=st.integers(0, 20))
def test_a_macro_expansion_bomb_is_refused_before_it_expands(header_text, monkeypatch, depth, width, at):
    # D0 = 1; Dk = D(k-1) repeated `width` times: width^depth tokens if expanded
    expanded = _count_expansion(monkeypatch)
    read_c(header_text.encode(), "clean")
    clean = expanded["tokens"]
    assert clean > 0  # the counter sees the preprocessor's work
    bomb = ["#define D0 1"] + [f"#define D{k} " + " ".join([f"D{k - 1}"] * width) for k in range(1, depth)]
    rows = header_text.split("\n")
    first_define = next(i for i, r in enumerate(rows) if r.startswith("#define ") and "_H" not in r)
    place = first_define + min(at, 5)
    forged = "\n".join(rows[:place] + bomb + [f"#define USE D{depth - 1}"] + rows[place:])
    expanded["tokens"] = 0
    with pytest.raises(ExportError, match="names the macro D0"):
        read_c(forged.encode(), "bomb")
    # refused at its second line: at most the file's own tokens were looked at
    assert expanded["tokens"] <= clean + 10 * depth * width


@pytest.mark.parametrize("depth", [12, 16, 20, 40])
def test_a_forward_macro_chain_is_refused_at_its_first_line(header_text, monkeypatch, depth):
    """#define M0 M1 M1 … #define M(d-1) Md Md, #define Md 1 and one use: each replacement
    names a macro defined after it, which C expands only at the use (2^depth tokens). The
    first definition holds an identifier: refused there, before anything is expanded."""
    expanded = _count_expansion(monkeypatch)
    read_c(header_text.encode(), "clean")
    clean = expanded["tokens"]
    chain = [f"#define M{k} M{k + 1} M{k + 1}" for k in range(depth)] + [f"#define M{depth} 1"]
    rows = header_text.split("\n")
    first_define = next(i for i, r in enumerate(rows) if r.startswith("#define ") and "_H" not in r)
    use = "enum { BOMB = sizeof((int[]){M0}) };"
    forged = "\n".join(rows[:first_define] + chain + rows[first_define:-2] + [use] + rows[-2:])
    expanded["tokens"] = 0
    with pytest.raises(
        ExportError, match=rf"line {first_define + 1}: M0's replacement holds the identifier M1"
    ):
        read_c(forged.encode(), "chain")
    assert expanded["tokens"] <= clean + 10


def _zip_bomb(megabytes: int, level: int) -> bytes:
    """A one-member npz whose member deflates ``megabytes`` MiB of zeros (honestly declared)."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=level) as archive:
        with archive.open("message.value.npy", "w", force_zip64=True) as fh:
            zeros = bytes(2**20)
            for _ in range(megabytes):
                fh.write(zeros)
    return buffer.getvalue()


@settings(HOSTILE, max_examples=2000 if THOROUGH else 6)
@given(megabytes=st.integers(1, 96), level=st.integers(1, 9), cases=st.integers(1, 64))
def test_a_compressed_log_bomb_unpacks_no_more_than_its_cube_can_hold(monkeypatch, megabytes, level, cases):
    shapes = {"status": (cases,), "pv_nm": (cases,), "message": (cases,)}
    cap = caselog.unpacked_cap(shapes)
    unpacked = {"bytes": 0}

    class Counting:
        def __init__(self, *args):  # type: ignore[no-untyped-def]
            self.inner = _DECOMPRESSOBJ(*args)

        def decompress(self, chunk, *args):  # type: ignore[no-untyped-def]
            out = self.inner.decompress(chunk, *args)
            unpacked["bytes"] += len(out)
            return out

        def __getattr__(self, name):  # type: ignore[no-untyped-def]
            return getattr(self.inner, name)

    monkeypatch.setattr(zipfile.zlib, "decompressobj", Counting)
    with zipfile.ZipFile(io.BytesIO(_zip_bomb(1, 1))) as honest:  # the counter sees unpacking
        assert len(honest.read("message.value.npy")) == unpacked["bytes"] == 2**20
    unpacked["bytes"] = 0
    bomb = _zip_bomb(megabytes, level)
    try:
        caselog._columns(bomb, cap)
    except caselog.BadLog as exc:
        refused = str(exc)
    else:  # pragma: no cover - a log that unpacks within the cap is not a bomb
        refused = ""
    assert unpacked["bytes"] <= cap
    if megabytes * 2**20 > cap:
        assert "more than a log of this cube can hold" in refused and unpacked["bytes"] == 0


# a first line names the format, and so the cap the file is judged by: a header's (the
# default, anything no program's first line names) or a program's
FIRST_LINES = [
    (b"", MAX_HEADER_BYTES),
    (b"/* ftsweep */\n", MAX_HEADER_BYTES),
    (b"(ftsweep spiral, dialect iso-sts)\n", store_io.MAX_PROGRAM_BYTES),
    (b"# ftsweep spiral program\n", store_io.MAX_PROGRAM_BYTES),
]


@settings(HOSTILE, max_examples=2000 if THOROUGH else 8)
@given(
    suffix=st.sampled_from([".h", ".txt", ".nc"]),
    excess=st.integers(1, 2**35),
    first=st.sampled_from(FIRST_LINES),
)
def test_a_file_past_its_cap_is_refused_having_read_its_first_line_at_most(
    tmp_path_factory, monkeypatch, suffix, excess, first
):
    path = tmp_path_factory.mktemp("sparse") / f"big{suffix}"
    head, cap = first
    with open(path, "wb") as fh:
        fh.write(head)
        fh.truncate(cap + excess)  # sparse: the size is a claim, not data
    read = {"bytes": 0}

    class Counting:
        def __init__(self, fh):  # type: ignore[no-untyped-def]
            self.fh = fh

        def read(self, n=-1):  # type: ignore[no-untyped-def]
            got = self.fh.read(n)
            read["bytes"] += len(got)
            return got

        def __enter__(self):  # type: ignore[no-untyped-def]
            return self

        def __exit__(self, *exc):  # type: ignore[no-untyped-def]
            self.fh.close()

    monkeypatch.setattr(os, "fdopen", lambda fd, *a, **k: Counting(_FDOPEN(fd, *a, **k)))
    with pytest.raises(ExportError, match="more than any|bytes"):
        verify(path)
    assert read["bytes"] <= 200  # the head that names the format, never the body


LOOP = [
    "G90 G21 G18 G94",
    "#1 = 0",
    "G93",
    "WHILE [#1 LT {n}] DO1",
    "G01 C[#1*0.1] X[10.0-#1*0.00001] Z0.0 F0.001",
    "#1 = #1 + 1",
    "END1",
    "M30",
]


# the units one pass of LOOP's body costs: its three lines, the G01's two expressions (5 and 4
# nodes), the assignment (3) and the WHILE's condition (3)
PASS_UNITS = 3 * gcode.LINE_UNITS + 9 + 3 + 3


@settings(HOSTILE, max_examples=2000 if THOROUGH else 20)
@given(passes=st.one_of(st.integers(1, 3000), st.integers(1, 10**15)), floor=st.integers(100, 50_000))
def test_a_g_code_loop_does_no_more_work_than_its_budget(monkeypatch, passes, floor):
    """The budget counts lines executed and expression nodes parsed and evaluated; a loop
    stops within one line of it, whatever the count it asks for."""
    monkeypatch.setattr(gcode, "WORK_FLOOR", floor)
    monkeypatch.setattr(gcode, "WORK_PER_BYTE", 0)
    lines = [line.format(n=passes) for line in LOOP]
    from ftsweep.inputs.controllers import Controller

    ctrl = Controller(dialect="iso-sts", interpolation="linear", g93_f="seconds")
    reader = gcode.IsoReader(lines, "iso-sts", ctrl)
    try:
        reader.run()
        message = ""
    except dialects.DialectError as exc:  # the budget, or what the program then lacks
        message = str(exc)
    assert reader.work <= floor + PASS_UNITS
    over = "work passed" in message
    # refused exactly when the passes' work passes the budget (counted: the first pass and
    # the lines around the loop make up the rest)
    assert over == (reader.work > floor)
    if not over:
        assert passes * PASS_UNITS <= floor


@pytest.mark.parametrize(
    ("expression", "why"),
    [
        ("1" + "+1" * 100_000, "more than 100,000 tokens"),
        ("[" * 10_000 + "1" + "]" * 10_000, ""),
        ("[" * 1_000_000 + "1", "more than 100,000 tokens"),
        ("##1", "indirect variable"),
        ("#" + "9" * 5000, "does not exist"),
        ("1\n#" + "9" * 5000 + " = 1", "does not exist"),
        ("ROUND[1" + "0" * 400 + "]", "not a finite number|no finite value"),
        ("FIX[1" + "0" * 400 + "] + #2", "no finite value|not a finite number"),
    ],
)
def test_an_expression_is_parsed_in_counted_linear_work(expression, why):
    """Iterative precedence parsing: brackets any depth cost their tokens, an expression of
    more than MAX_TOKENS tokens is refused before it is parsed whole, and every refusal is
    the reader's line and reason, never a raw Python message."""
    from ftsweep.inputs.programs import macro

    lines = ["G90 G18", "#2 = 1", *f"#1 = {expression}".split("\n"), "M30"]
    from ftsweep.inputs.controllers import Controller

    reader = gcode.IsoReader(lines, "iso-sts", Controller(dialect="iso-sts"))
    if not why:
        with pytest.raises(dialects.DialectError, match="no cutting block"):
            reader.run()
        assert reader.vars[1] == 1.0 and reader.work <= 2 * macro.MAX_TOKENS
        return
    with pytest.raises(dialects.DialectError, match=rf"^line [34] .*({why})"):
        reader.run()


SPECIAL_PROBE = """
import json, sys, warnings
from ftsweep.store import caselog
from ftsweep.tools.status import cube_status
from ftsweep.tools.select import open_cube
out = {}
status = cube_status(sys.argv[1])
out["done"], out["unreadable"] = status["counts"]["done"], status["unreadable"]
try:
    open_cube(sys.argv[1])
    out["select"] = "read"
except Exception as exc:
    out["select"] = f"{type(exc).__name__}: {exc}"
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    caselog.merge_logs(sys.argv[1])
out["warnings"] = [str(w.message) for w in caught]
print(json.dumps(out))
"""


@pytest.fixture(scope="module")
def ring_cube(tmp_path_factory, module_catalog_dir):
    folder = tmp_path_factory.mktemp("special")
    (folder / "ring.yaml").write_text(RING)
    run_sweep(
        str(folder / "ring.yaml"),
        folder / "ring.zarr",
        scheduler="synchronous",
        catalog_folder=module_catalog_dir,
    )
    return folder / "ring.zarr"


def _special(path: Path, kind: str) -> None:
    import socket

    path.parent.mkdir(parents=True, exist_ok=True)
    path.unlink(missing_ok=True)
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "socket":  # bound at a short path (AF_UNIX's limit), then moved into the cube
        import tempfile

        short = Path(tempfile.mkdtemp(prefix="s", dir="/tmp")) / "s"
        sock = socket.socket(socket.AF_UNIX)
        sock.bind(str(short))
        sock.close()
        os.rename(short, path)
        short.parent.rmdir()
    else:
        path.symlink_to("/dev/zero")


@pytest.mark.parametrize("kind", ["fifo", "socket", "dev-zero"])
@pytest.mark.parametrize("where", ["log", "block"])
def test_a_special_file_in_a_cube_blocks_no_reader(ring_cube, tmp_path, kind, where):
    """A FIFO, a socket or a link to /dev/zero among a cube's logs is quarantined by the merge
    (a warning naming it) and skipped by status and select; among its blocks it is named by
    status and refused by select, never opened to read. (memory:// holds no special files.)"""
    import shutil
    import subprocess
    import sys

    cube = tmp_path / "c.zarr"
    shutil.copytree(ring_cube, cube)
    if where == "log":
        entry = cube / "_log" / "20261206T000000-aaaaaaaa" / "0123456789ab-000001.npz"
    else:
        entry = next(p for p in sorted((cube / "pv_nm").rglob("*")) if p.is_file() and p.name != "zarr.json")
    _special(entry, kind)
    # the timeout only guards the suite against a hang: the outcome is asserted, not the time
    run = subprocess.run(
        [sys.executable, "-c", SPECIAL_PROBE, str(cube)], capture_output=True, text=True, timeout=120
    )
    assert run.returncode == 0, run.stderr[-2000:]
    got = json.loads(run.stdout)
    if where == "log":
        assert got["done"] == 1 and got["select"] == "read" and not got["unreadable"]
        assert any(
            "is not what a worker writes" in w and "not a file ftsweep writes" in w for w in got["warnings"]
        )
        assert not os.path.lexists(entry)  # quarantined: deleted unread
    else:
        assert got["done"] == 0 and "not a block ftsweep writes" in got["unreadable"][0]
        assert "unreadable chunks" in got["select"] and str(entry) in got["select"]
        assert os.path.lexists(entry)  # named, left for the next sweep to rewrite


@pytest.mark.parametrize("var", ["pv_inner_nm", "pv_outer_nm", "mean_nm", "error_min_nm"])
def test_a_done_log_with_a_non_finite_metric_is_refused(var):
    """Every metric the simulator refuses a case without is finite in a done case's log, or
    the log is quarantined: a NaN P-V of a zone or a NaN mean error included."""
    values = {
        "pv_nm": 10.0,
        "rms_nm": 2.0,
        "error_min_nm": -4.0,
        "error_max_nm": 6.0,
        "mean_nm": 0.5,
        "pv_inner_nm": 9.0,
        "pv_outer_nm": 10.0,
        "status": caselog.DONE,
    }
    shapes = {name: (4,) for name in values}
    assert caselog.checked_cases(caselog._encode([(1, values)]), shapes)  # the honest log passes
    values[var] = float("nan")
    with pytest.raises(caselog.BadLog, match=rf"case 1 is done but its {var} is nan"):
        caselog.checked_cases(caselog._encode([(1, values)]), shapes)


def test_a_sweep_spec_with_a_list_past_the_bound_is_refused_before_it_is_built(tmp_path, monkeypatch):
    """A list past MAX_LIST_ITEMS is refused from the YAML event stream, at the item past the
    bound: the events counted, never the whole file's objects built."""
    import yaml

    from ftsweep.inputs import yamlfiles
    from ftsweep.inputs.catalogs import CatalogError

    monkeypatch.setattr(yamlfiles, "MAX_LIST_ITEMS", 1000)
    events = {"n": 0}
    real = yaml.parse

    def counting(*args, **kwargs):  # type: ignore[no-untyped-def]
        for event in real(*args, **kwargs):
            events["n"] += 1
            yield event

    monkeypatch.setattr(yaml, "parse", counting)
    spec = tmp_path / "big.yaml"
    values = ", ".join(str(1000 + k) for k in range(50_000))
    spec.write_text(f"surface: sinewave2d\nlayout: ring\naxes:\n  points: [{values}]\n  aspect: [4.0]\n")
    with pytest.raises(CatalogError, match=r"line 4: a list of more than 1,000 items"):
        yamlfiles.read_yaml_file(spec)
    assert events["n"] < 1100  # stopped at the item past the bound


def test_a_fenced_runs_workers_write_nothing_and_the_taker_removes_their_logs(ring_cube, tmp_path):
    """Once a run's lease is taken over (its log folder fenced), its workers' next log write
    raises before anything is written; a log one of them wrote before the fence is deleted
    unread by the taking run's merge, so the cube's objects are the taker's."""
    import shutil

    cube = tmp_path / "c.zarr"
    shutil.copytree(ring_cube, cube)
    stale = caselog.CaseLog(cube, "20261206T000000-stale000")
    stale.write_failed(0, "written before the takeover", "20261206T000000-stale000")
    listed = caselog.fence_run(cube, "20261206T000000-stale000")
    assert len(listed) == 1  # the taker may read the log listed before the fence, none after
    late = caselog.CaseLog(cube, "20261206T000000-stale000")
    with pytest.raises(caselog.Fenced, match="taken over: its workers write nothing more"):
        late.write_failed(1, "written after the takeover", "20261206T000000-stale000")
    logs = sorted(p.name for p in (cube / "_log" / "20261206T000000-stale000").iterdir())
    assert len(logs) == 2 and "FENCED" in logs  # the one before the fence, and the marker
    caselog.merge_logs(cube, keep=frozenset())  # a taker that kept none of them
    left = [p for p in (cube / "_log").rglob("*") if p.is_file() and p.name != "FENCED"]
    assert not left
