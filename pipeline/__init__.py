"""ftsweep orchestration: catalogs, case specs, the case runner and the CLI.

This package's source is the repository's ``pipeline/`` folder, installed as ``ftsweep``
(``pipeline/export.py`` is ``ftsweep.tools.export``); the pure numerical stages are ``stages/``,
installed as ``ftsweep.stages``. docs/architecture.md draws the layers.

Citations in docstrings, messages and exported headers: "model §N, eq. (k)" is section N and
equation k of "The model" in the project's README.md; "[n]" is reference n listed there.

Importing ftsweep is light: the ``ds.ftsweep`` accessor (:mod:`ftsweep.tools.accessor`) is
registered at once if xarray is loaded already, otherwise when xarray first opens a dataset
(it loads every backend entry point then, ftsweep's among them:
:mod:`ftsweep.tools.xarray_backend`), so the command line, which may not need xarray at all,
does not pay for loading it. numba's cache of ftsweep's kernels
is the user's cache directory, never the installed package (:mod:`ftsweep.caches`).
"""

from __future__ import annotations

import sys
from typing import Any

from ftsweep.caches import use_user_numba_cache
from ftsweep.version import __version__

# before any kernel of ftsweep.stages is defined: numba caches them in the user's cache
# directory, never inside the installed package (ftsweep.caches)
use_user_numba_cache()

__all__ = ["__version__", "open_cube"]

if "xarray" in sys.modules:
    from ftsweep.tools import accessor  # noqa: F401  (registers ds.ftsweep)


def __getattr__(name: str) -> Any:
    """``ftsweep.open_cube`` (:func:`ftsweep.tools.xarray_backend.open_cube`), imported when first
    asked for: it needs xarray, which ``import ftsweep`` does not load."""
    if name == "open_cube":
        from ftsweep.tools.xarray_backend import open_cube

        return open_cube
    raise AttributeError(f"module 'ftsweep' has no attribute {name!r}")
