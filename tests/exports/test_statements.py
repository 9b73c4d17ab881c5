"""What an exported file is for, said first and bound to it: signed statements (name, length,
digests, case, surface, machine, cutting, compensation, dialect, time, expiry), the operator's
expectations, "as re-planned" exact on the platform a file was planned on, and a recorded
resolution judged by the file's own size before any re-simulation."""

from __future__ import annotations

import json
import os
import shutil
from datetime import timedelta
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from support.forging import entered_in_ledger, forge_header_from_sidecar, forge_program

from ftsweep.cli.main import main
from ftsweep.engine.case import CaseError
from ftsweep.exports import origin
from ftsweep.exports.fingerprint import fingerprint
from ftsweep.sweeps.run import run_sweep
from ftsweep.tools.export import ExportError, export, verify

RING = "surface: small_sine\nlayout: ring\naxes: {points: [15000], aspect: [4.0, 8.0]}\n"
SPIRAL = "surface: small_sine\nlayout: spiral\naxes: {points_per_rev: [60]}\n"


def cli(args: list[str], catalogs: Path, **env: str):  # type: ignore[no-untyped-def]
    return CliRunner().invoke(main, args, env={"FTSWEEP_CATALOGS": str(catalogs), **env})


@pytest.fixture(scope="module")
def cubes(tmp_path_factory, module_catalog_dir):
    """A two-case ring cube and a one-case spiral cube."""
    folder = tmp_path_factory.mktemp("cubes")
    out = {}
    for name, text in (("ring", RING), ("spiral", SPIRAL)):
        spec = folder / f"{name}.yaml"
        spec.write_text(text)
        out[name] = folder / f"{name}.zarr"
        run_sweep(str(spec), out[name], scheduler="synchronous", catalog_folder=module_catalog_dir)
    return out


@pytest.fixture()
def catalogs_env(module_catalog_dir, monkeypatch):
    monkeypatch.setenv("FTSWEEP_CATALOGS", str(module_catalog_dir))
    return module_catalog_dir


def signed_export(cubes, shop_keys, out: Path, case: int, catalogs: Path, *extra: str) -> None:
    args = [
        "export",
        str(cubes["ring"]),
        "--case",
        str(case),
        "-o",
        str(out),
        "--sign-key",
        str(shop_keys[0]),
    ]
    res = cli([*args, *extra], catalogs)
    assert res.exit_code == 0, res.output


# ------------------------------------------------------------------ what the file is for
def test_verify_says_first_what_a_signed_file_is_for(cubes, shop_keys, tmp_path, module_catalog_dir):
    out = tmp_path / "part.h"
    signed_export(cubes, shop_keys, out, 1, module_catalog_dir, "--expires", "30d")
    res = cli(["verify", str(out), "--trusted-key", str(shop_keys[1])], module_catalog_dir)
    assert res.exit_code == 0, res.output
    lines = res.output.splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith("for "))
    assert lines[at] == f"for          case points=15000 aspect=8 of {cubes['ring']}"
    assert at < next(i for i, line in enumerate(lines) if line.startswith("checksum"))
    said = "\n".join(lines[at : at + 4])
    for fact in ("surface small_sine", "machine fts-1m", "cutting reference", "compensation exact", "header"):
        assert fact in said, said
    assert "points, predicted P-V" in said and "signed       by key" in said and ", expires 20" in said
    statement = json.loads(out.with_name("part.h.sig").read_text())["statement"]
    assert statement["file"] == "part.h" and statement["case"] == 1
    assert statement["case_name"] == "points=15000 aspect=8"  # the case by its coordinates
    assert statement["length"] == out.stat().st_size and statement["signed_at"].endswith("Z")


def test_a_signed_file_copied_over_another_case_is_refused(cubes, shop_keys, tmp_path, module_catalog_dir):
    a, b = tmp_path / "a.h", tmp_path / "b.h"
    signed_export(cubes, shop_keys, a, 0, module_catalog_dir)
    signed_export(cubes, shop_keys, b, 1, module_catalog_dir)
    for suffix in ("", ".json", ".sig"):  # case 0's file, sidecar and signature over case 1's
        shutil.copy(f"{a}{suffix}", f"{b}{suffix}")
    res = cli(["verify", str(b), "--trusted-key", str(shop_keys[1])], module_catalog_dir)
    assert res.exit_code == 1 and "signed as 'a.h', not 'b.h'" in res.output, res.output
    # without a key the swap is still visible, and refused where the operator expects a case
    res = cli(["verify", str(b)], module_catalog_dir)
    assert res.exit_code == 0 and "for          case points=15000 aspect=4 of" in res.output, res.output
    res = cli(["verify", str(b), "--expect-case", "1"], module_catalog_dir)
    assert res.exit_code == 1 and "is for case 0, not the expected 1" in res.output, res.output
    res = cli(["verify", str(a), "--expect-case", "0", "--expect-surface", "lens_array"], module_catalog_dir)
    assert res.exit_code == 1 and "is for surface small_sine, not the expected lens_array" in res.output
    res = cli(["verify", str(a), "--expect-case", "0", "--expect-surface", "small_sine"], module_catalog_dir)
    assert res.exit_code == 0, res.output


def test_a_renamed_signed_file_is_refused(cubes, shop_keys, tmp_path, module_catalog_dir):
    a = tmp_path / "a.h"
    signed_export(cubes, shop_keys, a, 0, module_catalog_dir)
    moved = tmp_path / "other.h"
    for suffix in ("", ".json", ".sig"):
        os.rename(f"{a}{suffix}", f"{moved}{suffix}")
    res = cli(["verify", str(moved), "--trusted-key", str(shop_keys[1])], module_catalog_dir)
    assert res.exit_code == 1 and "renamed or copied" in res.output, res.output


def test_an_expired_statement_is_refused(cubes, shop_keys, tmp_path, catalogs_env, monkeypatch):
    out = tmp_path / "e.h"
    signed_export(cubes, shop_keys, out, 0, catalogs_env, "--expires", "1d")
    assert verify(out, trusted=(str(shop_keys[1]),))["origin"]["expires"]
    later = origin._now() + timedelta(days=2)
    monkeypatch.setattr(origin, "_now", lambda: later)
    with pytest.raises(ExportError, match="its signature expired at"):
        verify(out, trusted=(str(shop_keys[1]),))


@pytest.mark.parametrize("when", ["2020-01-01", "yesterday", "0d", "-3d"])
def test_an_expiry_that_has_passed_or_is_no_time_is_a_usage_error(
    cubes, shop_keys, tmp_path, module_catalog_dir, when
):
    args = [
        "export",
        str(cubes["ring"]),
        "--case",
        "0",
        "-o",
        str(tmp_path / "x.h"),
        "--sign-key",
        str(shop_keys[0]),
    ]
    res = cli([*args, "--expires", when], module_catalog_dir)
    assert res.exit_code == 2 and "--expires" in res.output, res.output
    assert not (tmp_path / "x.h").exists()


def test_a_signature_of_the_older_scheme_is_refused(cubes, shop_keys, tmp_path, catalogs_env):
    out = tmp_path / "old.h"
    signed_export(cubes, shop_keys, out, 0, catalogs_env)
    sig = out.with_name("old.h.sig")
    document = json.loads(sig.read_text())
    del document["scheme"], document["statement"]  # what the first scheme wrote: hashes only
    sig.write_text(json.dumps(document, indent=2) + "\n")
    with pytest.raises(ExportError, match="older scheme, which names no file, case or expiry"):
        verify(out, trusted=(str(shop_keys[1]),))


def test_a_key_others_can_read_and_a_config_others_can_change_are_warned_about(
    cubes, shop_keys, tmp_path, module_catalog_dir
):
    key = tmp_path / "open.key"
    shutil.copy(shop_keys[0], key)
    key.chmod(0o644)
    config = tmp_path / "config.toml"
    config.write_text(f'trusted_keys = ["{shop_keys[1]}"]\n')
    config.chmod(0o666)
    out = tmp_path / "w.h"
    res = cli(
        ["export", str(cubes["ring"]), "--case", "0", "-o", str(out), "--sign-key", str(key)],
        module_catalog_dir,
    )
    assert res.exit_code == 0, res.output
    assert f"warning: private key {key} is -rw-r--r--: others can read it; chmod 600" in res.stderr
    res = cli(["verify", str(out)], module_catalog_dir, FTSWEEP_CONFIG=str(config))  # its trusted shop_keys
    assert res.exit_code == 0, res.output
    assert f"warning: config file {config} is -rw-rw-rw-: others can change it; chmod go-w" in res.stderr
    config.chmod(0o644)  # readable by all is how configs are: only who may change it matters
    origin._WARNED.clear()
    res = cli(["verify", str(out)], module_catalog_dir, FTSWEEP_CONFIG=str(config))
    assert res.exit_code == 0 and "warning" not in res.stderr, res.output


# ------------------------------------------------------------------ exact as re-planned
@pytest.fixture()
def header(cubes, tmp_path, catalogs_env):
    out = tmp_path / "t.h"
    export(cubes["ring"], out, index=0)
    return out


def _other_platform(meta):  # type: ignore[no-untyped-def]
    meta["platform"] = {**meta["platform"], "numpy": "0.0.1"}


def test_every_cell_one_unit_off_is_refused_on_the_platform_it_was_planned_on(header):
    assert json.loads(header.with_name("t.h.json").read_text())["platform"] == fingerprint()
    assert "exactly as re-planned" in verify(header)["replanned"]
    forge_header_from_sidecar(header, lambda meta: None, cells=lambda ints: ints + 1)
    with pytest.raises(ExportError, match=r"cell\(s\) differ by more than 0 unit"):
        verify(header)
    # the same table as planned on another platform: one unit is the last digit's noise there,
    # allowed when the operator asks for it, never because the file says so
    forge_header_from_sidecar(header, _other_platform)
    with entered_in_ledger(header):  # as its export on that platform would have recorded it
        with pytest.raises(ExportError, match=r"cell\(s\) differ by more than 0 unit"):
            verify(header)
        record = verify(header, across_platforms=True)
    assert record["replanned"].startswith("planned on another platform (numpy 0.0.1 here ")
    assert "one unit allowed (as --across-platforms asks)" in record["replanned"]


def _no_platform(meta):  # type: ignore[no-untyped-def]
    del meta["platform"]


@pytest.mark.parametrize("edit", [_no_platform, _other_platform])
def test_the_file_does_not_choose_its_rule(header, edit):
    """Without a trusted key, removing or editing the sidecar's platform (its hashes re-made)
    leaves the exact rule: a one-unit edit is refused unless the operator asks for one unit
    across platforms, and the re-planned line says which rule judged it."""
    forge_header_from_sidecar(header, edit, cells=lambda ints: ints + 1)
    with entered_in_ledger(header):  # the rule alone is under test here, not the ledger
        with pytest.raises(ExportError, match=r"cell\(s\) differ by more than 0 unit"):
            verify(header)
        res = CliRunner().invoke(main, ["verify", str(header), "--across-platforms"])
    assert res.exit_code == 0, res.output
    assert "one unit allowed (as --across-platforms asks)" in res.output


def test_a_signed_platform_allows_one_unit_without_the_operator_asking(cubes, tmp_path, catalogs_env):
    """With a trusted key the platform is in the signed statement: a file signed as planned
    elsewhere is judged with one unit; its statement names the platform."""
    shop_keys = origin.new_keys(tmp_path / "k")
    out = tmp_path / "s.h"
    export(cubes["ring"], out, index=0, sign_key=str(shop_keys[0]))
    signed = json.loads(out.with_name("s.h.sig").read_text())["statement"]
    assert signed["platform"] == fingerprint()
    record = verify(out, trusted=(str(shop_keys[1]),))
    assert record["replanned"] == "planned on this platform: every value exactly as re-planned"


def test_a_checkerboard_of_one_unit_is_refused_on_the_platform_it_was_planned_on(header):
    def checker(ints):  # type: ignore[no-untyped-def]
        i, j = np.indices(ints.shape)
        return ints + np.where((i + j) % 2 == 0, 1, -1).astype(ints.dtype)

    forge_header_from_sidecar(header, lambda meta: None, cells=checker)
    with pytest.raises(ExportError, match=r"table cell \[0\]\[0\] holds"):
        verify(header)


def test_every_z_of_a_program_moved_by_a_fraction_of_a_nanometre_is_refused(cubes, tmp_path, catalogs_env):
    program = tmp_path / "p.txt"
    export(cubes["spiral"], program, index=0)

    def shift_z(rows):  # type: ignore[no-untyped-def]
        moved = []
        for row in rows:
            words = row.split(" ")
            if row[:1] in "-0123456789" and row and len(words) == 3:  # a data line: C X Z
                words[2] = f"{float(words[2]) + 0.9e-6:.9f}"  # +0.9 nm in mm
            moved.append(" ".join(words))
        return moved

    forge_program(program, lambda meta: None, lines=shift_z)
    with pytest.raises(ExportError, match=r"has Z_mm .* \(tolerance 0;"):
        verify(program)
    forge_program(program, _other_platform)  # planned elsewhere: still exact unless asked
    with pytest.raises(ExportError, match=r"has Z_mm .* \(tolerance 0;"):
        verify(program)
    # asked for: 0.9 nm is inside the 1 nm allowed across platforms
    with entered_in_ledger(program):
        assert verify(program, across_platforms=True)["replanned"].startswith("planned on another platform")


# ------------------------------------------------------------------ bounded before work
@pytest.mark.parametrize("kind", ["ring", "spiral"])
def test_a_recorded_resolution_past_the_files_size_is_refused_before_any_work(
    cubes, tmp_path, catalogs_env, kind
):
    out = tmp_path / ("r.h" if kind == "ring" else "r.txt")
    export(cubes[kind], out, index=0)

    def finer(meta):  # type: ignore[no-untyped-def]
        meta["case"]["resolution"] = {**meta["case"].get("resolution", {}), "samples_per_cell": 100_000}

    (forge_header_from_sidecar if kind == "ring" else forge_program)(out, finer)
    batches: list[int] = []
    with pytest.raises(
        CaseError, match=r"recorded resolution needs .* times the .* of the default resolution"
    ):
        verify(out, progress=lambda done, total: batches.append(done))
    assert batches == []  # refused before the first batch of rays
    # a convergence study's resolution (4x the angular samples, 2x the points per feed) is verified
    forge = forge_header_from_sidecar if kind == "ring" else forge_program
    study = {"samples_per_cell": 12, "points_per_feed": 4}
    forge(out, lambda m: m["case"].update(resolution={**m["case"]["resolution"], **study}))
    with pytest.raises(ExportError, match="re-simulates|P-V"):  # judged, not refused: its P-V moved
        verify(out, pv_tolerance_nm=1e-9)


# ------------------------------------------------------------------ rollback
def test_an_older_export_of_the_same_name_is_refused_while_its_cube_is_reachable(
    cubes, shop_keys, tmp_path, module_catalog_dir
):
    """Each export appends its statement's sequence to the cube's ledger: an older signed
    export put back under the same name verifies no more (it is not the latest), however
    valid its signature; a copy of the cube elsewhere leaves verify saying it did not check."""
    import shutil

    cube = tmp_path / "ring.zarr"
    shutil.copytree(cubes["ring"], cube)
    out, keep = tmp_path / "shop.h", tmp_path / "kept"
    args = ["export", str(cube), "-o", str(out), "--sign-key", str(shop_keys[0]), "--force"]
    assert cli([*args, "--case", "0"], module_catalog_dir).exit_code == 0
    keep.mkdir()
    for f in (out, out.with_name("shop.h.json"), out.with_name("shop.h.sig")):
        shutil.copy(f, keep / f.name)
    assert cli([*args, "--case", "1"], module_catalog_dir).exit_code == 0
    trusted = ["--trusted-key", str(shop_keys[1])]
    res = cli(["verify", str(out), *trusted], module_catalog_dir)
    assert (
        res.exit_code == 0
        and "latest       the latest export of shop.h in the cube's ledger (sequence 2)" in res.output
    )
    statement = json.loads(out.with_name("shop.h.sig").read_text())["statement"]
    assert statement["ledger"] == {"name": "shop.h", "sequence": 2}
    for f in keep.iterdir():  # the rollback: the older signed export put back
        shutil.copy(f, tmp_path / f.name)
    res = cli(["verify", str(out), *trusted], module_catalog_dir)
    assert (
        res.exit_code == 1
        and "is export 1 of shop.h, not the latest: the cube's ledger records sequence 2" in res.output
    )
    cube.rename(tmp_path / "moved.zarr")  # the cube out of reach: said, not silently passed
    res = cli(["verify", str(out), *trusted], module_catalog_dir)
    assert res.exit_code == 0 and f"not checked: the cube {cube} is not reachable" in res.output, res.output


def test_a_new_private_key_is_kept_out_of_git_by_default(tmp_path, monkeypatch, module_catalog_dir):
    """A key made inside a clone (the guide's secure/) is ignored by git; with no -o the pair
    goes to the user's config folder, outside any clone."""
    import subprocess

    clone = tmp_path / "clone"
    subprocess.run(["git", "init", "-q", str(clone)], check=True)
    res = cli(["keys", "new", "-o", str(clone / "secure" / "shop")], module_catalog_dir)
    assert res.exit_code == 0, res.output
    ignored = subprocess.run(
        ["git", "check-ignore", "-q", "secure/shop.key"], cwd=clone, capture_output=True, check=False
    )
    assert ignored.returncode == 0  # ignored: `git add -A` leaves the private key out
    shown = subprocess.run(
        ["git", "status", "--porcelain", "-uall"], cwd=clone, capture_output=True, text=True
    )
    assert "shop.pub" in shown.stdout and "shop.key" not in shown.stdout
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "config"))
    res = cli(["keys", "new"], module_catalog_dir)
    assert res.exit_code == 0, res.output
    assert (tmp_path / "config" / "ftsweep" / "keys" / "ftsweep-signing.key").is_file()


def test_a_corrected_files_statement_names_its_measurement_and_a_forged_one_is_refused():
    """A file planned on a measured correction states the measurement's SHA-256, the gain and
    terms its case used and the fit; read from an untrusted sidecar, a digest that is not 64
    hex digits is refused and only numbers are taken."""
    from ftsweep.errors import ExportError
    from ftsweep.exports.origin import measured_by

    block = {
        "measurement_sha256": "ab" * 32,
        "gain": 0.5,
        "terms": 10,
        "fit": {"piston_um": 0.1, "x": "text"},
    }
    meta = {"catalog_entries": {"surface": {"family": "zernike", "correction": block}}}
    found = measured_by(meta, {"correction_gain": 1.0})["measurement"]
    assert found == {"sha256": "ab" * 32, "gain": 1.0, "terms": 10.0, "fit": {"piston_um": 0.1, "x": None}}
    assert measured_by({"catalog_entries": {"surface": {"family": "sphere"}}}, {}) == {}
    forged = {"catalog_entries": {"surface": {"correction": {**block, "measurement_sha256": "../../etc"}}}}
    with pytest.raises(ExportError, match="names no SHA-256"):
        measured_by(forged, {})
