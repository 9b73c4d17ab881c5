"""Forging as an attacker with ftsweep's own code would: edit what an exported file or its
sidecar says, then re-make every digest, CRC and hash, so only re-planning, a catalog or a
signature can tell."""

from __future__ import annotations

import hashlib
import json
import re
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from hypothesis import strategies as st

from ftsweep.exports.files import CRC_LINE, crc_of, sidecar_digest
from ftsweep.kinds.table.header import CHECKSUM_MACRO, checksum, render_header
from ftsweep.kinds.table.verify import read_header
from ftsweep.tools.export import ExportError


def forge_header_from_sidecar(header: Path, edit, cells=None) -> str:  # type: ignore[no-untyped-def]
    """Edit the sidecar, then re-make the header from it with ftsweep's own renderer and
    re-make every digest, CRC and hash: what an attacker with the project's code can do."""
    side = header.with_name(header.name + ".json")
    meta = json.loads(side.read_text())
    edit(meta)
    macros, ints = read_header(header)
    ints = ints if cells is None else cells(ints)  # the table too, when given
    rendered = dict(meta, sidecar_sha256=sidecar_digest(meta))
    text, crc = render_header(header.stem, rendered, ints, meta["int_type"])
    meta.update(crc32=crc, header_sha256=hashlib.sha256(text.encode()).hexdigest())
    header.write_text(text)
    side.write_text(json.dumps(meta, indent=2))
    return text


def forge_header_text(header: Path, text: str) -> None:
    """Write ``text`` as the header, with the CRC macro re-made from what C reads of it
    (when C reads it at all) and the sidecar's CRC and header hash re-made."""
    header.write_text(text)
    try:
        macros, ints = read_header(header)
    except ExportError:
        crc = None
    else:
        crc = checksum(macros, ints, json.loads(dict(macros)["INT_TYPE"]))
        text = re.sub(rf"(_{CHECKSUM_MACRO}) 0x[0-9a-f]+UL", rf"\g<1> 0x{crc:08x}UL", text)
        header.write_text(text)
    side = header.with_name(header.name + ".json")
    meta = json.loads(side.read_text())
    meta.update(header_sha256=hashlib.sha256(text.encode()).hexdigest(), **({"crc32": crc} if crc else {}))
    side.write_text(json.dumps(meta, indent=2))


def forge_program(path: Path, edit, lines=None) -> None:  # type: ignore[no-untyped-def]
    """Edit a program's sidecar, re-render the header rows that carry the edited text (and
    its lines by ``lines(rows)``, when given), and re-make the sidecar digest line, the CRC
    line and the program hash."""
    side = path.with_name(path.name + ".json")
    meta = json.loads(side.read_text())
    old = dict(meta)
    edit(meta)
    text = path.read_bytes().decode()
    for key in ("created", "generator"):
        text = text.replace(str(old[key]), str(meta[key]), 1)
    rows = text.split("\n")
    rows = [
        f"# sidecar: {side.name} sha256 {sidecar_digest(meta, ('program', 'program_sha256', 'crc32'))}"
        if r.startswith("# sidecar:")
        else r
        for r in rows
    ]
    rows = rows if lines is None else lines(rows)
    at = next(i for i, r in enumerate(rows) if r.startswith("# CRC32:"))
    rows[at] = CRC_LINE.format(crc_of(rows[:at] + rows[at + 1 : -1]))
    data = "\n".join(rows).encode()
    path.write_bytes(data)
    meta.update(program_sha256=hashlib.sha256(data).hexdigest(), crc32=int(rows[at].split()[2], 16))
    side.write_text(json.dumps(meta, indent=2))


def mutated_copy(data, original: Path, alphabet, factory) -> tuple[bytes, bytes, Path]:  # type: ignore[no-untyped-def]
    """An exported file with one byte inserted, deleted or replaced (drawn from ``alphabet``),
    copied with its sidecar into a folder of its own: (original bytes, mutated bytes, copy)."""
    text = original.read_bytes()
    pos = data.draw(st.integers(0, len(text) - 1))
    op = data.draw(st.sampled_from(["insert", "delete", "replace"]))
    byte = data.draw(alphabet)
    mutated = text[:pos] + (byte if op != "delete" else b"") + text[pos + (op != "insert") :]
    folder = factory.mktemp("mutated")
    copy = folder / original.name
    copy.write_bytes(mutated)
    shutil.copy(
        original.with_name(original.name + ".json"), folder / original.with_name(original.name + ".json").name
    )
    return text, mutated, copy


@contextmanager
def entered_in_ledger(path: Path) -> Iterator[None]:
    """Within the block, ``path``'s current bytes are the latest export of its name in its
    cube's ledger, as a forger who can write the cube could make them: what the ledger then
    cannot tell, the checks after it (re-planning, re-simulation, a catalog or a signature)
    must. The entry is taken out again at the block's end (the cube is shared by tests)."""
    from ftsweep.store import ledger
    from ftsweep.store.storage import place

    side = path.with_name(path.name + ".json")
    at = place(json.loads(side.read_text())["cube"])
    sequence = ledger.next_sequence(at, path.name)
    entry = {
        "sha256": hashlib.sha256(path.read_bytes()).hexdigest(),
        "sidecar_sha256": hashlib.sha256(side.read_bytes()).hexdigest(),
        "created": "forged",
    }
    ledger.record(at, path.name, sequence, entry)
    try:
        yield
    finally:
        at.remove(f"{ledger.LEDGER}/{path.name}/{sequence:08d}.json")
