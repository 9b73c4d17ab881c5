"""One export and one verify for every program kind: a table of file formats (flox's
``Aggregation`` table, xarray's backend entrypoints), each naming the kinds it writes, how to
recognise its files, and its write, verify and report functions. Generic code asks the
table; the formats live with their kinds (:mod:`ftsweep.kinds.table.header`,
:mod:`ftsweep.kinds.path_programs`, :mod:`ftsweep.kinds.fresnel.study`) and share
:mod:`ftsweep.exports.files`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ftsweep.exports.origin import sign, signature_path, signing_key
from ftsweep.freetext import TextError, check_text
from ftsweep.store.io import (
    MAX_PROGRAM_BYTES,
    MAX_SIDECAR_BYTES,
    ExportError,
    check_overwrite,
    read_regular,
    read_sidecar,
    sidecar_path,
)
from ftsweep.store.storage import PathLike

Progress = Callable[[int, int], None] | None


@dataclass(frozen=True)
class FileFormat:
    """How one kind of exported file is written, recognised, verified and reported.

    kinds : the cube case kinds (a request's ``kind``) it exports (a Fresnel program is also
        written by its study, ``ftsweep fresnel -o``).
    magic : how its first line starts (None: the default format, read when no other's
        first line matches).
    export : ``(out, side, case, specs, chosen, extra, name) -> sidecar``.
    verify : ``(path, progress, pv_tolerance_nm, trust_plugins) -> record``.
    exported : the lines that say what ``export`` wrote (``(out, sidecar) -> lines``).
    verified : the lines that say what ``verify`` found (``record -> lines``).
    """

    name: str
    kinds: tuple[str, ...]
    magic: str | None
    export: Callable[..., dict[str, Any]] | None
    verify: Callable[..., dict[str, Any]]
    exported: Callable[[Path, dict[str, Any]], list[str]]
    verified: Callable[[dict[str, Any]], list[str]]


def _header_format() -> FileFormat:
    from ftsweep.kinds.table import header

    def exported(out: Path, meta: dict[str, Any]) -> list[str]:
        return [
            f"header       {out} ({meta['shape'][0]} × {meta['shape'][1]} {meta['int_type']}, "
            f"unit {meta['unit_nm']} nm, CRC-32 0x{meta['crc32']:08x})"
        ]

    def verified(record: dict[str, Any]) -> list[str]:
        return [
            f"checksum     {record['checksum']} (macros and table) ok; sidecar and file hashes ok",
            f"table        {record['layout']}: {record['n_points']:,} points, "
            "every macro and cell as re-planned",
            *_pv_lines(record, "the stored integers"),
        ]

    return FileFormat(
        "controller header",
        ("ring", "mesh"),
        None,
        header.export_header,
        header.verify_header,
        exported,
        verified,
    )


def _pv_lines(record: dict[str, Any], source: str) -> list[str]:
    return [
        f"P-V          {record['pv_nm']:.2f} nm re-simulated from {source} "
        f"(predicted at export: {record['predicted_pv_nm']:.2f} nm, "
        f"tolerance {record['pv_tolerance_nm']:.2f} nm) ok"
    ]


def _program_format(title: str, kind: str, magic: str, columns: str, write: Any, check: Any) -> FileFormat:
    def exported(out: Path, meta: dict[str, Any]) -> list[str]:
        return [f"program      {out} ({meta['n_points']:,} lines {columns}, CRC-32 0x{meta['crc32']:08x})"]

    def verified(record: dict[str, Any]) -> list[str]:
        return [
            f"checksum     {record['checksum']} (every line) ok; sidecar and file hashes ok",
            f"program      {record['layout']}: {record['n_points']:,} points, every line as re-planned",
            *_pv_lines(record, "the program's lines"),
        ]

    def export(*args: Any, name: str | None = None) -> dict[str, Any]:
        return dict(write(*args))  # a program's lines need no C identifiers

    return FileFormat(title, (kind,), magic, export, check, exported, verified)


def _fresnel_format() -> FileFormat:
    from ftsweep.kinds.fresnel import study as fstudy

    def export(*args: Any, name: str | None = None) -> dict[str, Any]:
        return dict(fstudy.export_case(*args))

    def verify(path: Path, progress: Progress, pv_tolerance_nm: float | None, trust: bool) -> dict[str, Any]:
        return fstudy.verify(path, trust, progress, pv_tolerance_nm)

    def exported(out: Path, meta: dict[str, Any]) -> list[str]:
        return [f"program      {out} ({meta['n_points']:,} lines t C X Y Z, CRC-32 0x{meta['crc32']:08x})"]

    def verified(record: dict[str, Any]) -> list[str]:
        if "pv_nm" not in record:  # a study's program (ftsweep fresnel -o): no prediction recorded
            return [
                f"checksum     {record['checksum']} (every line) ok; sidecar and program hashes ok",
                f"program      fresnel: {record['lines']:,} lines t C X Y Z, {record['machining_s']:.1f} s; "
                "every line within the machine's limits and as re-planned (t, C, X, Y, Z)",
            ]
        return [
            f"checksum     {record['checksum']} (every line) ok; sidecar and file hashes ok",
            f"program      fresnel: {record['n_points']:,} points, every line within the machine's limits "
            "and as re-planned",
            *_pv_lines(record, "the program's lines"),
        ]

    return FileFormat("Fresnel program", ("fresnel",), fstudy.F_MAGIC, export, verify, exported, verified)


@functools.cache
def formats() -> tuple[FileFormat, ...]:
    """Every registered file format (built once); the first is the default."""
    from ftsweep.kinds import path_programs as program

    return (
        _header_format(),
        _program_format(
            "spiral program", "spiral", program.MAGIC, "C X Z", program.export_program, program.verify_program
        ),  # fmt: skip
        _program_format(
            "D-path program", "dpath", program.D_MAGIC, "t C X Z", program.export_dpath, program.verify_dpath
        ),  # fmt: skip
        _fresnel_format(),
    )


def format_of_kind(kind: str) -> FileFormat:
    """The format a cube case of ``kind`` is exported in."""
    for fmt in formats():
        if kind in fmt.kinds:
            return fmt
    raise ExportError(f"a {kind} case has no export format")


def format_of_file(path: Path) -> FileFormat:
    """The format of an exported file, by its first line (anything else is read as a header,
    whose reader says precisely what is wrong with it)."""
    # the largest file any format reads is a program's; a device or FIFO is refused, never read
    head = read_regular(path, MAX_PROGRAM_BYTES, head=200)
    first = head.split(b"\n", 1)[0].decode("utf-8", errors="replace")
    found = [f for f in formats() if f.magic is not None and first.startswith(f.magic)]
    return found[0] if found else formats()[0]


def export(
    cube_path: PathLike,
    out: Path,
    budget_points: int | None = None,
    tolerance_nm: float | None = None,
    index: int | None = None,
    force: bool = False,
    name: str | None = None,
    trust_plugins: bool = False,
    sign_key: str | None = None,
) -> dict[str, Any]:
    """Choose a case of a cube (a path or URL; ``select``'s rules), plan it again from the cube's recorded
    spec and catalog entries and write it in its kind's format with its sidecar, atomically
    (a table as a C header, a spiral or D-path program as plain-text lines). Returns the
    sidecar's content. A plug-in surface the cube names must be in the local catalog unless
    ``trust_plugins``. Signed (``FILE.sig``) when a signing key is configured
    (:func:`ftsweep.exports.origin.signing_key` of ``sign_key``)."""
    from ftsweep.tools.select import check_exportable, choose, open_cube, recorded_case

    out = Path(out)
    side = sidecar_path(out)
    try:  # the sidecar names the file and the file its sidecar: both are rendered
        check_text(out.name, "the output file's name")
    except TextError as exc:
        raise ExportError(f"-o {str(out)[:200]!r}: {exc}") from None
    if side == out:
        raise ExportError(
            f"-o {out}: the sidecar {side.name} would overwrite the file; name it FILE.h or FILE.txt"
        )
    check_overwrite((out, side, signature_path(out)), force)
    key = signing_key(sign_key)
    ds = open_cube(cube_path)
    chosen = choose(ds, budget_points, tolerance_nm, index)
    if tolerance_nm is not None and not chosen.get("met", True):
        raise ExportError(
            f"no case meets P-V ≤ {tolerance_nm:g} nm (best found: {chosen['pv_nm']:.2f} nm at "
            f"{chosen['n_points']:,} points); nothing exported"
        )
    flat = int(chosen["index"])
    check_exportable(ds, flat)
    case, specs = recorded_case(ds, flat, trust_plugins)
    extra = {"cube": str(cube_path), "cube_git_revision": ds.attrs.get("git_revision")}
    fmt = format_of_kind(case.layout.kind)
    assert fmt.export is not None
    meta = fmt.export(out, side, case, specs, chosen, extra, name=name)
    return signed(out, key, meta)


def signed(out: Path, key: Path | None, meta: dict[str, Any]) -> dict[str, Any]:
    """``meta`` of a file just written, after signing it with ``key`` (``signature`` then
    holds the key's ID) or, with no key, removing a signature left by an earlier export."""
    if key is None:
        signature_path(out).unlink(missing_ok=True)
        return meta
    return {**meta, "signature": sign(out, key)}


def verify(
    path: Path,
    progress: Progress = None,
    pv_tolerance_nm: float | None = None,
    trust_plugins: bool = False,
    trusted: tuple[str, ...] = (),
    accept_recorded: bool = False,
) -> dict[str, Any]:
    """Verify any exported file by its format (:func:`format_of_file`): what the machine
    reads, parsed as the machine parses it, against what the recorded case plans; and its
    origin (:mod:`ftsweep.exports.origin`): with trusted keys (``trusted``, or the config file's)
    its signature, else its recorded catalog entries against the local catalog (unless
    ``accept_recorded``). The record's ``origin`` says which was proved. Raises
    :class:`~ftsweep.exports.files.ExportError` naming the first difference."""
    from ftsweep.exports import origin as org

    path = Path(path)
    fmt = format_of_file(path)
    side = sidecar_path(path)
    before = _contents(path, side)
    # the file as the machine reads it first (its own errors name what is wrong with it) ...
    record = fmt.verify(path, progress, pv_tolerance_nm, trust_plugins)
    file_bytes, side_bytes = _contents(path, side)
    if side_bytes is None or (file_bytes, side_bytes) != before:  # judged must be what is proved
        raise ExportError(f"{path} or its sidecar changed while it was verified; verify it again")
    # ... then who made it
    keys = org.trusted_keys(trusted)
    if keys:
        record["origin"] = {
            "proved": "signed",
            "key_id": org.check_signature(path, file_bytes, side_bytes, keys),
        }
    elif accept_recorded:
        record["origin"] = {"proved": "recorded entries (--accept-recorded): not compared with a catalog"}
    else:
        catalog = org.check_catalog(read_sidecar(path, side_bytes), side)
        record["origin"] = {"proved": "consistent with this catalog", "catalog": catalog}
    return record


def _contents(path: Path, side: Path) -> tuple[bytes, bytes | None]:
    """The bytes of a file and its sidecar (regular files only, bounded; None: no sidecar,
    which the format's verify names)."""
    sidecar = read_regular(side, MAX_SIDECAR_BYTES, "sidecar") if side.exists() else None
    return read_regular(path, MAX_PROGRAM_BYTES), sidecar


def origin_line(record: dict[str, Any]) -> str:
    """The line that says what verify proved of a file's origin."""
    proved = record.get("origin", {})
    if proved.get("key_id"):
        return f"origin       signed by key {proved['key_id']} (trusted)"
    if proved.get("catalog"):
        return (
            f"origin       consistent with this catalog ({proved['catalog']}); no signature checked "
            "(--trusted-key proves who exported it)"
        )
    return f"origin       {proved.get('proved', 'not checked')}"
