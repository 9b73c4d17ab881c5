"""Exported files are read as the C compiler and the controller read them: free text never
becomes syntax, a header is judged by what a real preprocessor and parser make of it, a
program line by line as a controller splits lines, and only regular files are read. Each
attack is first shown to work on what C or the controller would execute."""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support.forging import (
    entered_in_ledger,
    forge_header_from_sidecar,
    forge_header_text,
    forge_program,
    mutated_copy,
)
from support.settings import THOROUGH

from ftsweep.cli.main import main
from ftsweep.exports.files import CRC_LINE, crc_of, sidecar_digest
from ftsweep.kinds.table.c_view import read_c
from ftsweep.kinds.table.header import render_header
from ftsweep.store.io import read_sidecar
from ftsweep.sweeps.run import run_sweep
from ftsweep.tools.export import ExportError, export, verify

CC = shutil.which("cc") or shutil.which("gcc")
needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler on this machine")

RING = "surface: small_sine\nlayout: ring\naxes: {points: [15000], aspect: [4.0]}\n"
SPIRAL = "surface: small_sine\nlayout: spiral\naxes: {points_per_rev: [60]}\n"


def cli(args: list[str], catalogs: Path):  # type: ignore[no-untyped-def]
    return CliRunner().invoke(main, args, env={"FTSWEEP_CATALOGS": str(catalogs)})


@pytest.fixture(scope="module")
def originals(tmp_path_factory, module_catalog_dir):
    """A ring header and a spiral program, freshly exported (tests edit copies)."""
    folder = tmp_path_factory.mktemp("originals")
    out = {}
    for name, text, suffix in (("fts", RING, ".h"), ("prog", SPIRAL, ".txt")):
        spec = folder / f"{name}.yaml"
        spec.write_text(text)
        cube_path = folder / f"{name}.zarr"
        run_sweep(str(spec), cube_path, scheduler="synchronous", catalog_folder=module_catalog_dir)
        os.environ["FTSWEEP_CATALOGS"] = str(module_catalog_dir)
        try:
            export(cube_path, folder / f"{name}{suffix}", index=0)
        finally:
            del os.environ["FTSWEEP_CATALOGS"]
        out[name] = folder / f"{name}{suffix}"
    return out


@pytest.fixture()
def copies(originals, tmp_path, module_catalog_dir, monkeypatch):
    monkeypatch.setenv("FTSWEEP_CATALOGS", str(module_catalog_dir))
    out = {}
    for name, path in originals.items():
        for suffix in ("", ".json"):
            shutil.copy(f"{path}{suffix}", tmp_path / f"{name}{path.suffix}{suffix}")
        out[name] = tmp_path / path.name
    return out


INJECTED = "ftsweep 0.0.0 a forged o */\n#\tdefine FTS_H\n#\tdefine FTS_PITCH0 7.63\n/*"


def c_macros(header: Path) -> dict[str, str]:
    """The macros gcc's preprocessor ends with, by name (``cc -E -dM``)."""
    out = subprocess.run(
        [CC, "-E", "-dM", "-x", "c", str(header)], capture_output=True, text=True, check=True
    )
    pairs = (line.split(None, 2)[1:] for line in out.stdout.splitlines() if line.startswith("#define "))
    return {p[0]: (p[1] if len(p) > 1 else "") for p in pairs}


# ------------------------------------------------------------------ the header
@needs_cc
def test_free_text_in_the_sidecar_cannot_rewrite_the_header(copies):
    header = copies["fts"]
    good_pitch = c_macros(header)["FTS_PITCH0"]
    forge_header_from_sidecar(header, lambda m: m.update(generator=INJECTED))
    # the attack is real: C reads the injected pitch and skips the real definitions
    assert c_macros(header)["FTS_PITCH0"] == "7.63" != good_pitch
    with pytest.raises(ExportError, match="line 13: a conditional other than the include guard"):
        verify(header)  # C's reading of the header refuses it
    with pytest.raises(ExportError, match=r"fts.h.json: fts.h.json.generator holds '\*' at character 26"):
        read_sidecar(header)  # and the sidecar's text is refused where it enters, on its own


def test_the_header_is_judged_by_what_c_reads_even_with_a_clean_sidecar(copies):
    # the injected lines in the header alone, every checksum re-made: C's reading refuses them
    header = copies["fts"]
    text = header.read_text()
    forged = text.replace(" */\n#ifndef", " */\n#\tdefine FTS_H\n#\tdefine FTS_PITCH0 7.63\n#ifndef", 1)
    forge_header_text(header, forged)
    with pytest.raises(ExportError, match="line 12: a conditional other than the include guard"):
        verify(header)


D0, UNIT, INC = "#define FTS_PITCH0", "#define FTS_UNIT_NM", "#include <stdint.h>"
OPEN, CLOSE = " = {\n", "\n};"
# id -> ((old, new) replacements, what the refusal names)
EDITS = {
    "include-file": ([(INC, '#include "/etc/hostname"')], "#include"),
    "include-system": ([(INC, INC + "\n#include <stdio.h>")], "#include"),
    "undef": ([("#define FTS_ROWS", "# define FTS_ROWS 1\n#undef FTS_ROWS\n#define FTS_ROWS")], "#undef"),
    "redefine": ([(D0, "# define FTS_PITCH0 7.63\n" + D0)], "second definition"),
    "conditional": ([(D0, "#define FTS_PITCH0 7.63\n#if 0\n" + D0)], "#if"),
    "function-like": ([(UNIT, "#define FTS_X(a) a\n" + UNIT)], "function-like"),
    "pragma": ([(UNIT, "#pragma once\n" + UNIT)], "#pragma"),
    "rows-skipped": ([(OPEN, OPEN + "#if 0\n"), (CLOSE, "\n#endif" + CLOSE)], "#if"),
    "rows-in-comment": ([(OPEN, OPEN + "/*\n"), (CLOSE, "\n*/" + CLOSE)], "other declarations"),
    "second-table": (
        [(CLOSE, CLOSE + "\nstatic const int32_t fts_other[1][1] = {{1}};")],
        "other declarations",
    ),
    "expression": ([(D0 + " ", D0 + " 2. + ")], "C reads macro PITCH0"),
    "comment-in-value": ([(D0 + " ", D0 + " /* */ 1.0 + ")], "C reads macro PITCH0"),
    "splice": ([(D0 + " ", D0 + " \\\n")], "C reads macro PITCH0|line"),
    "octal-cell": ([("    {1000, ", "    {01000, ")], "holds '01000', not an integer as export writes one"),
    # 30 macros each twice the one before: refused at the second, before anything is expanded
    "expansion-bomb": (
        [
            (
                UNIT,
                "#define FTS_B0 1\n"
                + "".join(f"#define FTS_B{k} FTS_B{k - 1}+FTS_B{k - 1}\n" for k in range(1, 31))
                + UNIT,
            )
        ],
        "FTS_B1's replacement names the macro FTS_B0 .*nothing expanded",
    ),
}


@pytest.mark.parametrize("edit", list(EDITS))
def test_anything_export_does_not_write_is_refused_by_name(copies, edit):
    header = copies["fts"]
    replacements, message = EDITS[edit]
    text = header.read_text()
    for old, new in replacements:
        assert old in text
        text = text.replace(old, new, 1)
    forge_header_text(header, text)
    with pytest.raises(ExportError, match=message):
        verify(header)


@needs_cc
def test_the_c_view_is_what_gcc_reads(originals):
    header = originals["fts"]
    view = read_c(header.read_bytes(), str(header))
    gcc = c_macros(header)
    assert {k: gcc[k] for k, _ in view.macros} == dict(view.macros)
    assert view.guard in gcc


def _gcc_cells(header: Path, folder: Path, name: str, int_type: str) -> list[int] | None:
    """The cells of table ``name`` as a program compiled by gcc reads them (None: gcc refuses
    the file)."""
    main_c = folder / "main.c"
    main_c.write_text(
        f'#include <stdio.h>\n#include "{header.name}"\n'
        f"int main(void) {{ const {int_type} *p = &{name}[0][0];\n"
        f'  for (long k = 0; k < (long)(sizeof {name} / sizeof *p); ++k) printf("%ld\\n", (long)p[k]);\n'
        "  return 0; }\n"
    )
    exe = folder / "main"
    built = subprocess.run(
        [CC, "-std=c99", "-w", "-o", str(exe), str(main_c)], capture_output=True, cwd=folder
    )
    if built.returncode:
        return None
    return [int(v) for v in subprocess.run([str(exe)], capture_output=True, text=True).stdout.split()]


# the byte-mutation properties draw the same examples every run, so CI never fails by the
# draw; HYPOTHESIS_PROFILE=thorough draws thousands of fresh ones (tests/conftest.py)
MUTATIONS = settings(derandomize=not THOROUGH, suppress_health_check=[HealthCheck.function_scoped_fixture])

BYTES = st.sampled_from(
    [b"#", b"/", b"*", b"\n", b"\\", b'"', b"1", b"9", b"-", b" ", b"x", b"{", b"}", b",", b"?"]
)


@needs_cc
@MUTATIONS
@given(data=st.data())
def test_mutated_headers_are_refused_whenever_c_would_read_other_values(
    originals, tmp_path_factory, module_catalog_dir, data
):
    # any byte inserted, deleted or replaced, inside or outside comments: when the C view
    # accepts the file it agrees with gcc, and verify refuses whenever the values differ
    original = originals["fts"]
    text, mutated, header = mutated_copy(data, original, BYTES, tmp_path_factory)
    folder = header.parent
    base = read_c(text, "original")
    try:
        view = read_c(mutated, "mutated")
    except ExportError:
        view = None
    if view is not None:  # accepted in form: it must be what gcc reads
        gcc = c_macros(header)
        assert {k: gcc.get(k) for k, _ in view.macros} == dict(view.macros)
        assert _gcc_cells(header, folder, view.name, view.int_type) == view.cells.ravel().tolist()
    forge_header_text(header, mutated.decode("latin-1"))
    # the same reading and the same cells: exported on this platform, so verify allows no
    # difference from the re-planned table (one unit only across platforms)
    same = (
        view is not None
        and (view.macros, view.name, view.int_type, view.guard)
        == (base.macros, base.name, base.int_type, base.guard)
        and view.cells.shape == base.cells.shape
        and bool(np.array_equal(view.cells, base.cells))
    )
    if not same:
        os.environ["FTSWEEP_CATALOGS"] = str(module_catalog_dir)
        try:
            with pytest.raises(ExportError):
                verify(header)
        finally:
            del os.environ["FTSWEEP_CATALOGS"]


# ------------------------------------------------------------------ programs
def test_a_line_end_in_the_sidecar_never_becomes_a_motion_line(copies):
    program = copies["prog"]
    forge_program(program, lambda m: m.update(generator=m["generator"] + "\r0.000 0.5 -0.1"))
    assert b"\r0.000 0.5 -0.1\n" in program.read_bytes()  # a CR-splitting controller runs this line
    with pytest.raises(ExportError, match="carriage return|generator holds"):
        verify(program)


@pytest.mark.parametrize("spelling", ["4e0", "+{v}", "{v}0", "0{v}"])
def test_a_data_line_spelt_otherwise_is_refused(copies, spelling):
    program = copies["prog"]
    rows = program.read_bytes().decode().split("\n")
    k = len(rows) - 5
    first = rows[k].split(" ")
    first[1] = spelling.format(v=first[1]) if "{v}" in spelling else spelling
    rows[k] = " ".join(first)
    at = next(i for i, r in enumerate(rows) if r.startswith("# CRC32:"))
    rows[at] = CRC_LINE.format(crc_of(rows[:at] + rows[at + 1 : -1]))
    program.write_bytes("\n".join(rows).encode())
    with pytest.raises(ExportError, match=f"line {k + 1}, column .*: a data line"):
        verify(program)


# ------------------------------------------------------------------ what is read at all
@pytest.mark.parametrize("target", ["/dev/zero", "fifo", "folder"])
def test_only_regular_files_are_read_and_refused_at_once(tmp_path, module_catalog_dir, target):
    if target == "fifo":
        path = tmp_path / "p.h"
        os.mkfifo(path)
    elif target == "folder":
        path = tmp_path / "d.h"
        path.mkdir()
    else:
        path = Path(target)
    start = time.perf_counter()
    with pytest.raises(ExportError, match="not a regular"):
        verify(path)
    assert time.perf_counter() - start < 1.0


def test_verify_dev_zero_exits_nonzero_within_a_second(tmp_path):
    start = time.perf_counter()
    done = subprocess.run(
        [str(Path(sys.executable).parent / "ftsweep"), "verify", "/dev/zero"],
        capture_output=True,
        text=True,
        timeout=30,
    )
    elapsed = time.perf_counter() - start
    assert done.returncode != 0 and "not a regular file" in done.stderr
    print(f"ftsweep verify /dev/zero: exit {done.returncode} in {elapsed:.2f} s")


def test_a_sidecar_number_beyond_a_float_is_named(copies, module_catalog_dir):
    header = copies["fts"]
    side = header.with_name(header.name + ".json")
    side.write_text(side.read_text().replace('"crc32": ', '"crc32": 1e400, "x": ', 1))
    res = cli(["verify", str(header)], module_catalog_dir)
    assert res.exit_code == 1 and "does not fit a float" in res.output and "unexpected" not in res.output


def test_an_output_name_that_would_become_syntax_is_refused(originals, tmp_path, module_catalog_dir):
    cube_path = originals["fts"].with_suffix(".zarr")
    res = cli(["export", str(cube_path), "--case", "0", "-o", str(tmp_path / "a*b.h")], module_catalog_dir)
    assert res.exit_code == 1 and "file's name holds '*'" in res.output
    assert not list(tmp_path.iterdir())


def test_a_catalog_entry_name_that_would_become_syntax_is_refused(tmp_path, module_catalog_dir):
    from ftsweep.inputs.catalogs import CatalogError, entries

    folder = tmp_path / "cat"
    shutil.copytree(module_catalog_dir, folder)
    with (folder / "machines.yaml").open("a") as fh:
        fh.write('\n"evil */ #define":\n  description: x\n')
    with pytest.raises(CatalogError, match=r"entry's name holds '\*'"):
        entries("machines", folder)


# ------------------------------------------------------------------ origin
def test_a_new_private_key_is_its_owners_alone(shop_keys):
    key, pub = shop_keys
    assert oct(key.stat().st_mode & 0o777) == "0o600" and pub.stat().st_size > 0


def test_signed_export_verifies_with_its_key_and_any_change_is_refused(
    originals, tmp_path, module_catalog_dir, shop_keys
):
    key, pub = shop_keys
    out = tmp_path / "signed.h"
    cube_path = str(originals["fts"].with_suffix(".zarr"))
    res = cli(
        ["export", cube_path, "--case", "0", "-o", str(out), "--sign-key", str(key)], module_catalog_dir
    )
    assert res.exit_code == 0 and "signature" in res.output, res.output
    ok = cli(["verify", str(out), "--trusted-key", str(pub)], module_catalog_dir)
    assert ok.exit_code == 0 and "origin       signed by key" in ok.output, ok.output
    # another key is not trusted
    other = cli(["keys", "new", "-o", str(tmp_path / "other")], module_catalog_dir)
    assert other.exit_code == 0
    res = cli(["verify", str(out), "--trusted-key", str(tmp_path / "other.pub")], module_catalog_dir)
    assert res.exit_code == 1 and "not trusted here" in res.output
    # one changed byte anywhere in the file, its sidecar or the signature: refused
    for target in (out, out.with_name(out.name + ".json"), out.with_name("signed.h.sig")):
        original = target.read_bytes()
        for pos in (0, len(original) // 2, len(original) - 2):
            changed = bytearray(original)
            changed[pos] = ord("A") if changed[pos] != ord("A") else ord("B")
            target.write_bytes(bytes(changed))
            res = cli(["verify", str(out), "--trusted-key", str(pub)], module_catalog_dir)
            assert res.exit_code == 1, (target.name, pos, res.output)
        target.write_bytes(original)
    # unsigned: refused when a key is trusted
    out.with_name("signed.h.sig").unlink()
    res = cli(["verify", str(out), "--trusted-key", str(pub)], module_catalog_dir)
    assert res.exit_code == 1 and "is not signed" in res.output


def test_trusted_keys_come_from_the_config_file(
    originals, tmp_path, module_catalog_dir, shop_keys, monkeypatch
):
    key, pub = shop_keys
    config = tmp_path / "config.toml"
    config.write_text(f'signing_key = "{key}"\ntrusted_keys = ["{pub}"]\n')
    monkeypatch.setenv("FTSWEEP_CONFIG", str(config))
    out = tmp_path / "c.h"
    res = cli(
        ["export", str(originals["fts"].with_suffix(".zarr")), "--case", "0", "-o", str(out)],
        module_catalog_dir,
    )
    assert res.exit_code == 0 and out.with_name("c.h.sig").exists(), res.output
    res = cli(["verify", str(out)], module_catalog_dir)
    assert res.exit_code == 0 and "signed by key" in res.output, res.output


def test_a_consistent_forgery_of_the_recorded_surface_is_refused_against_the_catalog(
    copies, module_catalog_dir
):
    # halve the recorded amplitude, re-plan the table with ftsweep's own planner and re-make
    # every hash: consistent, so only the catalog (or a signature) can tell
    from ftsweep.exports.files import recorded_case_of
    from ftsweep.kinds.table.header import planned_ints
    from ftsweep.kinds.table.layout import build_layout

    header = copies["fts"]
    side = header.with_name(header.name + ".json")
    meta = json.loads(side.read_text())
    params = meta["catalog_entries"]["surface"]["params"]
    key = next(k for k in params if k.startswith("amplitude"))
    params[key] /= 2
    side.write_text(json.dumps(meta))
    case, specs = recorded_case_of(meta, side)
    ints = planned_ints(case, specs, build_layout(specs[0], case.layout))

    def forge() -> None:
        rendered = dict(meta, sidecar_sha256=sidecar_digest(meta))
        text, crc = render_header(header.stem, rendered, ints, meta["int_type"])
        meta.update(crc32=crc, header_sha256=hashlib.sha256(text.encode()).hexdigest())
        header.write_text(text)
        side.write_text(json.dumps(meta, indent=2))

    forge()  # and the predicted P-V re-simulated from the forged table, as a forger would
    with entered_in_ledger(header):  # a forger who can write the cube: the ledger cannot tell
        meta["pv_nm"] = verify(header, pv_tolerance_nm=1e9, accept_recorded=True)["pv_nm"]
    forge()
    with entered_in_ledger(header):
        res = cli(["verify", str(header)], module_catalog_dir)
        assert res.exit_code == 1 and f"surface 'small_sine'.params.{key}: recorded" in res.output, res.output
        # against its own recorded entries it is consistent, and verify says that is all it proved
        res = cli(["verify", str(header), "--accept-recorded"], module_catalog_dir)
        assert res.exit_code == 0 and "not compared with a catalog" in res.output, res.output


def test_a_fresh_export_is_consistent_with_this_catalog(originals, module_catalog_dir):
    res = cli(["verify", str(originals["fts"])], module_catalog_dir)
    assert res.exit_code == 0 and "consistent with this catalog" in res.output, res.output


# ------------------------------------------------------------------ causes a user made
def test_tiny_pitches_are_one_line_naming_the_point_count(module_catalog_dir):
    res = cli(
        ["predict", "--surface", "sinewave2d", "--drho-um", "1e-300", "--dtheta-deg", "1e-300"],
        module_catalog_dir,
    )
    assert res.exit_code == 1 and "about 1e605 points, over the capacity" in res.output, res.output
    assert "unexpected" not in res.output


def test_object_storage_without_credentials_is_one_line_naming_them(tmp_path, module_catalog_dir):
    pytest.importorskip("s3fs")
    spec = tmp_path / "s.yaml"
    spec.write_text(RING)
    env = {k: v for k, v in os.environ.items() if not k.startswith("AWS_")}
    # no credentials anywhere, no instance metadata; the endpoint is a closed local port
    env.update(
        AWS_SHARED_CREDENTIALS_FILE=str(tmp_path / "none"),
        AWS_CONFIG_FILE=str(tmp_path / "none"),
        AWS_EC2_METADATA_DISABLED="true",
        FSSPEC_S3_ENDPOINT_URL="http://127.0.0.1:9",
        FTSWEEP_CATALOGS=str(module_catalog_dir),
    )
    exe = str(Path(sys.executable).parent / "ftsweep")
    done = subprocess.run(
        [exe, "sweep", str(spec), "--out", "s3://bucket/c.zarr", "--scheduler", "synchronous"],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert done.returncode == 1, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert "NoCredentialsError" in last and "AWS_ACCESS_KEY_ID" in last and "unexpected" not in last


def _controller_reading(raw: bytes) -> list[list[float]] | None:
    """A program's data as a controller that ends lines at CR, LF or CRLF and reads numbers
    loosely reads it: the numbers of every line after the column line (comments ``#`` aside);
    None where a line holds something that is not a number."""
    lines = re.split(rb"\r\n|\r|\n", raw)
    start = next((i for i, line in enumerate(lines) if line == b"C_deg X_mm Z_mm"), None)
    if start is None:
        return None
    rows = []
    for line in lines[start + 1 :]:
        if line.startswith(b"#") or not line.strip():
            continue
        try:
            rows.append([float(v) for v in line.split()])
        except ValueError:
            return None
    return rows


def _same_motion(a: list[list[float]] | None, b: list[list[float]]) -> bool:
    # exactly: the program was exported on this platform, so verify allows no difference from
    # the re-planned lines (files.LINE_TOLERANCE applies only across platforms)
    return a is not None and a == b


PROGRAM_BYTES = st.sampled_from([b"\r", b"\n", b"#", b" ", b"1", b"9", b"-", b"+", b"e", b".", b"\t", b"0"])


@MUTATIONS
@given(data=st.data())
def test_mutated_programs_are_refused_whenever_the_controller_would_move_otherwise(
    originals, tmp_path_factory, module_catalog_dir, data
):
    # any byte inserted, deleted or replaced, with the CRC line, the sidecar's digest line and
    # every hash re-made as an attacker would: if a controller would read other motion, verify
    # refuses
    original = originals["prog"]
    text, mutated, program = mutated_copy(data, original, PROGRAM_BYTES, tmp_path_factory)
    rows = mutated.decode("latin-1").split("\n")
    at = next((i for i, r in enumerate(rows) if r.startswith("# CRC32:")), None)
    if at is not None:  # re-make the CRC over every other line, and the file's hashes
        rows[at] = CRC_LINE.format(crc_of(rows[:at] + rows[at + 1 : -1]))
        forged = "\n".join(rows).encode("latin-1")
        program.write_bytes(forged)
        side = program.with_name(program.name + ".json")
        meta = json.loads(side.read_text())
        meta.update(program_sha256=hashlib.sha256(forged).hexdigest(), crc32=int(rows[at].split()[2], 16))
        side.write_text(json.dumps(meta, indent=2))
    if not _same_motion(_controller_reading(program.read_bytes()), _controller_reading(text) or []):
        os.environ["FTSWEEP_CATALOGS"] = str(module_catalog_dir)
        try:
            with pytest.raises(ExportError):
                verify(program)
        finally:
            del os.environ["FTSWEEP_CATALOGS"]


def test_an_export_chosen_by_tolerance_verifies(originals, tmp_path, module_catalog_dir):
    # select's rule ("P-V ≤ … nm") is how the case was chosen, not text written into the file
    cube_path = str(originals["fts"].with_suffix(".zarr"))
    out = tmp_path / "tol.h"
    res = cli(["export", cube_path, "--tolerance-nm", "1000", "-o", str(out)], module_catalog_dir)
    assert res.exit_code == 0, res.output
    assert "≤" in json.loads(out.with_name(out.name + ".json").read_text())["selection"]["rule"]
    res = cli(["verify", str(out)], module_catalog_dir)
    assert res.exit_code == 0, res.output


def test_a_study_program_name_that_would_become_syntax_is_refused(tmp_path, module_catalog_dir):
    # `fresnel -o` names the sidecar inside the program: the name is held to the text rule
    out = tmp_path / "f(1).txt"
    res = cli(
        [
            "fresnel",
            "--points-per-turn",
            "40",
            "--facet-height-um",
            "10",
            "--plots",
            str(tmp_path),
            "-o",
            str(out),
        ],
        module_catalog_dir,
    )
    assert res.exit_code == 1 and "holds '('" in res.output, res.output
    assert not out.exists() and not out.with_name(out.name + ".json").exists()


@pytest.mark.parametrize(
    ("name", "words"), [("big.h", "more than any file ftsweep reads"), ("big.nc", "more than any")]
)
def test_a_huge_sparse_file_is_refused_before_a_byte_is_read(tmp_path, module_catalog_dir, name, words):
    # 2 GiB of nothing (a sparse file): refused by its size from fstat, nothing read
    path = tmp_path / name
    with path.open("wb") as fh:
        fh.truncate(2 * 2**30)
    res = cli(["verify", str(path)], module_catalog_dir)
    assert res.exit_code != 0 and words in res.output and "nothing was read" in res.output, res.output
    if name.endswith(".nc"):
        res = cli(["predict", "--program", str(path)], module_catalog_dir)
        assert res.exit_code != 0 and "nothing was read" in res.output, res.output


def test_a_program_that_is_not_utf8_is_named_as_such(tmp_path, module_catalog_dir):
    path = tmp_path / "latin1.nc"
    path.write_bytes(b"(ISO STS \xe9)\nG90 G18\nM30\n")
    res = cli(["verify", str(path)], module_catalog_dir)
    assert (
        res.exit_code != 0 and "not an ftsweep header or program: its first line is not UTF-8" in res.output
    )
