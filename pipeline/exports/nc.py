"""Spiral programs ([4]) in controllers' dialects (:mod:`ftsweep.exports.dialects`): export
from a cube case, verify against the re-planned program, and any dialect's program (ftsweep's
or another CAM's) turned into the program the one simulator runs (docs/controllers.md).

A dialect file starts with a comment header (units, tool, spindle, surface, points per
revolution, ftsweep version, interpolation, the sidecar's digest, a CRC-32 over every other
line); its JSON sidecar records the case as a text program's does, the dialect, and the P-V
of the program as written (its numbers rounded to the controller's decimals).
"""

from __future__ import annotations

import hashlib
import math
import zlib
from pathlib import Path
from typing import Any, Optional

import numpy as np

from ftsweep.engine.case import Case, CaseError
from ftsweep.exports import dialects
from ftsweep.exports.dialects import DialectError, Moves
from ftsweep.exports.files import (
    ProgramError,
    check_controller_text,
    checked_pv,
    recorded_case_of,
    recorded_entries,
    recorded_extra,
    sidecar_digest,
)
from ftsweep.inputs.catalogs import Controller
from ftsweep.simulate import resolve_case, run_case
from ftsweep.stages import segments
from ftsweep.stages.spiral import SpiralPath
from ftsweep.store.io import (
    MAX_PROGRAM_BYTES,
    dumps_json,
    read_regular,
    read_sidecar,
    sidecar_path,
    write_texts_atomic,
)
from ftsweep.version import __version__

MAGIC = "ftsweep spiral program"
CRC_TEXT = "CRC32: 0x{:08x} over every other line"
TEXT_FIELDS = ("program", "program_sha256", "crc32")
DIALECT_OF = {"linear": "iso-sts", "pvt": "pmac-pvt", "spline1": "pmac-spline"}


def controller_of(machine: Any, dialect: str) -> Controller:
    """The controller a ``dialect`` program is written for: the machine's, or (a machine that
    declares none) the dialect's defaults. Refuses a dialect whose interpolation is not the
    one the machine's programs were simulated with."""
    want = dialects.INTERPOLATION[dialect]
    if machine.interpolation != want:
        raise ProgramError(
            f"the machine's controller interpolates {machine.interpolation}, but a {dialect} program is cut "
            f"with {want} segments: not the program the cube predicted; export --dialect "
            f"{DIALECT_OF[machine.interpolation]}"
        )
    ctrl = machine.controller
    if ctrl is None or ctrl.dialect != dialect and dialect not in ("iso-sts", "linuxcnc"):
        return Controller(dialect=dialect, interpolation=want) if ctrl is None else ctrl
    return ctrl if ctrl.dialect == dialect else ctrl.model_copy(update={"dialect": dialect})


def omega(rpm: float) -> float:
    """Spindle angular speed [rad/s] of ``rpm``."""
    return rpm * math.pi / 30.0


def moves_of(path: SpiralPath, values_um: np.ndarray, rpm: float) -> Moves:
    """A planned spiral (points, commands [µm], its segments) as a controller's moves at a
    constant spindle speed: C accumulated [deg], X [mm], Z [mm], segment times [s]; PVT
    velocities from the segments' tangents; a SPLINE1 program's Z as its control points."""
    w = omega(rpm)
    phi = path.phi
    seconds = np.diff(phi) / w
    x = path.rho * 1e-3
    z = np.asarray(values_um) * 1e-3
    velocity = None
    if path.interpolation == "pvt":
        assert path.d0 is not None and path.d1 is not None
        dphi = np.diff(phi)
        slope = np.append(path.d0 / dphi, path.d1[-1] / dphi[-1])  # µm/rad, continuous (C¹)
        velocity = {
            "C": np.full(phi.size, math.degrees(w)),
            "X": np.full(phi.size, -path.feed_um / (2.0 * math.pi) * w * 1e-3),
            "Z": slope * w * 1e-3,
        }
    elif path.interpolation == "spline1":
        z = segments.control_points(np.asarray(values_um)) * 1e-3
    return Moves(np.degrees(phi), x, z, seconds, None, velocity, path.interpolation)


def _limits(moves: Moves, ctrl: Controller) -> None:
    """Refuse, naming the limit, a program the controller cannot run."""
    blocks = moves.n_points - 1
    if blocks > ctrl.max_blocks:
        raise ProgramError(
            f"the program has {blocks:,} blocks, more than the controller's {ctrl.max_blocks:,}"
        )
    longest = float(moves.seconds.max(initial=0.0))
    if longest > ctrl.max_segment_s:
        raise ProgramError(
            f"a segment takes {longest * 1e3:.6g} ms, longer than the controller's "
            f"{ctrl.max_segment_s * 1e3:g} ms"
        )
    if ctrl.interpolation == "spline1":
        ta = float(moves.seconds[0])
        if not np.allclose(moves.seconds[:-1], ta, rtol=1e-9) or not segments.whole_steps(ta * 1e3, 1.0):
            raise ProgramError(
                f"SPLINE1 needs one TA of whole milliseconds; this program's is {ta * 1e3:.6g} ms"
            )


def header(
    case: Case, specs: tuple[Any, Any, Any], path: SpiralPath, rcase: Any, dialect: str, digest: str
) -> list[str]:
    """The comment header of a dialect program (every line ASCII, no parentheses)."""
    rpm = specs[2].spindle_rpm
    how = {
        "linear": "linear segments",
        "pvt": "PVT cubic Hermite segments",
        "spline1": "SPLINE1 uniform cubic B-spline",
    }
    return [
        f"{MAGIC}, dialect {dialect}: {how[path.interpolation]} between points",
        f"generator: ftsweep {__version__}",
        f"surface: {case.surface}, compensation {case.compensation}, machine {case.machine}",
        f"tool: nose radius {rcase.nose_radius_um:.6g} um, feed {rcase.feed_um:.9g} um/rev",
        f"spindle: {rpm:g} rpm, C increasing, the spiral runs from the edge to the centre",
        f"points: {path.n_points}, {path.max_points_per_rev} per revolution at most, "
        f"{path.revolutions:.6g} revolutions",
        "units: X Z mm, C deg, G93 F inverse time, PVT segment ms, velocities units/s",
        f"sidecar sha256: {digest}",
    ]


def _document(
    case: Case, specs: tuple[Any, Any, Any], dialect: str, meta_in: dict[str, Any]
) -> tuple[list[str], Moves, dict[str, Any], SpiralPath]:
    """The lines (CRC line not yet filled), moves, sidecar and path of a case's program."""
    ctrl = controller_of(specs[1], dialect)
    rcase = resolve_case(case, specs=specs)
    path = rcase.layout
    if not isinstance(path, SpiralPath):
        raise ProgramError(
            f"a {case.layout.kind} case is not written in controller dialects yet: --dialect text"
        )
    moves = moves_of(path, rcase.values, specs[2].spindle_rpm)
    _limits(moves, ctrl)
    meta = {
        **meta_in,
        "layout": "spiral",
        "dialect": dialect,
        "controller": ctrl.model_dump(mode="json"),
        "n_points": path.n_points,
        "case": case.model_dump(mode="json"),
        "catalog_entries": recorded_entries(specs),
    }
    digest = sidecar_digest(meta, TEXT_FIELDS)
    comments = [*header(case, specs, path, rcase, dialect, digest), CRC_TEXT.format(0)]
    return dialects.render(moves, dialect, comments, ctrl), moves, meta, path


def _with_crc(lines: list[str], dialect: str) -> tuple[list[str], int]:
    """The lines with their CRC line (the last comment of the header) filled in."""
    at = _crc_index(lines, dialect)
    crc = zlib.crc32("\n".join(lines[:at] + lines[at + 1 :]).encode("ascii")) & 0xFFFFFFFF
    done = list(lines)
    done[at] = _comment_line(dialect, CRC_TEXT.format(crc))
    return done, crc


def _comment_line(dialect: str, text: str) -> str:
    return f"; {text}" if dialect.startswith("pmac") else f"({text})"


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
    specs: tuple[Any, Any, Any],
    chosen: dict[str, Any],
    extra: dict[str, Any],
    dialect: str,
) -> dict[str, Any]:
    """Plan a spiral case again and write it in ``dialect`` with its sidecar, atomically;
    the sidecar records the P-V of the program as written (re-simulated from its lines)."""
    meta_in = {"generator": f"ftsweep {__version__}", "pv_nm": chosen["pv_nm"], **extra, "selection": chosen}
    lines, _, meta, _ = _document(case, specs, dialect, meta_in)
    # the program as the controller reads it, simulated: its decimals are the controller's
    moves = dialects.read(lines, dialect, meta["controller"]["g93_f"])
    record = simulate_moves(case, specs, moves)
    meta["pv_nm_as_written"] = record["pv_nm"]
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
        return _comment_line(dialect, f"sidecar sha256: {digest}")
    return line


def simulate_moves(
    case: Case, specs: Optional[tuple[Any, Any, Any]], moves: Moves, progress: Any = None
) -> dict[str, Any]:
    """The record of ``case`` with its program replaced by ``moves`` (:func:`program_of`)."""
    return run_case(case, specs=specs, progress=progress, program=program_of(moves))


# how far a program's X may lie off the Archimedean spiral its first and last points set:
# half the last printed digit plus a thousandth of the feed
SPIRAL_SLACK_FEED = 1e-3


def program_of(moves: Moves) -> tuple[SpiralPath, np.ndarray]:
    """The spiral path and commands [µm] a program's moves give the one simulator: φ from C
    (accumulated), ρ0 and the feed from X (refused unless X follows ρ0 − F·φ/2π), and the
    segments its interpolation forms (PVT: tangents V·T; SPLINE1: the B-spline of its
    control points)."""
    phi = np.radians(moves.c_deg)
    if moves.n_points < 3 or not np.all(np.diff(phi) > 0.0):
        raise DialectError("a spiral program needs at least 3 points with C increasing from block to block")
    x_um = moves.x_mm * 1e3
    span = float(phi[-1] - phi[0])
    feed = 2.0 * math.pi * float(x_um[0] - x_um[-1]) / span
    if not feed > 0.0:
        raise DialectError(
            "X does not decrease along the program: not a facing spiral from the edge to the centre"
        )
    rho0 = float(x_um[0]) + feed * float(phi[0]) / (2.0 * math.pi)
    off = np.abs(rho0 - feed * phi / (2.0 * math.pi) - x_um)
    slack = 0.5 * 10.0 ** (3 - 6) + SPIRAL_SLACK_FEED * feed + 1e-3 * float(np.max(np.abs(x_um))) * 1e-6
    worst = int(np.argmax(off))
    if off[worst] > max(slack, 1e-3):
        raise DialectError(
            f"point {worst + 1}: X is {off[worst]:.4g} µm off the spiral of constant feed {feed:.6g} µm/rev "
            "through the first and last points: the one simulator predicts constant-feed spirals only"
        )
    z_um = moves.z_mm * 1e3
    rule = SpiralPath("spiral", phi, rho0, feed, "chord", 0.0)
    if moves.interpolation == "linear":
        return rule, z_um
    if moves.interpolation == "pvt":
        assert moves.velocity is not None
        d0, d1 = segments.pvt_tangents(moves.velocity["Z"] * 1e3, moves.seconds)
        return rule._replace(interpolation="pvt", d0=d0, d1=d1), z_um
    way, d0, d1 = segments.bspline_segments(z_um)
    return rule._replace(interpolation="spline1", d0=d0, d1=d1), way


def read_lines(path: Path, strict: bool) -> list[str]:
    """A program's lines: ASCII, bounded, a regular file; ``strict`` (a file ftsweep wrote)
    as export writes them (LF only, no blank line), else CR LF line ends allowed."""
    raw = read_regular(path, MAX_PROGRAM_BYTES, "program")
    if not strict:
        raw = raw.replace(b"\r\n", b"\n")
        if raw and not raw.endswith(b"\n"):
            raw += b"\n"
        raw = b"\n".join(line for line in raw.split(b"\n") if line.strip()) + b"\n"
    check_controller_text(path, raw)
    return raw.decode("ascii").split("\n")[:-1]


def is_dialect_file(first_line: str) -> bool:
    """Whether a first line is that of an ftsweep dialect program."""
    return any(first_line.startswith(p + MAGIC) for p in ("(", "; "))


def verify(
    path: Path, progress: Any = None, pv_tolerance_nm: Optional[float] = None, trust_plugins: bool = False
) -> dict[str, Any]:
    """Check a dialect program: CRC and sidecar, every line equal to the program its recorded
    case plans again (named by line), then the part re-simulated from what the file commands
    as the strict reader reads it, against the P-V the export recorded."""
    path = Path(path)
    lines = read_lines(path, strict=True)
    dialect = "pmac-pvt" if lines[0].startswith("; ") else "iso-sts"
    first = dialects.comment_text(dialect, lines[0]) or ""
    dialect = first.split("dialect ", 1)[-1].split(":", 1)[0]
    if dialect not in dialects.INTERPOLATION:
        raise ProgramError(f"{path}: line 1 names no dialect ftsweep writes")
    at = _crc_index(lines, dialect)
    stored = (dialects.comment_text(dialect, lines[at]) or "").split()[1]
    crc = zlib.crc32("\n".join(lines[:at] + lines[at + 1 :]).encode("ascii")) & 0xFFFFFFFF
    if stored != f"0x{crc:08x}":
        raise ProgramError(f"{path}: CRC32 mismatch (header {stored}): a line was changed; do not run it")
    meta = read_sidecar(path)
    data = ("\n".join(lines) + "\n").encode("ascii")
    if meta.get("program_sha256") != hashlib.sha256(data).hexdigest():
        raise ProgramError(f"{sidecar_path(path)} does not belong to {path} (SHA-256 of the program differs)")
    digest = sidecar_digest(meta, TEXT_FIELDS)
    if not any(dialects.comment_text(dialect, ln) == f"sidecar sha256: {digest}" for ln in lines[:at]):
        raise ProgramError(f"{path}: the sidecar was changed (its SHA-256 differs from the header's)")
    case, specs = recorded_case_of(meta, sidecar_path(path), trust_plugins)
    meta_in = {k: meta[k] for k in ("generator", "pv_nm", "selection") if k in meta}
    meta_in.update(recorded_extra(meta))
    planned, _, expected, _ = _document(case, specs, dialect, meta_in)
    claims = [k for k in expected if k not in TEXT_FIELDS and _json(meta.get(k)) != _json(expected[k])]
    if claims:
        raise ProgramError(
            f"{sidecar_path(path)}: {', '.join(claims[:5])} differ(s) from what the recorded case gives"
        )
    planned = [_replace_digest(line, dialect, digest) for line in planned]
    planned, _ = _with_crc(planned, dialect)
    for number, (a, b) in enumerate(zip(lines, planned, strict=False), start=1):
        if a != b:
            raise ProgramError(
                f"{path}: line {number} reads {a[:100]!r} where the recorded case gives {b[:100]!r}; "
                "do not run it"
            )
    if len(lines) != len(planned):
        raise ProgramError(
            f"{path}: {len(lines):,} lines where the recorded case gives {len(planned):,}; do not run it"
        )
    moves = dialects.read(lines, dialect, meta["controller"]["g93_f"])
    record = simulate_moves(case, specs, moves, progress)
    record = checked_pv(path, {**meta, "pv_nm": meta["pv_nm_as_written"]}, record, pv_tolerance_nm)
    record.update(dialect=dialect, cube_pv_nm=float(meta["pv_nm"]), checksum=f"0x{crc:08x}")
    return record


def _json(value: Any) -> str:
    return dumps_json(value, sort_keys=True)


def stand_in_case(surface: str, machine: str, cutting: str, compensation: str = "exact") -> Case:
    """The case a program from elsewhere is simulated as: its surface and entries, a spiral
    request whose program the file's moves replace."""
    from ftsweep.engine.case import program_request

    try:
        return Case(
            surface=surface,
            machine=machine,
            cutting=cutting,
            compensation=compensation,
            layout=program_request(kind="spiral", points_per_rev=16),
        )
    except ValueError as exc:
        raise CaseError(str(exc)) from None


def default_dialect(machine: Any) -> str:
    """The dialect a machine's programs are exported in by default (its controller's)."""
    return "text" if machine.controller is None else str(machine.controller.dialect)


def dialect_format() -> Any:
    """The file format of dialect programs (:class:`ftsweep.exports.files.FileFormat`)."""
    from ftsweep.exports.files import FileFormat, pv_lines

    def exported(out: Path, meta: dict[str, Any]) -> list[str]:
        return [
            f"program      {out} ({meta['dialect']}, {meta['n_points']:,} points, "
            f"CRC-32 0x{meta['crc32']:08x}; "
            f"P-V as written {meta['pv_nm_as_written']:.2f} nm)"
        ]

    def verified(record: dict[str, Any]) -> list[str]:
        return [
            f"checksum     {record['checksum']} (every other line) ok; sidecar and file hashes ok",
            f"program      spiral in {record['dialect']}: {record['n_points']:,} points, "
            "every line as re-planned",
            *pv_lines(record, "the program as the controller reads it"),
            f"cube         P-V {record['cube_pv_nm']:.2f} nm before rounding to the controller's decimals",
        ]

    def export_fn(*args: Any, name: Optional[str] = None) -> dict[str, Any]:
        raise ProgramError("dialect programs are written by export --dialect")

    return FileFormat("dialect program", None, export_fn, verify, exported, verified)


def _peaks(moves: Moves) -> dict[str, float]:
    """Peak X and Z speeds [mm/s] and accelerations [m/s²] of a program's segments (speeds
    per segment, accelerations between consecutive segments' speeds)."""
    t = np.asarray(moves.seconds, dtype=np.float64)
    out: dict[str, float] = {}
    for axis, values in (("x", moves.x_mm), ("z", moves.z_mm)):
        v = np.diff(values) / t
        a = np.diff(v) / (0.5 * (t[:-1] + t[1:])) * 1e-3 if v.size > 1 else np.zeros(0)
        out[f"{axis}_speed_mm_s"] = float(np.max(np.abs(v), initial=0.0))
        out[f"{axis}_accel_m_s2"] = float(np.max(np.abs(a), initial=0.0))
    return out


def _against(peaks: dict[str, float], machine: Any) -> dict[str, Any]:
    """The peaks beside the machine's limits (its X-Z axes, or the servo's acceleration)."""
    axes = machine.axes
    limits = {
        "x_speed_mm_s": axes.x_feed_mm_s if axes else None,
        "x_accel_m_s2": axes.x_accel_m_s2 if axes else None,
        "z_speed_mm_s": axes.z_velocity_mm_s if axes else None,
        "z_accel_m_s2": axes.z_accel_m_s2 if axes else machine.peak_accel_m_s2,
    }
    return {
        k: {"peak": v, "limit": limits[k], "ok": limits[k] is None or v <= limits[k]}
        for k, v in peaks.items()
    }


def predict_program(
    path: Path,
    surface: Optional[str],
    machine: Optional[str],
    cutting: Optional[str],
    g93_f: str = "inverse_minutes",
    progress: Any = None,
) -> dict[str, Any]:
    """Read a path program in any supported dialect (ftsweep's or another CAM's), summarise
    it (points, revolutions, feed per revolution, spindle speed, peak axis speeds and
    accelerations against the machine's limits) and, with a ``surface``, predict the form
    error it leaves through the one simulator (docs/controllers.md)."""
    from ftsweep.inputs import catalogs

    lines = read_lines(Path(path), strict=False)
    first = lines[0] if lines else ""
    dialect = dialects.detect(lines)
    if is_dialect_file(first):
        dialect = (dialects.comment_text(dialect, first) or "").split("dialect ", 1)[-1].split(":", 1)[0]
    moves = dialects.read(lines, dialect, g93_f)
    info: dict[str, Any] = {"program": str(path), "dialect": dialect, "interpolation": moves.interpolation}
    info.update(dialects.summary(moves))
    turns = (moves.c_deg[-1] - moves.c_deg[0]) / 360.0
    info["spindle_rpm"] = float(turns / info["machining_s"] * 60.0) if info["machining_s"] > 0 else math.nan
    machine = (
        machine
        or {"linear": "sts-moore", "pvt": "sts-pmac-pvt", "spline1": "sts-pmac-spline"}[moves.interpolation]
    )
    info["machine"] = machine
    info["axes"] = _against(_peaks(moves), catalogs.entry("machines", machine))
    info["notes"] = moves.notes
    if surface is None:
        return info
    case = stand_in_case(surface, machine, cutting or "reference")
    record = simulate_moves(case, None, moves, progress)
    info.update({k: record[k] for k in ("pv_nm", "rms_nm", "pv_interp_nm", "nose_radius_um", "feed_um")})
    info["surface"] = surface
    info["record"] = record
    return info
