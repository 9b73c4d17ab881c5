"""The controller header: a ring or mesh table (layered or not) as a C header ([1], model
§2-§4), exported from a cube's case (:mod:`ftsweep.kinds.table.verify` reads it back).

:func:`export_header` writes the chosen case's control table as fixed-point integers (unit
and type from the machine catalog) in the order the controller indexes them,
``table[i][j]`` with i the ring (ρ = origin0 + i·pitch0) or x index and j the angle
(θ = origin1 + j·pitch1, periodic) or y index, plus macros for everything needed to use
and check it and a CRC-32 of the table. A JSON sidecar repeats the metadata with the full
case spec and the catalog entries used.
"""

from __future__ import annotations

import hashlib
import re
import time
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from ftsweep.engine.case import Case
from ftsweep.engine.planning import control_table
from ftsweep.errors import ExportError
from ftsweep.exports.files import layer_schedule, recorded_entries, sidecar_digest
from ftsweep.inputs.case_entries import Entries
from ftsweep.kinds.table.layout import build_layout
from ftsweep.simulate import resolve_case
from ftsweep.store.io import check_sidecar_text, dumps_json, write_texts_atomic
from ftsweep.version import __version__

INT_RANGE = {"int16": (-(2**15), 2**15 - 1), "int32": (-(2**31), 2**31 - 1)}
LE_DTYPE = {"int16": "<i2", "int32": "<i4"}


C_KEYWORDS = frozenset(
    "auto break case char const continue default do double else enum extern float for goto if inline int "
    "long register restrict return short signed sizeof static struct switch typedef union unsigned void "
    "volatile while _Bool _Complex _Imaginary".split()
)


def c_identifier(text: str) -> str:
    """A valid C identifier from any name: other characters become ``_``; a leading digit, a
    keyword or an empty name gets a prefix; reserved leading underscores are avoided."""
    ident = re.sub(r"[^0-9A-Za-z_]", "_", text).strip("_")
    if not ident or ident[0].isdigit() or ident in C_KEYWORDS:
        ident = "fts_" + ident
    return ident


def c_string(text: str) -> str:
    """A C string literal of ``text``: quotes, backslashes and non-printable or non-ASCII
    bytes escaped (octal, which cannot swallow a following hex digit)."""
    out = []
    for byte in text.encode("utf-8"):
        ch = chr(byte)
        if ch in '"\\':
            out.append("\\" + ch)
        elif 32 <= byte < 127:
            out.append(ch)
        else:
            out.append(f"\\{byte:03o}")
    return '"' + "".join(out) + '"'


def quantise(table_um: np.ndarray, unit_nm: float, int_type: str) -> np.ndarray:
    """Fixed-point integers of a table [µm] in steps of ``unit_nm`` [nm]; refuses non-finite
    values and overflow."""
    table_um = np.asarray(table_um, dtype=np.float64)
    bad = ~np.isfinite(table_um)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise ExportError(
            f"the table holds {int(bad.sum()):,} non-finite values (first at [{i}, {j}]); nothing exported"
        )
    q = np.rint(table_um * 1e3 / unit_nm)
    lo, hi = INT_RANGE[int_type]
    if q.min() < lo or q.max() > hi:
        raise ExportError(
            f"table values {q.min():.0f}..{q.max():.0f} (units of {unit_nm} nm) do not fit {int_type}; "
            "use a coarser table_unit_nm or int32 in the machine catalog"
        )
    return q.astype(LE_DTYPE[int_type])


CHECKSUM_MACRO = "CHECKSUM_CRC32"


def checksum(macros: list[tuple[str, str]], ints: np.ndarray, int_type: str) -> int:
    """CRC-32 of everything the controller uses: each macro (name without the prefix, and its
    value exactly as written, ``NAME=VALUE`` lines in header order, the checksum macro itself
    left out) followed by the table as little-endian integers in row-major (controller) order."""
    text = "".join(f"{name}={value}\n" for name, value in macros if name != CHECKSUM_MACRO)
    crc = zlib.crc32(text.encode("utf-8"))
    return zlib.crc32(np.ascontiguousarray(ints, dtype=LE_DTYPE[int_type]).tobytes(), crc) & 0xFFFFFFFF


def _c_list(values: Any) -> str:
    return "{" + ", ".join(repr(float(v)) if isinstance(v, float) else str(v) for v in values) + "}"


def layer_macros(schedule: dict[str, Any]) -> list[tuple[str, str, str]]:
    """Macros of a layered header: the schedule of :func:`layer_schedule` (initializer lists
    usable as ``static const double x[] = PREFIX_LAYER_OFFSETS_UM;``)."""
    phis = [v for pair in schedule["segment_phi_deg"] for v in pair]
    return [
        ("N_LAYERS", str(schedule["n_layers"]), "layers, cut in this order"),
        ("LAYER_ZONE_UM", repr(schedule["zone_um"]), "height of a stroke zone [um]"),
        ("LAYER_MARGIN_UM", repr(schedule["margin_um"]), "travel kept free, half at each end [um]"),
        ("RHO0_UM", repr(schedule["rho0_um"]), "spiral start radius [um]"),
        ("LAYER_OFFSETS_UM", _c_list(schedule["offset_um"]), "Z offset of each layer: W = table - offset"),
        ("LAYER_START_RADII_UM", _c_list(schedule["start_radius_um"]), "radius of each layer's first cut"),
        ("N_SEGMENTS", str(len(schedule["segment_layer"])), ""),
        ("SEGMENT_LAYERS", _c_list(schedule["segment_layer"]), "layer of each segment"),
        ("SEGMENT_PHI_DEG", _c_list(phis), "start, end of each segment [deg of spindle from the edge]"),
    ]


def header_macros(meta: dict[str, Any], shape: tuple[int, int], int_type: str) -> list[tuple[str, str, str]]:
    """(name without prefix, value as written, comment) of every macro of the header."""
    kind = meta["layout"]
    rows, cols = shape
    layered = layer_macros(meta["layers"]) if meta.get("layers") else []
    return [
        ("LAYOUT_KIND", c_string(kind), ""),
        ("LAYOUT_IS_RING", str(1 if kind == "ring" else 0), ""),
        ("ROWS", str(rows), ""),
        ("COLS", str(cols), ""),
        ("N_POINTS", f"{rows * cols}L", ""),
        ("PITCH0", repr(meta["pitch"][0]), "drho [um]" if kind == "ring" else "dx [um]"),
        ("PITCH1", repr(meta["pitch"][1]), "dtheta [deg]" if kind == "ring" else "dy [um]"),
        ("ORIGIN0", repr(meta["origin"][0]), ""),
        ("ORIGIN1", repr(meta["origin"][1]), ""),
        ("UNIT_NM", repr(meta["unit_nm"]), ""),
        ("INT_TYPE", c_string(int_type), ""),
        ("SURFACE", c_string(meta["surface"]), ""),
        ("COMPENSATION", c_string(meta["compensation"]), ""),
        ("FEED_UM", repr(meta["feed_um"]), ""),
        ("NOSE_RADIUS_UM", repr(meta["nose_radius_um"]), ""),
        ("SPINDLE_RPM", repr(meta["spindle_rpm"]), ""),
        ("PREDICTED_PV_NM", repr(meta["pv_nm"]), ""),
        ("GENERATOR", c_string(meta["generator"]), ""),
        *layered,
        (
            "SIDECAR_SHA256",
            c_string(meta["sidecar_sha256"]),
            "of the sidecar without crc32, header_sha256, created",
        ),
    ]


# what the table's values are, citing the README's model (ASCII: the header is C source)
COMPENSATION_CITED = {
    "exact": "tool-nose compensated commands, section 4 eq. 3",
    "slope": "slope-approximated compensated commands, section 4 eq. 4",
    "none": "surface heights without nose compensation, section 4",
}


LAYERED_NOTE = [
    " * Layered ([3], ftsweep docs/kinds.md 'Layered trajectories'): the part is cut in",
    " * N_LAYERS layers, in order. In layer k the Z axis sets the workpiece at",
    " * LAYER_OFFSETS_UM[k] and the FTS outputs W = table - LAYER_OFFSETS_UM[k] (within its",
    " * travel); the layer cuts the spiral only on its segments, from SEGMENT_PHI_DEG[2s] to",
    " * SEGMENT_PHI_DEG[2s+1] (spindle angle accumulated from the edge: C = phi mod 360,",
    " * X = RHO0_UM - FEED_UM*phi/360), stopping the spindle and lifting the tool between them.",
]


def render_header(name: str, meta: dict[str, Any], ints: np.ndarray, int_type: str) -> tuple[str, int]:
    """The C header text (C99) and its CRC-32 (:func:`checksum`)."""
    ident = c_identifier(name)
    macro = ident.upper()
    table = ident.lower() + "_table"
    rows, cols = ints.shape
    kind = meta["layout"]
    axes = ("rho [um]", "theta [deg], periodic") if kind == "ring" else ("x [um]", "y [um]")
    macros = header_macros(meta, (rows, cols), int_type)
    crc = checksum([(n, v) for n, v, _ in macros], ints, int_type)
    lines = [
        f"/* Controller table generated by {meta['generator']}.",
        f" * Do not edit: {macro}_{CHECKSUM_MACRO} covers every macro below (NAME=VALUE lines)",
        " * and the table.",
        f" * {table}[i][j] holds the W command at {axes[0]} = {macro}_ORIGIN0 + i*{macro}_PITCH0,",
        f" * {axes[1]} = {macro}_ORIGIN1 + j*{macro}_PITCH1, in units of {macro}_UNIT_NM nm.",
        f" * Values are {COMPENSATION_CITED[meta['compensation']]} (ftsweep README, 'The model'),",
        " * interpolated bilinearly by the FTS controller (section 3, eq. 2; the method of",
        " * reference [1] there).",
        *(LAYERED_NOTE if meta.get("layers") else []),
        " */",
        f"#ifndef {macro}_H",
        f"#define {macro}_H",
        "",
        "#include <stdint.h>",
        "",
    ]
    for n, v, comment in macros:
        lines.append(f"#define {macro}_{n} {v}" + (f" /* {comment} */" if comment else ""))
    lines += [
        f"#define {macro}_{CHECKSUM_MACRO} 0x{crc:08x}UL",
        "",
        f"static const {int_type}_t {table}[{macro}_ROWS][{macro}_COLS] = {{",
    ]
    # tolist() makes Python ints in C: the same digits as str(int(v)) a value at a time, 4× faster
    for i, row in enumerate(np.asarray(ints, dtype=np.int64).tolist()):
        values = ", ".join(map(str, row))
        lines.append(f"    {{{values}}}{',' if i < rows - 1 else ''}")
    lines += ["};", "", f"#endif /* {macro}_H */", ""]
    return "\n".join(lines), crc


def header_meta(
    case: Case, specs: Entries, layout: Any, pv_nm: float, created: str, generator: str
) -> dict[str, Any]:
    """What a header states about a table case (everything but the layer schedule and the
    sidecar's digest): export writes it and verify re-derives it from the recorded case."""
    _, machine, cutting = specs
    return {
        "generator": generator,
        "created": created,
        "layout": layout.kind,
        "shape": list(layout.shape),
        "pitch": list(layout.pitch),
        "origin": list(layout.origin),
        "unit_nm": machine.table_unit_nm,
        "int_type": machine.table_int_type,
        "surface": case.surface,
        "compensation": case.compensation,
        "feed_um": case.feed_of(cutting),
        "nose_radius_um": case.nose_radius_of(cutting),
        "spindle_rpm": cutting.spindle_rpm,
        "pv_nm": pv_nm,
    }


def planned_ints(case: Case, specs: Entries, layout: Any) -> np.ndarray:
    """The table [table units] a table case plans: compensated commands (model §4) quantised
    to the machine's fixed-point unit."""
    surface, machine, cutting = specs
    table_um, _ = control_table(case, layout, surface, case.nose_radius_of(cutting))
    return quantise(table_um, machine.table_unit_nm, machine.table_int_type)


def export_header(
    out: Path,
    side: Path,
    case: Case,
    specs: Entries,
    chosen: dict[str, Any],
    extra: dict[str, Any],
    name: str | None = None,
) -> dict[str, Any]:
    """Compute the chosen table case's table from its recorded spec and catalog entries and
    write the header (C identifiers prefixed by ``name``, default the file's stem) and its
    sidecar atomically. Returns the sidecar's content."""
    surface, machine, _ = specs
    layout = build_layout(surface, case.layout)
    if layout.n_points != chosen["n_points"]:
        raise ExportError(f"the cube says {chosen['n_points']} points but the spec gives {layout.n_points}")
    ints = planned_ints(case, specs, layout)
    meta = header_meta(
        case, specs, layout, chosen["pv_nm"], time.strftime("%Y-%m-%dT%H:%M:%S%z"), f"ftsweep {__version__}"
    )
    # the schedule of the table as stored: verify plans it again from the same integers
    meta["layers"] = layer_schedule(resolve_case(case, specs=specs), ints * machine.table_unit_nm * 1e-3)
    sidecar = dict(meta)
    sidecar.update(
        header=out.name,
        **extra,
        selection=chosen,
        case=case.model_dump(mode="json"),
        catalog_entries=recorded_entries(specs),
    )
    check_sidecar_text(sidecar, side, "nothing exported")
    # the header names the sidecar's hash and the sidecar the header's: editing either one,
    # or re-forging the table with its CRC, is caught by verify
    meta["sidecar_sha256"] = sidecar_digest(sidecar)
    text, crc = render_header(name or out.stem, meta, ints, machine.table_int_type)
    sidecar.update(crc32=crc, header_sha256=hashlib.sha256(text.encode("utf-8")).hexdigest())
    side_text = dumps_json(sidecar, indent=2) + "\n"
    write_texts_atomic({side: side_text, out: text})
    return sidecar
