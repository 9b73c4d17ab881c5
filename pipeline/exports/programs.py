"""The path-program file machinery the path kinds share (docs/architecture.md, "Trust"): one
plain-text line per control point under a ``#`` header of units, surface, tool, budgets and
predicted P-V, with a JSON sidecar holding the full case; both written atomically. ``CRC32``
in the header covers every other line of the file; the header names the sidecar's SHA-256
and the sidecar the program's (:mod:`ftsweep.exports.files`). A kind's format
(:mod:`ftsweep.kinds.spiral.format`, :mod:`ftsweep.kinds.dpath.format`) plans the program
again from the recorded case and compares it with every line the machine reads.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ftsweep.engine.contract import FileFormat
from ftsweep.exports.files import pv_lines, read_program_file

__all__ = ["program_format", "read_program"]


def read_program(path: Path, magic: str, columns: str) -> tuple[dict[str, str], np.ndarray]:
    """The header fields and the (N, columns) data of a program file, its CRC checked."""
    doc = read_program_file(path, magic, columns)
    return doc.fields, doc.data


def program_format(
    title: str, magic: str, columns: str, write: Any, check: Any, dialect: Any = None
) -> FileFormat:
    """The :class:`~ftsweep.exports.files.FileFormat` of a path program titled ``title``, whose
    first line starts with ``magic``, written by ``write`` and verified by ``check``."""

    def exported(out: Path, meta: dict[str, Any]) -> list[str]:
        return [f"program      {out} ({meta['n_points']:,} lines {columns}, CRC-32 0x{meta['crc32']:08x})"]

    def verified(record: dict[str, Any]) -> list[str]:
        return [
            f"checksum     {record['checksum']} (every line) ok; sidecar and file hashes ok",
            f"program      {record['layout']}: {record['n_points']:,} points, every line as re-planned",
            *pv_lines(record, "the program's lines"),
        ]

    def export(*args: Any, name: str | None = None) -> dict[str, Any]:
        return dict(write(*args))  # a program's lines need no C identifiers

    return FileFormat(title, magic, export, check, exported, verified, dialect)
