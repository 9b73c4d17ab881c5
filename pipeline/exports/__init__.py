"""Exported files: one export and one verify for every kind, the sidecar and program-file machinery
they share, and who signed a file.
"""

from __future__ import annotations

from ftsweep.stages import face

# the public names, each loaded from its module on first use (importing the face loads none)
_EXPORTS = {
    "ExportError": "files",
    "ProgramError": "files",
    "check_signature": "origin",
    "program_format": "programs",
    "purpose": "origin",
    "read_program": "programs",
    "sign": "origin",
    "signed": "origin",
    "signing_key": "origin",
    "trusted_keys": "origin",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = face(__name__, _EXPORTS)
