"""One export and one verify for every program kind: each kind names its file format
(:class:`ftsweep.exports.files.FileFormat`: how to recognise its files, and its write, verify
and report functions), and generic code asks the registry for them. The formats live with
their kinds (``ftsweep.kinds.<kind>``) and share the machinery of :mod:`ftsweep.exports`.
This is the export command's layer (tools): it selects from cubes and asks the registry.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any, Optional

from ftsweep import registry
from ftsweep.engine.contract import FileFormat
from ftsweep.errors import ExportError
from ftsweep.exports.files import Progress
from ftsweep.exports.origin import sign, signature_path, signing_key
from ftsweep.freetext import TextError, check_text
from ftsweep.store import ledger
from ftsweep.store.io import (
    MAX_PROGRAM_BYTES,
    MAX_SIDECAR_BYTES,
    check_overwrite,
    read_regular,
    read_sidecar,
    sidecar_of,
    sidecar_path,
)
from ftsweep.store.storage import PathLike, StorageError, place


def formats() -> tuple[FileFormat, ...]:
    """Every registered kind's file format, once each; the first is the default (the one
    whose files no first line announces)."""
    found: dict[str, FileFormat] = {}
    for kind in registry.kinds().values():
        fmt = kind.file_format()
        found.setdefault(fmt.name, fmt)
    return tuple(sorted(found.values(), key=lambda f: f.magic is not None))


def format_of_kind(kind: str) -> FileFormat:
    """The format a cube case of ``kind`` is exported in (its kind's)."""
    try:
        return registry.kind(kind).file_format()  # type: ignore[no-any-return]
    except ValueError:
        raise ExportError(f"a {kind} case has no export format") from None


def format_of_file(path: Path) -> FileFormat:
    """The format of an exported file, by its first line (anything else is read as a header,
    whose reader says precisely what is wrong with it)."""
    # the largest file any format reads is a program's; a device or FIFO is refused, never read
    head = read_regular(path, MAX_PROGRAM_BYTES, head=200)
    line = head.split(b"\n", 1)[0]
    try:
        first = line.decode("utf-8")
    except UnicodeDecodeError as exc:
        cut = b"\n" not in head and exc.start >= len(line) - 3  # a character the head cut in two
        if not cut:
            what = "header" if path.suffix == ".h" else "header or program"
            raise ExportError(
                f"{path} is not an ftsweep {what}: its first line is not UTF-8 text (byte {exc.start}); "
                "export writes ASCII"
            ) from None
        first = line.decode("utf-8", errors="replace")
    from ftsweep.exports import nc

    if nc.is_dialect_file(first):
        return nc.dialect_format()  # type: ignore[no-any-return]
    found = [f for f in formats() if f.magic is not None and first.startswith(f.magic)]
    return found[0] if found else formats()[0]


def export(
    cube_path: PathLike,
    out: Path,
    budget_points: int | None = None,
    tolerance_nm: float | None = None,
    index: int | str | None = None,
    force: bool = False,
    name: str | None = None,
    trust_plugins: bool = False,
    sign_key: str | None = None,
    dialect: str | None = None,
    expires: datetime | None = None,
    machine: str | None = None,
) -> dict[str, Any]:
    """Choose a case of a cube (a path or URL; ``select``'s rules), plan it again from the cube's recorded
    spec and catalog entries and write it in its kind's format with its sidecar, atomically
    (a table as a C header, a spiral or D-path program as plain-text lines). Returns the
    sidecar's content. A plug-in surface the cube names must be in the local catalog unless
    ``trust_plugins``. Signed (``FILE.sig``: a statement of what the file is for, valid until
    ``expires`` when given) when a signing key is configured
    (:func:`ftsweep.exports.origin.signing_key` of ``sign_key``). A path program is written in
    ``dialect`` (default: the machine's controller's, :mod:`ftsweep.exports.nc`). ``machine``:
    plan the chosen case for another machine of the local catalog (its controller, capacity,
    units and limits) and predict it there (:func:`for_machine`); the file states that P-V."""
    out = Path(out)
    side = sidecar_path(out)
    try:  # the sidecar names the file and the file its sidecar: both are rendered
        check_text(out.name, "the output file's name")
    except TextError as exc:
        raise ExportError(f"-o {str(out)[:200]!r}: {exc}") from None
    key = signing_key(sign_key)
    signer = None if key is None else Signer(key, expires)
    with _export_lock(out):
        check_overwrite((out, side, signature_path(out)), force)
        return _export_locked(
            cube_path,
            out,
            Selection(budget_points, tolerance_nm, index),
            Writing(name, trust_plugins, signer, dialect, machine),
        )


@dataclass(frozen=True)
class Selection:
    """Which case of a cube is exported (``select``'s rules, :func:`ftsweep.tools.select.choose`):
    the best within a budget of points, the fewest points within a tolerance [nm], or a case
    by its index or name."""

    budget_points: int | None
    tolerance_nm: float | None
    index: int | str | None


@dataclass(frozen=True)
class Signer:
    """The signing key a statement is made with and the time it expires (None: never)."""

    key: Path
    expires: datetime | None


@dataclass(frozen=True)
class Writing:
    """How the chosen case is written: the program's name in its header, whether plug-in
    surfaces of the recorded entries are trusted, its signer (None: unsigned), its dialect
    (None: the controller's) and another machine to plan it for (None: the cube's)."""

    name: str | None
    trust_plugins: bool
    signer: Signer | None
    dialect: str | None
    machine: str | None


@contextmanager
def _export_lock(out: Path) -> Iterator[None]:
    """Hold ``FILE.lock`` beside the exported file (:func:`ftsweep.store.lock.acquire`: a
    killed export's lock is taken over): a second export to the same name is refused,
    naming the first, and writes nothing."""
    from ftsweep.store.lock import LockError, acquire, release

    try:
        lock = acquire(out, command=f"ftsweep export -o {out.name}")
    except LockError as exc:
        raise ExportError(f"{exc}; nothing exported") from None
    try:
        yield
    finally:
        release(lock)


def _export_locked(cube_path: PathLike, out: Path, selection: Selection, writing: Writing) -> dict[str, Any]:
    """:func:`export` once its lock is held: the files are written and signed in a staging
    folder beside ``out`` under their final names, then published (:func:`_publish`)."""
    from ftsweep.exports import nc
    from ftsweep.exports.fingerprint import fingerprint
    from ftsweep.tools.machines import dialect_for, for_machine
    from ftsweep.tools.query import flat_of
    from ftsweep.tools.select import check_exportable, choose, open_cube, recorded_case

    tolerance_nm = selection.tolerance_nm
    name, trust_plugins, signer = writing.name, writing.trust_plugins, writing.signer
    dialect, machine = writing.dialect, writing.machine
    ds = open_cube(cube_path)
    chosen = choose(ds, selection.budget_points, tolerance_nm, selection.index)
    if tolerance_nm is not None and not chosen.get("met", True):
        raise ExportError(
            f"no case meets P-V ≤ {tolerance_nm:g} nm (best found: {chosen['pv_nm']:.2f} nm at "
            f"{chosen['n_points']:,} points); nothing exported"
        )
    flat = flat_of(ds, chosen["index"])
    check_exportable(ds, flat)
    case, specs = recorded_case(ds, flat, trust_plugins)
    planned_for = None
    if machine is not None and machine != case.machine:
        case, specs, chosen, planned_for = for_machine(case, specs, chosen, machine, dialect)
    # the platform decides whether verify must find every number exactly as re-planned
    sequence = ledger.next_sequence(place(cube_path), out.name)
    extra: dict[str, Any] = {
        "cube": str(cube_path),
        "cube_git_revision": ds.attrs.get("git_revision"),
        "platform": fingerprint(),
        "ledger": {"name": out.name, "sequence": sequence},
        **({"planned_for": planned_for} if planned_for else {}),
    }
    dialect = dialect_for(case.machine, specs.machine, dialect, case.layout.kind)
    stage = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".export", dir=out.parent))
    try:
        staged, staged_side = stage / out.name, stage / sidecar_path(out).name
        if dialect != "text":
            meta = nc.export(staged, staged_side, case, specs, chosen, extra, dialect)
        else:
            fmt = format_of_kind(case.layout.kind)
            assert fmt.export is not None
            meta = fmt.export(staged, staged_side, case, specs, chosen, extra, name=name)
        if signer is not None:  # signed before anything is published: a failed signing publishes nothing
            meta = {**meta, "signature": sign(staged, signer.key, signer.expires)}
        # appended before the file is published: a file verify finds is always in the ledger
        ledger.record(place(cube_path), out.name, sequence, _ledger_entry(stage, out, meta))
        _publish(stage, out)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    return meta


def _ledger_entry(stage: Path, out: Path, meta: dict[str, Any]) -> dict[str, Any]:
    """What the cube's ledger records of a staged export: the file's and its sidecar's
    SHA-256, when (the sidecar's ``created``) and the case number exported."""
    return {
        "sha256": hashlib.sha256((stage / out.name).read_bytes()).hexdigest(),
        "sidecar_sha256": hashlib.sha256((stage / sidecar_path(out).name).read_bytes()).hexdigest(),
        "created": str(meta.get("created")),
        # the case exported: report maps it by default
        "case": int(meta["selection"]["index"]),
    }


def check_latest(path: Path, file_bytes: bytes, meta: dict[str, Any]) -> str:
    """Refuse a file that is not the latest export of its name in its cube's ledger (a
    rolled-back file: an older export of the same name); what was checked, or why not (no
    cube recorded, the cube not reachable, no ledger entry of that name)."""
    cube, recorded = meta.get("cube"), meta.get("ledger")
    name = path.name
    if isinstance(recorded, dict) and isinstance(recorded.get("name"), str):
        name = recorded["name"]
    if not isinstance(cube, str):
        return "not checked: the file records no cube (a study's program)"
    try:
        at = place(cube)
        reachable = at.exists("zarr.json")
        found = ledger.sequences(at, name) if reachable else []
    except (OSError, StorageError, ValueError) as exc:
        return f"not checked: the cube {cube} is not reachable ({str(exc)[:120]})"
    if not reachable:
        return f"not checked: the cube {cube} is not reachable from here"
    if not found:
        return f"not checked: the cube's ledger records no export named {name} (exported before ledgers)"
    try:
        return _latest_of(path, name, at, found, hashlib.sha256(file_bytes).hexdigest())
    except ledger.LedgerError as exc:  # an entry that is not one export writes
        raise ExportError(f"{path}: {exc}; do not load it") from None


def check_cube_case(meta: dict[str, Any]) -> str:
    """Whether the case a file names by its coordinates is still, in its cube, the case the
    file was planned from (a cube grown, or started over from another spec, may hold another
    case there): the cube's recorded case spec under those coordinates against the sidecar's.
    One line saying which, or why it was not checked (the cube not reachable)."""
    from ftsweep.exports.origin import case_name_of
    from ftsweep.store import cube
    from ftsweep.tools.query import case_numbers, find_case
    from ftsweep.tools.select import recorded_case

    raw = meta.get("selection")
    selection: dict[str, Any] = raw if isinstance(raw, dict) else {}
    cube_path, name = meta.get("cube"), case_name_of(selection)
    if not isinstance(cube_path, str) or name is None:
        return "not checked: the file names no case of a cube (a study's program)"
    try:
        at = place(cube_path)
        if not at.exists("zarr.json"):
            return f"not checked: the cube {cube_path} is not reachable from here"
        ds = cube.open_dataset(at)
    except (OSError, StorageError, ValueError) as exc:
        return f"not checked: the cube {cube_path} is not reachable ({str(exc)[:120]})"
    try:
        flat = find_case(ds, name)
    except ValueError as exc:
        return f"the cube no longer holds the file's case {name} ({str(exc)[:160]}): it was started over"
    number = int(case_numbers(ds)[flat])
    try:
        planned, _ = recorded_case(ds, flat)
    except ValueError as exc:  # the cube's record of it cannot be read as a case
        return f"not checked: the cube's case {name} cannot be read ({str(exc)[:160]})"
    moved = meta.get("planned_for")
    if isinstance(moved, dict) and isinstance(moved.get("machine"), str):  # export --machine
        planned = planned.model_copy(update={"machine": moved["machine"]})
    if planned.model_dump(mode="json") != meta.get("case") or number != selection.get("index"):
        return (
            f"the cube's case {name} (number {number}) is no longer the case this file was planned from: "
            "the cube was started over from another spec; export it again"
        )
    return f"the cube's case {name} (number {number}) is the file's case"


def _latest_of(path: Path, name: str, at: Any, found: list[int], digest: str) -> str:
    """:func:`check_latest` once the ledger's sequences of ``name`` are ``found``: the file
    (its SHA-256 ``digest``) is the latest export, or refused as an older or unrecorded one."""
    latest = ledger.entry(at, name, found[-1])
    if latest is not None and latest["sha256"] == digest:
        return f"the latest export of {name} in the cube's ledger (sequence {found[-1]})"
    mine = next(
        (k for k in reversed(found) if (ledger.entry(at, name, k) or {}).get("sha256") == digest), None
    )
    if mine is None:
        raise ExportError(
            f"{path} is no export of {name} the cube's ledger records (its latest is sequence {found[-1]}, "
            f"{latest['created'] if latest else '?'}); do not load it"
        )
    raise ExportError(
        f"{path} is export {mine} of {name}, not the latest: the cube's ledger records sequence {found[-1]} "
        f"({latest['created'] if latest else '?'}), a rolled-back file; do not load it"
    )


def _publish(stage: Path, out: Path) -> None:
    """Move the staged sidecar, signature and file into place, the file last, each by one
    ``os.replace`` (a reader sees an old file or the new one whole); a signature left by an
    earlier export of an unsigned file is removed. A kill between two renames can leave a
    new sidecar beside the old file, which verify refuses (their hashes name each other)."""
    side, sig = sidecar_path(out), signature_path(out)
    os.replace(stage / side.name, side)
    if (stage / sig.name).exists():
        os.replace(stage / sig.name, sig)
    else:
        sig.unlink(missing_ok=True)
    os.replace(stage / out.name, out)


def verify(
    path: Path,
    progress: Progress = None,
    pv_tolerance_nm: float | None = None,
    trust_plugins: bool = False,
    trusted: tuple[str, ...] = (),
    accept_recorded: bool = False,
    compiled: bool = False,
    expect: dict[str, Any] | None = None,
    across_platforms: bool = False,
) -> dict[str, Any]:
    """Verify any exported file by its format (:func:`format_of_file`): what the machine
    reads, parsed as the machine parses it, against what the recorded case plans; and its
    origin (:mod:`ftsweep.exports.origin`): with trusted keys (``trusted``, or the config file's)
    its signed statement, else its recorded catalog entries against the local catalog (unless
    ``accept_recorded``). With ``compiled``, the C reference interpolator's commands from
    the file (:mod:`ftsweep.exports.compiled`) must equal the simulator's. ``expect``: facts
    of :func:`~ftsweep.exports.origin.purpose` the file must be for (``case``, ``surface``).
    Numbers are judged exactly as re-planned unless ``across_platforms`` (the operator's
    choice) or a trusted signature names the other platform the file was planned on: then one
    unit of the last printed digit is allowed (the file never chooses its rule).
    The record's ``purpose`` says what the file is for, ``replanned`` which rule judged its
    numbers, ``origin`` what was proved. Raises
    :class:`~ftsweep.exports.files.ExportError` naming the first difference."""
    from ftsweep.engine.cost import bounded_by_default_resolution
    from ftsweep.exports import origin as org
    from ftsweep.exports.fingerprint import exact_on_this_platform, one_unit_across_platforms

    path = Path(path)
    fmt = format_of_file(path)
    side = sidecar_of(path)
    before = _identity(path, side)  # nothing read yet: the format's own cap judges the file first
    keys = org.trusted_keys(trusted)
    signed = _signed_statement(path, keys)
    across = _why_one_unit(across_platforms, signed)
    # the file as the machine reads it first (its own errors name what is wrong with it) ...
    with bounded_by_default_resolution(), one_unit_across_platforms(across):
        record = fmt.verify(path, progress, pv_tolerance_nm, trust_plugins)
    if compiled:
        if fmt.compiled is None:
            raise ExportError(f"--compiled evaluates table headers and PMAC programs, not a {fmt.name}")
        record.update(fmt.compiled(path, trust_plugins))
    file_bytes, side_bytes = _contents(path, side)
    if side_bytes is None or _identity(path, side) != before:  # judged must be what is proved
        raise ExportError(f"{path} or its sidecar changed while it was verified; verify it again")
    meta = read_sidecar(path, side_bytes)
    record["purpose"] = org.purpose(meta)
    with one_unit_across_platforms(across):
        record["replanned"] = exact_on_this_platform(meta.get("platform"))[1]
    _check_expected(path, record["purpose"], expect or {})
    record["latest"] = check_latest(path, file_bytes, meta)
    record["in_cube"] = check_cube_case(meta)
    # ... then who made it
    record["origin"] = _proved_origin(path, meta, file_bytes, side_bytes, keys, accept_recorded, signed)
    if side != sidecar_path(path):
        record["note"] = (
            f"the sidecar has the older name {side.name}; export again to name it {sidecar_path(path).name}"
        )
    return record


def _proved_origin(
    path: Path,
    meta: dict[str, Any],
    file_bytes: bytes,
    side_bytes: bytes,
    keys: list[Path],
    accept_recorded: bool,
    signed: Optional[dict[str, Any]],
) -> dict[str, Any]:
    """What verify proved of who made the file: with trusted ``keys`` its signed statement
    (``signed``, checked already on these bytes, else checked here, which names the fault),
    else its recorded catalog entries against the local catalog (unless ``accept_recorded``)."""
    from ftsweep.exports import origin as org

    if keys:
        statement = signed or org.check_signature(path, file_bytes, side_bytes, meta, keys)
        return {"proved": "signed", **statement}
    if accept_recorded:
        return {"proved": "recorded entries (--accept-recorded): not compared with a catalog"}
    return {"proved": "consistent with this catalog", "catalog": org.check_catalog(meta, sidecar_of(path))}


def _why_one_unit(asked: bool, signed: Optional[dict[str, Any]]) -> str:
    """Why verify may allow one unit across platforms ('' for never): the operator asked, or a
    trusted key signed the statement naming the platform the file was planned on."""
    if asked:
        return "as --across-platforms asks"
    return "the platform is in the statement a trusted key signed" if (signed or {}).get("platform") else ""


def _signed_statement(path: Path, keys: list[Path]) -> Optional[dict[str, Any]]:
    """The statement a trusted key validly signed for the file as it is now (None: no trusted
    key, or no valid signature: the content is then judged exactly, and the origin check after
    it names the fault). Its platform lets verify allow one unit across platforms; verify's
    later check that neither file changed makes it the statement of the bytes it judged."""
    from ftsweep.exports import origin as org

    if not keys:
        return None
    side = sidecar_of(path)
    file_bytes, side_bytes = _contents(path, side)
    if side_bytes is None:
        return None
    try:
        return org.check_signature(path, file_bytes, side_bytes, read_sidecar(path, side_bytes), keys)
    except ExportError:
        return None


def _check_expected(path: Path, purpose: dict[str, Any], expect: dict[str, Any]) -> None:
    """Refuse a file that is not for what the operator expects (``--expect-case``,
    ``--expect-surface``), naming both."""
    for key, wanted in expect.items():
        if wanted is None:
            continue
        got = purpose.get(key)
        if key == "case":  # a case number, or the case's coordinates however they are spaced
            number = str(wanted).strip().isdigit()
            got = got if number else purpose.get("case_name")
            wanted = int(wanted) if number else _spelled(str(wanted))
            got = got if number or got is None else _spelled(str(got))
        if got != wanted:
            raise ExportError(
                f"{path} is for {key} {got!s:.80}, not the expected {wanted}: a swapped or "
                "wrong file; do not load it"
            )


def _spelled(name: str) -> str:
    """A case's coordinates ``points=950000,aspect=16.0`` spelled as its name is."""
    from ftsweep.store.values import value_text

    def one(part: str) -> str:
        axis, _, value = part.partition("=")
        try:
            return f"{axis}={value_text(float(value))}"
        except ValueError:
            return part

    return " ".join(one(p) for p in name.replace(",", " ").split())


def _identity(path: Path, side: Path) -> tuple[tuple[int, ...], ...]:
    """What changes when a file or its sidecar is replaced or written (inode, size, time of
    last change in ns), read from ``stat`` without reading either file."""
    found: list[tuple[int, ...]] = []
    for each in (path, side):
        try:
            info = os.stat(each)
            found.append((info.st_ino, info.st_size, info.st_mtime_ns, info.st_ctime_ns))
        except OSError:
            found.append(())
    return tuple(found)


def _contents(path: Path, side: Path) -> tuple[bytes, bytes | None]:
    """The bytes of a file and its sidecar (regular files only, bounded; None: no sidecar,
    which the format's verify names)."""
    sidecar = read_regular(side, MAX_SIDECAR_BYTES, "sidecar") if side.exists() else None
    return read_regular(path, MAX_PROGRAM_BYTES), sidecar


def purpose_lines(record: dict[str, Any]) -> list[str]:
    """The first lines verify prints: what the file is for (case, surface, machine, cutting,
    compensation, dialect, points, predicted P-V) and, when its statement was checked, who
    signed it when, until when."""
    p = record["purpose"]
    named = p.get("case_name") or f"number {p['case']}"
    case = f"case {named} of {p['cube']}" if p["case"] is not None else "a study's program (no cube)"
    points = f"{p['points']:,} points" if p["points"] is not None else "points not recorded"
    pv = f"predicted P-V {p['pv_nm']:.2f} nm" if isinstance(p["pv_nm"], (int, float)) else "no P-V recorded"
    lines = [
        f"for          {case}",
        f"             surface {p['surface']}, machine {p['machine']}, cutting {p['cutting']}, "
        f"compensation {p['compensation']}",
        f"             {p['dialect']}, {points}, {pv}",
    ]
    measured = p.get("measurement")
    if isinstance(measured, dict):
        lines.append(
            f"corrected    by measurement {measured['sha256'][:16]}… (gain {measured['gain']:g}, "
            f"{measured['terms']:.0f} terms kept)"
        )
    signed = record.get("origin", {})
    if signed.get("key_id"):
        until = f", expires {signed['expires']}" if signed.get("expires") else ", no expiry"
        when = f"at {signed['signed_at']}{until} (ftsweep {signed['ftsweep']})"
        lines.append(f"signed       by key {signed['key_id']} {when}")
    return lines


def replanned_line(record: dict[str, Any]) -> str:
    """The line that says which rule judged the file's numbers against the re-planned ones."""
    return f"re-planned   {record['replanned']}"


def origin_line(record: dict[str, Any]) -> str:
    """The line that says what verify proved of a file's origin (and a note on its sidecar's
    older name, where it has one)."""
    line = _origin(record)
    return f"{line}\nnote         {record['note']}" if record.get("note") else line


def _origin(record: dict[str, Any]) -> str:
    proved = record.get("origin", {})
    if proved.get("key_id"):
        return f"origin       signed by key {proved['key_id']} (trusted)"
    if proved.get("catalog"):
        return (
            f"origin       consistent with this catalog ({proved['catalog']}); no signature checked "
            "(--trusted-key proves who exported it)"
        )
    return f"origin       {proved.get('proved', 'not checked')}"
