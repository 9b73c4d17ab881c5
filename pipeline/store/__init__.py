"""Where results live: storage places (local or fsspec), Zarr cubes, case logs, the writer's lock,
and atomic small-file writes.
"""

from __future__ import annotations

from ftsweep.stages import face

# the public names, each loaded from its module on first use (importing the face loads none)
_EXPORTS = {
    "CubeError": "cube",
    "CubeWriter": "cube",
    "Lease": "lock",
    "LeaseLost": "lock",
    "LockError": "lock",
    "PathLike": "storage",
    "Place": "storage",
    "StorageError": "storage",
    "cube_lock": "lock",
    "open_dataset": "cube",
    "place": "storage",
    "read_sidecar": "io",
    "sidecar_path": "io",
    "write_texts_atomic": "io",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = face(__name__, _EXPORTS)
