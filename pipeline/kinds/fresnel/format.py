"""The file format of Fresnel programs ([2]): how ``export`` and ``verify`` reach the study's
writer and checker (:mod:`ftsweep.kinds.fresnel.study`)."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

from ftsweep.engine.contract import FileFormat
from ftsweep.exports.files import Progress, pv_lines


@functools.cache
def fresnel_format() -> FileFormat:
    """The Fresnel program's file format ([2]): one line t C X Y Z per point, written by
    ``export`` from a cube and by the study (``ftsweep fresnel -o``)."""
    from ftsweep.kinds.fresnel import study as fstudy
    from ftsweep.kinds.fresnel.dialect import dialect_adapter

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
            *pv_lines(record, "the program's lines"),
        ]

    return FileFormat(
        "Fresnel program", fstudy.F_MAGIC, export, verify, exported, verified, dialect_adapter()
    )
