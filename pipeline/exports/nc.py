"""Path programs in controllers' dialects (:mod:`ftsweep.exports.dialects`): export from a
cube case, verify against the re-planned program, and programs from elsewhere predicted
(docs/controllers.md). What is particular to a kind (its moves, its simulation from them, its
limits) is the kind's :class:`~ftsweep.exports.dialects.Adapter`, declared beside its format.

A dialect file starts with a comment header (units, tool, spindle, surface, points per
revolution, ftsweep version, interpolation, the sidecar's digest, a CRC-32 over every other
line); its JSON sidecar records the case as a text program's does, the dialect, and the P-V
of the program as written (its numbers rounded to the controller's decimals).
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any, Optional

import numpy as np

from ftsweep.engine import plugins as registry
from ftsweep.engine.case import Case
from ftsweep.exports import dialects
from ftsweep.exports.dialects import Adapter, Moves
from ftsweep.exports.files import (
    ProgramError,
    check_controller_text,
    checked_pv,
    crc_of,
    now,
    recorded_case_of,
    recorded_entries,
    recorded_extra,
    sidecar_digest,
    sidecar_naming,
)
from ftsweep.exports.moves import against, check_velocities, peaks
from ftsweep.inputs.case_entries import Entries
from ftsweep.inputs.catalogs import Controller
from ftsweep.store.io import (
    MAX_PROGRAM_BYTES,
    dumps_json,
    read_regular,
    sidecar_of,
    write_texts_atomic,
)
from ftsweep.version import __version__

CRC_TEXT = "CRC32: 0x{:08x} over every other line"
TEXT_FIELDS = ("program", "program_sha256", "crc32")
# the dialect to name for a machine's interpolation (G-code's first)
DIALECT_OF = {i: d for d, i in reversed(dialects.INTERPOLATION.items())}
HOW = {
    "linear": "linear segments",
    "pvt": "PVT cubic Hermite segments",
    "spline1": "SPLINE1 uniform cubic B-spline",
}


def adapter_of(kind: str) -> Adapter:
    """The dialect adapter of a path kind (its file format's); refused for a kind without."""
    fmt = registry.kind(kind).file_format()
    if fmt.dialect is None:
        raise ProgramError(
            f"a {kind} case is written in ftsweep's own format only: --dialect text (a {kind} case is a "
            "table its FTS controller interpolates; a controller's dialect carries a path program: sweep "
            "the part as one, layout: spiral, on a machine whose controller reads the dialect, as "
            "`ftsweep catalogs` lists them)"
        )
    return fmt.dialect  # type: ignore[no-any-return]


# what a dialect's words mean beyond the axes' units: each file's header says only its own
TIME_UNITS = {
    "linear": "G93 F inverse time",
    "pvt": "PVT segment ms, velocities units/s",
    "spline1": "SPLINE1 segment ms",
}


def _units_line(moves: Moves, dialect: str) -> str:
    """The header's units: the axes the program moves and its dialect's time words."""
    axes = [
        a
        for a, v in (("X", moves.x_mm), ("Y", moves.y_mm), ("Z", moves.z_mm), ("W", moves.w_mm))
        if v is not None
    ]
    return f"units: {' '.join(axes)} mm, C deg, {TIME_UNITS[dialects.INTERPOLATION[dialect]]}"


def named_machine(lines: list[str]) -> Optional[str]:
    """The machine an ftsweep dialect file's header names (``…, machine NAME``), as written:
    the caller checks it against the catalog (a file is data; its text names, never decides)."""
    for line in lines[:40]:
        text = line.strip().lstrip("(;").rstrip(")").strip()
        if text.startswith("surface: ") and ", machine " in text:
            name = text.rsplit(", machine ", 1)[1].strip()
            return name if name.replace("-", "").replace("_", "").isalnum() and len(name) <= 64 else None
    return None


def controller_of(machine: Any, dialect: str) -> Controller:
    """The controller a ``dialect`` program is written for: the machine's, or (a machine that
    declares none) the dialect's defaults. Refuses a dialect whose interpolation is not the
    one the machine's programs were simulated with."""
    want = dialects.INTERPOLATION[dialect]
    if machine.interpolation != want:
        readers = ", ".join(f"--machine {m}" for m in dialects.machines_reading(dialect))
        raise ProgramError(
            f"the machine's controller interpolates {machine.interpolation}, but a {dialect} program is cut "
            f"with {want} segments: not the program the cube predicted; export --dialect "
            f"{DIALECT_OF[machine.interpolation]}, or plan and predict the case for a machine whose "
            f"controller reads {dialect}: {readers or 'none in the catalog'}"
        )
    ctrl = machine.controller
    if ctrl is None:
        return Controller(dialect=dialect, interpolation=want)
    if ctrl.dialect == dialect:
        return ctrl
    # the same interpolation in another dialect (ISO or LinuxCNC): the machine's limits, the
    # conventions of that dialect's controller
    limits = ("time_quantum_s", "max_segment_s", "decimals", "max_blocks", "servo_period_s", "c_limit_deg")
    return Controller(dialect=dialect, interpolation=want, **{k: getattr(ctrl, k) for k in limits})


def _document(
    case: Case, specs: Entries, dialect: str, meta_in: dict[str, Any]
) -> tuple[list[str], dict[str, Any], tuple[Adapter, Any]]:
    """The lines (CRC line not yet filled), sidecar, and the kind's adapter with the resolved
    case it planned, of a case's program."""
    ctrl = controller_of(specs.machine, dialect)
    adapter = adapter_of(case.layout.kind)
    moves, kind_lines, rcase = adapter.planned(case, specs)
    if ctrl.interpolation == "pvt" and moves.cut_starts is None:
        planned = moves.n_points
        moves = dialects.with_stop(moves, dialects.stop_seconds(moves, specs.machine, ctrl.time_quantum_s))
        # the kind's own line counts its points; the file holds the stop too, as export says
        kind_lines = [
            *kind_lines,
            f"stop: one point past the {planned} planned brings every axis to rest, "
            f"{moves.n_points} points in all",
        ]
    dialects.check_limits(moves, ctrl)
    meta = {
        **meta_in,
        "layout": case.layout.kind,
        "dialect": dialect,
        "controller": ctrl.model_dump(mode="json"),
        "n_points": moves.n_points,
        "case": case.model_dump(mode="json"),
        "catalog_entries": recorded_entries(specs),
    }
    comments = [
        f"ftsweep {case.layout.kind} program, dialect {dialect}: {HOW[moves.interpolation]} between points",
        f"generator: ftsweep {__version__}",
        f"surface: {case.surface}, compensation {case.compensation}, machine {case.machine}",
        *kind_lines,
        _motion_line(moves),
        _units_line(moves, dialect),
        *(f"conventions: {c}" for c in ctrl.conventions()),
        f"sidecar sha256: {sidecar_digest(meta, TEXT_FIELDS)}",
        CRC_TEXT.format(0),
    ]
    return dialects.render(moves, dialect, comments, ctrl), meta, (adapter, rcase)


def _motion_line(moves: Moves) -> str:
    """Revolutions, points per revolution and spindle speed of the moves (averages)."""
    s = dialects.summary(moves)
    return (
        f"motion: {s['revolutions']:.6g} revolutions, {s['points_per_rev']:.6g} points per revolution and "
        f"{s['spindle_rpm']:.6g} rpm on average, {s['machining_s']:.3f} s"
    )


def _with_crc(lines: list[str], dialect: str) -> tuple[list[str], int]:
    """The lines with their CRC line (the last comment of the header) filled in."""
    at = _crc_index(lines, dialect)
    crc = crc_of(lines[:at] + lines[at + 1 :])
    done = list(lines)
    done[at] = dialects.comment(dialect, CRC_TEXT.format(crc))
    return done, crc


def _crc_index(lines: list[str], dialect: str) -> int:
    for i, line in enumerate(lines[:40]):
        text = dialects.comment_text(dialect, line)
        if text is not None and text.startswith("CRC32: "):
            return i
    raise ProgramError("the program has no CRC32 comment line")


def export(
    out: Path,
    side: Path,
    case: Case,
    specs: Entries,
    chosen: dict[str, Any],
    extra: dict[str, Any],
    dialect: str,
) -> dict[str, Any]:
    """Plan a path case again and write it in ``dialect`` with its sidecar, atomically;
    refused, named, when the moves as written leave the machine's limits. The sidecar records
    the P-V of the program as written (re-simulated from its lines as the reader reads them)."""
    meta_in = {
        "generator": f"ftsweep {__version__}",
        "created": now(),  # the sidecar's time stamp, outside its digest: the program is the same file
        "pv_nm": chosen["pv_nm"],
        **extra,
        "selection": chosen,
    }
    lines, meta, (adapter, rcase) = _document(case, specs, dialect, meta_in)
    moves = dialects.read(lines, dialect, meta["controller"])
    reason = adapter.check(rcase, moves)
    if reason:
        raise ProgramError(
            f"the program leaves the limits of machine '{case.machine}': {reason}; nothing exported"
        )
    meta["pv_nm_as_written"] = adapter.simulate(case, specs, moves, None, rcase)["pv_nm"]
    digest = sidecar_digest(meta, TEXT_FIELDS)  # the header names the sidecar as written
    lines = [_replace_digest(line, dialect, digest) for line in lines]
    lines, crc = _with_crc(lines, dialect)
    data = ("\n".join(lines) + "\n").encode("ascii")
    meta.update(program=out.name, crc32=crc, program_sha256=hashlib.sha256(data).hexdigest())
    write_texts_atomic({side: dumps_json(meta, indent=2) + "\n", out: data})
    return meta


def _replace_digest(line: str, dialect: str, digest: str) -> str:
    text = dialects.comment_text(dialect, line)
    if text is not None and text.startswith("sidecar sha256: "):
        return dialects.comment(dialect, f"sidecar sha256: {digest}")
    return line


def read_lines(path: Path, strict: bool) -> list[str]:
    """A program's lines: ASCII, bounded, a regular file; ``strict`` (a file ftsweep wrote)
    as export writes them (LF only, no blank line), else CR LF line ends allowed and every
    line kept, blank ones too, so that ``lines[k]`` is the file's line k + 1 as an editor
    counts it."""
    raw = read_regular(path, MAX_PROGRAM_BYTES, "program")
    if not strict:
        raw = raw.replace(b"\r\n", b"\n")
        if raw and not raw.endswith(b"\n"):
            raw += b"\n"
    check_controller_text(path, raw, blank_lines=not strict)
    return raw.decode("ascii").split("\n")[:-1]


def is_dialect_file(first_line: str) -> bool:
    """Whether a first line is that of an ftsweep dialect program."""
    return first_line.startswith(("(ftsweep ", "; ftsweep ")) and ", dialect " in first_line


def dialect_named(lines: list[str]) -> str:
    """The dialect an ftsweep dialect program's first line names."""
    first = lines[0] if lines else ""
    text = dialects.comment_text("pmac-pvt" if first.startswith("; ") else "iso-sts", first) or ""
    dialect = text.split(", dialect ", 1)[-1].split(":", 1)[0]
    if dialect not in dialects.INTERPOLATION:
        raise ProgramError("line 1 names no dialect ftsweep writes")
    return dialect


def _checked_text(path: Path, lines: list[str], dialect: str) -> dict[str, Any]:
    """The sidecar of a dialect program whose CRC, hashes and sidecar digest check out."""
    at = _crc_index(lines, dialect)
    stored = (dialects.comment_text(dialect, lines[at]) or "").split()[1]
    crc = crc_of(lines[:at] + lines[at + 1 :])
    if stored != f"0x{crc:08x}":
        raise ProgramError(f"{path}: CRC32 mismatch (header {stored}): a line was changed; do not run it")
    data = ("\n".join(lines) + "\n").encode("ascii")
    stated = [t for t in (dialects.comment_text(dialect, ln) for ln in lines[:at]) if t]
    digest = next((t[len("sidecar sha256: ") :] for t in stated if t.startswith("sidecar sha256: ")), "")
    meta = sidecar_naming(path, hashlib.sha256(data).hexdigest(), digest)
    return dict(meta, _digest=digest, _crc=crc)


def verify(
    path: Path, progress: Any = None, pv_tolerance_nm: Optional[float] = None, trust_plugins: bool = False
) -> dict[str, Any]:
    """Check a dialect program: CRC and sidecar, every line equal to the program its recorded
    case plans again (the first difference named by line), the moves within the machine's
    limits, then the part re-simulated from what the file commands as the strict reader reads
    it, against the P-V the export recorded."""
    path = Path(path)
    lines = read_lines(path, strict=True)
    dialect = dialect_named(lines)
    meta = _checked_text(path, lines, dialect)
    digest, crc = meta.pop("_digest"), meta.pop("_crc")
    case, specs = recorded_case_of(meta, sidecar_of(path), trust_plugins)
    meta_in: dict[str, Any] = {k: meta[k] for k in ("generator", "pv_nm", "selection") if k in meta}
    meta_in.update(recorded_extra(meta))
    planned, expected, (adapter, rcase) = _document(case, specs, dialect, meta_in)
    claims = [k for k in expected if k not in TEXT_FIELDS and _json(meta.get(k)) != _json(expected[k])]
    if claims:
        raise ProgramError(
            f"{sidecar_of(path)}: {', '.join(claims[:5])} differ(s) from what the recorded case gives"
        )
    planned, _ = _with_crc([_replace_digest(line, dialect, digest) for line in planned], dialect)
    for number, (a, b) in enumerate(zip(lines, planned, strict=False), start=1):
        if a != b and "conventions: " in a and "conventions: " in b:
            raise ProgramError(
                f"{path}: line {number} states the controller conventions {a[:160]!r}, machine "
                f"'{case.machine}' has {b[:160]!r}: the file was written for another profile; do not run it"
            )
        if a != b:
            raise ProgramError(
                f"{path}: line {number} reads {a[:100]!r} where the recorded case gives {b[:100]!r}; "
                "do not run it"
            )
    if len(lines) != len(planned):
        raise ProgramError(
            f"{path}: {len(lines):,} lines where the recorded case gives {len(planned):,}; do not run it"
        )
    moves = dialects.read(lines, dialect, meta["controller"])
    reason = adapter.check(rcase, moves)
    if reason:
        raise ProgramError(
            f"{path}: a block leaves the limits of machine '{case.machine}': {reason}; do not run it"
        )
    record = adapter.simulate(case, specs, moves, progress, rcase)
    record = checked_pv(path, {**meta, "pv_nm": meta["pv_nm_as_written"]}, record, pv_tolerance_nm)
    # the file's points (a layered program's cuts repeat the points layers share)
    record.update(dialect=dialect, cube_pv_nm=float(meta["pv_nm"]), checksum=f"0x{crc:08x}")
    record.update(n_points=moves.n_points, cuts=len(moves.cuts()))
    return record


def _json(value: Any) -> str:
    return dumps_json(value, sort_keys=True)


def default_dialect(machine: Any) -> str:
    """The dialect a machine's programs are exported in by default (its controller's)."""
    return "text" if machine.controller is None else str(machine.controller.dialect)


def dialect_format() -> Any:
    """The file format of dialect programs (:class:`ftsweep.exports.files.FileFormat`)."""
    from ftsweep.engine.contract import FileFormat
    from ftsweep.exports.files import pv_lines

    def exported(out: Path, meta: dict[str, Any]) -> list[str]:
        return [
            f"program      {out} ({meta['dialect']}, {meta['n_points']:,} points, "
            f"CRC-32 0x{meta['crc32']:08x}; "
            f"P-V as written {meta['pv_nm_as_written']:.2f} nm)"
        ]

    def verified(record: dict[str, Any]) -> list[str]:
        return [
            f"checksum     {record['checksum']} (every other line) ok; sidecar and file hashes ok",
            f"program      {record['layout']} in {record['dialect']}: {record['n_points']:,} points"
            + (f" in {record['cuts']:,} cuts" if record.get("cuts", 1) > 1 else "")
            + ", every line as re-planned",
            *pv_lines(record, "the program as the controller reads it"),
            f"cube         P-V {record['cube_pv_nm']:.2f} nm before rounding to the controller's decimals",
        ]

    def export_fn(*args: Any, name: Optional[str] = None) -> dict[str, Any]:
        raise ProgramError("dialect programs are written by export --dialect")

    return FileFormat(
        "dialect program", None, export_fn, verify, exported, verified, compiled=check_dialect_file
    )


def read_any(path: Path, machine: Optional[str] = None) -> Moves:
    """The moves of a program file in any supported dialect (ftsweep's own dialect files by
    their first line, others by their blocks: :func:`ftsweep.exports.dialects.detect`), read
    as the profile of ``machine`` (else the one the file names, else its dialect's default
    machine) says (:func:`profile_for`)."""
    lines = read_lines(Path(path), strict=False)
    dialect = _dialect_of(lines)
    name, _ = _machine_for(named_machine(lines), machine, dialect)
    return dialects.read(lines, dialect, profile_for(name, dialect))


def _dialect_of(lines: list[str]) -> str:
    """A program's dialect, named by its first line (ftsweep's) or by its blocks."""
    return dialect_named(lines) if lines and is_dialect_file(lines[0]) else dialects.detect(lines)


def profile_for(machine: str, dialect: str, g93_f: Optional[str] = None) -> Controller:
    """The controller profile a ``dialect`` program is read with on ``machine``: the machine's
    when it reads that dialect, else that dialect's controller's conventions with the
    machine's limits; ``g93_f`` overrides what F means under G93."""
    from ftsweep.inputs import catalogs

    entry = catalogs.entry("machines", machine)
    ctrl = entry.controller
    want = dialects.INTERPOLATION[dialect]
    if ctrl is None or ctrl.dialect != dialect:
        keep = (
            {}
            if ctrl is None
            else {k: getattr(ctrl, k) for k in ("decimals", "max_blocks", "servo_period_s")}
        )
        ctrl = Controller(dialect=dialect, interpolation=want, **keep)
    return ctrl if g93_f is None else ctrl.model_copy(update={"g93_f": g93_f})


def predict_program(
    path: Path,
    surface: Optional[str],
    machine: Optional[str],
    cutting: Optional[str],
    g93_f: Optional[str] = None,
    progress: Any = None,
    map_bins: Optional[int] = None,
    nose_radius_um: Optional[float] = None,
    preamble: Optional[Path] = None,
    compiled: bool = False,
) -> dict[str, Any]:
    """Read a path program in any supported dialect (ftsweep's or another CAM's) as the
    profile of its machine (``machine``, else the one its header names, else its dialect's
    default) says, summarise it (points, revolutions, feed per revolution, spindle speed,
    peak axis speeds and accelerations against the machine's limits) and, with a
    ``surface``, predict the form error it leaves (with ``map_bins``, its error map) through
    the one simulator, as the program kind that reads programs from elsewhere (its adapter's
    ``stand_in``) simulates it, with the ``cutting`` entry's tool or ``nose_radius_um`` [µm]
    (docs/controllers.md). A ``preamble`` file's lines are read first, the program's
    own from the modal state they leave (a bare point list in its template's state). With
    ``compiled``, the C reference reads the same file (after its preamble) and every axis
    of every cut is compared with this reading (:func:`ftsweep.exports.compiled.compare_reading`)."""
    from ftsweep.inputs import catalogs

    lines = read_lines(Path(path), strict=False)  # read once: its moves and the machine it names
    head = [] if preamble is None else read_lines(Path(preamble), strict=False)
    whole = head + lines
    dialect = _dialect_of(whole)
    machine, machine_from = _machine_for(named_machine(whole), machine, dialect)
    ctrl = profile_for(machine, dialect, g93_f)
    moves = dialects.read(whole, dialect, ctrl, preamble=len(head))
    info: dict[str, Any] = {
        "program": str(path),
        "dialect": moves.dialect,
        "interpolation": moves.interpolation,
        "machine": machine,
        "machine_from": machine_from,
        "conventions": ctrl.conventions(),
        "cut_rule": ctrl.cut_rule(),
    }
    if preamble is not None:
        info["preamble"] = str(preamble)
    if compiled:
        info["compiled"] = _compiled_reading(whole, moves, ctrl, path)
    info.update(dialects.summary(moves))
    entry = catalogs.entry("machines", machine)
    check_velocities(moves, entry, machine)
    info["axes"] = against(peaks(moves), entry)
    info["notes"] = list(moves.notes)
    if entry.interpolation != moves.interpolation:
        info["notes"].append(
            f"the file commands {moves.interpolation} segments, machine {machine}'s controller forms "
            f"{entry.interpolation} ones: predicted as the file commands them"
        )
    if surface is None:
        return info
    info.update(_predicted(moves, surface, machine, cutting, progress, map_bins, nose_radius_um))
    return info


def _compiled_reading(lines: list[str], moves: Moves, ctrl: Controller, path: Path) -> dict[str, Any]:
    """The C reference's reading of a program's ``lines`` (its preamble's first) against
    ``moves``, the strict reader's."""
    import tempfile

    from ftsweep.exports.compiled import compare_reading

    with tempfile.TemporaryDirectory(prefix="ftsweep-program-") as tmp:
        whole = Path(tmp) / Path(path).name
        whole.write_text("\n".join(lines) + "\n", encoding="ascii")
        return compare_reading(whole, moves, ctrl)


def _predicted(
    moves: Moves,
    surface: str,
    machine: str,
    cutting: Optional[str],
    progress: Any,
    map_bins: Optional[int],
    nose_radius_um: Optional[float],
) -> dict[str, Any]:
    """The form error a program's ``moves`` leave on ``surface`` (:func:`predict_program`)."""
    kind, adapter = _foreign_reader()
    case = adapter.stand_in(surface, machine, cutting or "reference")  # type: ignore[misc]
    # a map always: it says where the error's extremes lie
    res = case.resolution.model_copy(update={"error_map_bins": map_bins or WHERE_BINS})
    case = case.model_copy(update={"resolution": res})
    if nose_radius_um is not None:
        case = case.model_copy(update={"nose_radius_um": nose_radius_um})
    record = adapter.simulate(case, None, moves, progress, None)
    info = {k: record[k] for k in ("pv_nm", "rms_nm", "pv_interp_nm", "nose_radius_um", "feed_um")}
    info.update(surface=surface, kind=kind, extremes=extremes(record))
    for key in ("cut_radii_mm", "judged_radii_mm"):
        if key in record:
            info[key] = list(record[key])
    info.update({k: record[k] for k in PROGRAM_ERRORS if k in record})
    if not map_bins:
        record = {k: v for k, v in record.items() if not k.startswith("error_map")}
    info["record"] = record
    return info


# a program's form error by cause and by zone (:mod:`ftsweep.kinds.spiral.commanded`)
PROGRAM_ERRORS = ("pv_departure_nm", "centre_radius_mm", "pv_centre_nm", "pv_beyond_centre_nm")

# bins per side of the map that locates a program's highest and lowest error
WHERE_BINS = 64


def extremes(record: dict[str, Any]) -> dict[str, dict[str, float]]:
    """Where a predicted part's form error is highest and lowest: the centres [mm] of the
    error map's bins whose peak error [nm] is the largest and the least, with those errors."""
    peak = np.asarray(record["error_map_peak_nm"], dtype=np.float64)
    centres = np.asarray(record["error_map_x_um"], dtype=np.float64) * 1e-3
    if not np.any(np.isfinite(peak)):
        return {}
    out = {}
    for name, at in (("highest", np.nanargmax(peak)), ("lowest", np.nanargmin(peak))):
        iy, ix = np.unravel_index(int(at), peak.shape)
        x, y = float(centres[ix]), float(centres[iy])
        out[name] = {"x_mm": x, "y_mm": y, "r_mm": float(np.hypot(x, y)), "error_nm": float(peak[iy, ix])}
    return out


# the machine a program is read against when neither --machine nor the file names one
DEFAULT_MACHINE = {
    "iso-sts": "sts-moore",
    "linuxcnc": "sts-linuxcnc",
    "pmac-pvt": "sts-pmac-pvt",
    "pmac-spline": "sts-pmac-spline",
}


def _machine_for(named: Optional[str], given: Optional[str], dialect: str) -> tuple[str, str]:
    """The machine a program is read against and where it came from: ``--machine``, else the
    one the file's header names (``named``) when the catalog has it, else its dialect's
    default."""
    from ftsweep.inputs import catalogs

    if given:
        return given, "--machine"
    if named is not None and named in catalogs.entries("machines"):
        return named, "named by the file"
    why = f"the file names {named!r}, which the catalog lacks" if named else "the file names none"
    return DEFAULT_MACHINE[dialect], f"default for {dialect} programs ({why}; give --machine)"


def _foreign_reader() -> tuple[str, Adapter]:
    """The registered kind whose adapter simulates programs from elsewhere (the first)."""
    for name, kind in registry.kinds().items():
        adapter = kind.file_format().dialect
        if adapter is not None and adapter.stand_in is not None:
            return name, adapter
    raise ProgramError("no registered program kind reads programs from elsewhere")


def check_dialect_file(path: Path, trust_plugins: bool = False) -> dict[str, Any]:
    """:func:`check_program` of a dialect program verify has read already, through its
    kind's adapter (the ``compiled`` check of :func:`dialect_format`)."""
    from ftsweep.exports.compiled import check_program
    from ftsweep.store.io import read_sidecar

    lines = read_lines(Path(path), strict=True)
    meta = read_sidecar(Path(path))
    adapter = adapter_of(str(meta.get("layout")))
    dialect = dialect_named(lines)
    ctrl = Controller.model_validate(
        {**meta["controller"], "dialect": dialect, "interpolation": dialects.INTERPOLATION[dialect]}
    )
    return check_program(path, dialects.read(lines, dialect, ctrl), adapter, ctrl)
