"""Selection, header export and verification."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner
from support.clusters import BIN

from ftsweep.cli.main import main
from ftsweep.engine.planning import control_table
from ftsweep.inputs.catalogs import entry
from ftsweep.kinds.table.header import c_identifier, c_string
from ftsweep.kinds.table.layout import build_layout
from ftsweep.kinds.table.verify import read_header
from ftsweep.store import cube
from ftsweep.sweeps.run import run_sweep
from ftsweep.sweeps.spec import case_at, load_sweep
from ftsweep.tools.export import ExportError, export, verify
from ftsweep.tools.select import SelectError, choose, open_cube

RING = """
surface: small_sine
layout: ring
axes: {points: [15000, 30000], aspect: [1.0, 4.0, 16.0]}
"""
MESH = """
surface: small_lens
layout: mesh
axes: {points: [15000], aspect: [0.5, 1.0, 2.0]}
"""


def make_cube(tmp_path: Path, catalog_dir: Path, text: str, name: str) -> Path:
    spec = tmp_path / f"{name}.yaml"
    spec.write_text(text)
    out = tmp_path / f"{name}.zarr"
    run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    return out


@pytest.fixture()
def ring_cube(tmp_path, catalog_dir, monkeypatch):
    monkeypatch.setenv("FTSWEEP_CATALOGS", str(catalog_dir))
    return make_cube(tmp_path, catalog_dir, RING, "ring")


@pytest.fixture()
def mesh_cube(tmp_path, catalog_dir, monkeypatch):
    monkeypatch.setenv("FTSWEEP_CATALOGS", str(catalog_dir))
    return make_cube(tmp_path, catalog_dir, MESH, "mesh")


# ----------------------------------------------------------------------------- select
def test_budget_selection_beats_every_other_eligible_case(ring_cube):
    ds = open_cube(ring_cube)
    chosen = choose(ds, budget_points=30000)
    pv = ds["pv_nm"].values
    under = (
        (ds["n_points"].values <= 30000) & (ds["status"].values == cube.DONE) & (ds["feasible"].values == 1)
    )
    assert chosen["n_points"] <= 30000
    assert chosen["pv_nm"] == pytest.approx(np.min(pv[under]))
    assert np.sum(pv[under] <= chosen["pv_nm"]) == 1  # strictly lower than every other


def test_tolerance_selection_takes_the_fewest_points(ring_cube):
    ds = open_cube(ring_cube)
    pv, n = ds["pv_nm"].values.ravel(), ds["n_points"].values.ravel()
    tol = float(np.sort(pv)[2]) + 1e-9  # three cases meet it
    chosen = choose(ds, tolerance_nm=tol)
    assert chosen["met"] and chosen["pv_nm"] <= tol
    assert chosen["n_points"] == n[pv <= tol].min()
    best = choose(ds, tolerance_nm=0.01)
    assert best["met"] is False and best["pv_nm"] == pytest.approx(np.nanmin(pv))
    r = CliRunner().invoke(main, ["select", str(ring_cube), "--tolerance-nm", "0.01"])
    assert r.exit_code == 1 and "not met" in r.output and "best found" in r.output


def test_select_cli_json(ring_cube):
    r = CliRunner().invoke(main, ["select", str(ring_cube), "--budget-points", "30000", "--json"])
    assert r.exit_code == 0, r.output
    data = json.loads(r.stdout)
    assert {"n_points", "drho_um", "dtheta_deg", "pv_nm", "aspect_actual", "aspect_target"} <= set(data)


def test_a_missing_or_second_rule_is_refused_with_the_commands_own_options(tmp_path):
    # refused before the cube is opened (an empty folder would fail as a cube), naming the
    # options each command has: select has no --case
    folder = tmp_path / "any.zarr"
    folder.mkdir()
    r = CliRunner().invoke(main, ["select", str(folder)])
    assert r.exit_code == 2 and "give exactly one of --budget-points or --tolerance-nm (got none)" in r.output
    r = CliRunner().invoke(
        main, ["export", str(folder), "--budget-points", "5", "--case", "0", "-o", str(tmp_path / "a.h")]
    )
    assert r.exit_code == 2
    assert "--budget-points, --tolerance-nm or --case (got --budget-points and --case)" in r.output
    assert not (tmp_path / "a.h").exists()


# ----------------------------------------------------------------------------- export
C_PROGRAM = """
#include <stdio.h>
#include "{header}"
int main(void) {{
    printf("%d %d\\n", {M}_ROWS, {M}_COLS);
    for (int i = 0; i < {M}_ROWS; ++i)
        for (int j = 0; j < {M}_COLS; ++j)
            printf("%ld\\n", (long){t}_table[i][j]);
    return 0;
}}
"""


@pytest.mark.parametrize("kind", ["ring", "mesh"])
def test_header_compiles_and_c_reads_the_cube_case(kind, ring_cube, mesh_cube, tmp_path, catalog_dir):
    gcc = shutil.which("gcc")
    assert gcc, "gcc is needed to check the exported header (apt-get install gcc)"
    cube_path = ring_cube if kind == "ring" else mesh_cube
    header = tmp_path / f"{kind}_fts.h"
    meta = export(cube_path, header, index=1)
    ident = c_identifier(header.stem)
    src = tmp_path / "print_table.c"
    src.write_text(C_PROGRAM.format(header=header.name, M=ident.upper(), t=ident.lower()))
    exe = tmp_path / "print_table"
    subprocess.run(
        [gcc, "-std=c99", "-Wall", "-Werror", "-o", str(exe), str(src)],
        check=True,
        capture_output=True,
        cwd=tmp_path,
    )
    out = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.split()
    rows, cols = int(out[0]), int(out[1])
    values = np.array([int(v) for v in out[2:]]).reshape(rows, cols)
    # the cube's case, recomputed from its spec, in the header's unit
    ds = xr.open_zarr(cube_path)
    _, spec = load_sweep(str(tmp_path / f"{kind}.yaml"), catalog_dir)
    case = case_at(spec, 1)
    surface = entry("surfaces", case.surface, catalog_dir)
    layout = build_layout(surface, case.layout)
    table_um, _ = control_table(case, layout, surface, 83.0)
    assert (rows, cols) == layout.shape == tuple(meta["shape"])
    assert int(ds["n_points"].values.ravel()[1]) == rows * cols
    assert np.max(np.abs(values - table_um * 1e3 / meta["unit_nm"])) <= 1.0


@pytest.mark.parametrize("kind", ["ring", "mesh"])
def test_verify_reproduces_the_cube_pv(kind, ring_cube, mesh_cube, tmp_path):
    cube_path = ring_cube if kind == "ring" else mesh_cube
    header = tmp_path / f"{kind}.h"
    export(cube_path, header, budget_points=30000)
    record = verify(header)
    chosen = choose(open_cube(cube_path), budget_points=30000)
    assert abs(record["pv_nm"] - chosen["pv_nm"]) <= max(1.0, 0.02 * chosen["pv_nm"])
    r = CliRunner().invoke(main, ["verify", str(header)])
    assert r.exit_code == 0 and "checksum" in r.output and "re-simulated" in r.output


def test_corrupted_header_fails_verify_on_its_checksum(ring_cube, tmp_path):
    header = tmp_path / "t.h"
    export(ring_cube, header, index=0)
    text = header.read_text()
    macros, ints = read_header(header)
    first_row = text.index("{", text.index("_table["))
    start = first_row + text[first_row:].index("{", 1) + 1
    end = text.index(",", start)
    header.write_text(text[:start] + str(int(text[start:end]) + 1) + text[end:])  # one value, one unit
    with pytest.raises(ExportError, match="checksum mismatch"):
        verify(header)
    r = CliRunner().invoke(main, ["verify", str(header)])
    assert r.exit_code != 0 and "checksum mismatch" in r.output


def test_a_table_value_that_is_not_an_integer_is_named(ring_cube, tmp_path):
    header = tmp_path / "t.h"
    export(ring_cube, header, index=0)
    text = header.read_text()
    first_row = text.index("{", text.index("_table["))
    start = first_row + text[first_row:].index("{", 1) + 1
    end = text.index(",", start)
    for bad in ("1.5", "12x", "0x1F"):  # each read as integers once (a regex took their digits)
        header.write_text(text[:start] + bad + text[end:])
        with pytest.raises(ExportError, match=f"holds {bad!r}, not an integer"):
            read_header(header)


def test_existing_header_needs_force(ring_cube, tmp_path):
    header = tmp_path / "t.h"
    export(ring_cube, header, index=0)
    with pytest.raises(ExportError, match="--force"):
        export(ring_cube, header, index=1)
    export(ring_cube, header, index=1, force=True)
    assert json.loads(header.with_name(header.name + ".json").read_text())["selection"]["index"] == 1
    assert not list(tmp_path.glob(".t.h.*"))  # no temporary files left behind


def test_failed_and_infeasible_cases_are_refused(tmp_path, catalog_dir, monkeypatch):
    monkeypatch.setenv("FTSWEEP_CATALOGS", str(catalog_dir))
    failing = make_cube(tmp_path, catalog_dir, RING.replace("[15000, 30000]", "[15000, 5000000]"), "over")
    with pytest.raises(SelectError, match="refused in the sweep.*over the capacity"):
        export(failing, tmp_path / "a.h", index=3)
    sluggish = make_cube(tmp_path, catalog_dir, RING + "machine: sluggish-fts\n", "sluggish")
    ds = open_cube(sluggish)
    assert np.all(ds["feasible"].values == 0)
    assert all("bandwidth" in r for r in ds["infeasible_reason"].values.ravel())
    with pytest.raises(SelectError, match="infeasible for the machine.*bandwidth"):
        export(sluggish, tmp_path / "b.h", index=0)
    with pytest.raises(SelectError, match="no computed, feasible case"):
        choose(ds, budget_points=10**6)
    r = CliRunner().invoke(main, ["export", str(sluggish), "--case", "0", "-o", str(tmp_path / "c.h")])
    assert r.exit_code != 0 and "infeasible" in r.output
    assert not (tmp_path / "a.h").exists() and not (tmp_path / "b.h").exists()


def test_identifiers_are_valid_c_whatever_the_names(ring_cube, tmp_path):
    from ftsweep.kinds.table.header import C_KEYWORDS

    for raw in ("3d lens/array", "ü-mlaut x", "__", "if", "int"):
        ident = c_identifier(raw)
        assert ident.replace("_", "a").isalnum() and not ident[0].isdigit() and not ident.startswith("_")
        assert ident not in C_KEYWORDS
    assert c_string('a"b\\c\nü') == '"a\\"b\\\\c\\012\\303\\274"'
    gcc = shutil.which("gcc")
    header = tmp_path / "odd.h"
    name = '7 "odd" name/ü'
    export(ring_cube, header, index=0, name=name)
    ident = c_identifier(name)
    src = tmp_path / "odd.c"
    src.write_text(
        f'#include "odd.h"\nint main(void) {{ return {ident.lower()}_table[0][0] > 0 && '
        f"{ident.upper()}_ROWS > 0 ? 0 : 1; }}\n"
    )
    subprocess.run(
        [gcc, "-std=c99", "-Wall", "-Werror", "-o", str(tmp_path / "odd"), str(src)],
        check=True,
        cwd=tmp_path,
        capture_output=True,
    )


def test_a_second_export_to_the_same_name_is_refused_and_writes_nothing(ring_cube, tmp_path):
    from ftsweep.store.lock import acquire, release

    header = tmp_path / "busy.h"
    held = acquire(header, command="ftsweep export -o busy.h")  # an export of another process
    try:
        with pytest.raises(ExportError, match="busy.h is being written by pid .*nothing exported"):
            export(ring_cube, header, index=0)
    finally:
        release(held)
    assert not header.exists() and not header.with_name(header.name + ".json").exists()
    export(ring_cube, header, index=0)  # once the first is done
    assert header.exists() and not list(tmp_path.glob(".busy.h.*"))


def test_a_failed_signing_publishes_nothing(ring_cube, tmp_path):
    # the file and its sidecar are signed in a staging folder before anything is published:
    # a key that cannot sign leaves neither an unsigned header nor its sidecar behind
    bad_key = tmp_path / "not-a-key.key"
    bad_key.write_text("not a PEM key\n")
    header = tmp_path / "signed.h"
    with pytest.raises(ExportError, match="not a PEM private key"):
        export(ring_cube, header, index=0, sign_key=str(bad_key))
    assert sorted(p.name for p in tmp_path.glob("signed*")) == []
    assert not list(tmp_path.glob(".signed.h.*"))


def test_two_exports_to_one_name_leave_one_case_whole(ring_cube, tmp_path, catalog_dir):
    # two processes export cases 0 and 1 to one -o at once: one wins whole, the other is
    # refused (or, having started after, replaces it whole); header and sidecar always agree
    header = tmp_path / "race.h"
    cmd = [str(BIN / "ftsweep"), "export", str(ring_cube), "-o", str(header), "--force"]
    env = {**os.environ, "FTSWEEP_CATALOGS": str(catalog_dir)}
    procs = [
        subprocess.Popen(
            [*cmd, "--case", str(i)], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        for i in (0, 1)
    ]
    results = [(p.wait(timeout=300), p.stderr.read()) for p in procs]  # type: ignore[union-attr]
    assert any(rc == 0 for rc, _ in results), results
    for rc, err in results:
        assert rc == 0 or "is being written by pid" in err, err
    verify(header)  # the pair agrees: one case's header with that case's sidecar
    assert not list(tmp_path.glob(".race.h.*")) and not (tmp_path / "race.h.lock").exists()
