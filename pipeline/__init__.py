"""ftsweep orchestration: catalogs, case specs, the case runner and the CLI.

This package's source is the repository's ``pipeline/`` folder, installed as ``ftsweep``
(``pipeline/export.py`` is ``ftsweep.tools.export``); the pure numerical stages are ``stages/``,
installed as ``ftsweep.stages``. docs/architecture.md draws the layers.

Citations in docstrings, messages and exported headers: "model §N, eq. (k)" is section N and
equation k of "The model" in the project's README.md; "[n]" is reference n listed there.

Importing ftsweep is light: the ``ds.ftsweep`` accessor (:mod:`ftsweep.tools.accessor`) is registered
with xarray at once if xarray is loaded, else the moment it is, so that ``import ftsweep`` in
either order with ``import xarray`` gives the accessor while the command line, which may not
need xarray at all, does not pay for loading it. numba's cache of ftsweep's kernels is the
user's cache directory, never the installed package (:mod:`ftsweep.caches`).
"""

from __future__ import annotations

import importlib.abc
import importlib.util
import sys
from collections.abc import Callable, Sequence
from types import ModuleType
from typing import Any, Optional

from ftsweep.caches import use_user_numba_cache
from ftsweep.version import __version__

# before any kernel of ftsweep.stages is defined: numba caches them in the user's cache
# directory, never inside the installed package (ftsweep.caches)
use_user_numba_cache()

__all__ = ["__version__"]


def _register_accessor() -> None:
    from ftsweep.tools import accessor  # noqa: F401  (registers ds.ftsweep)


class _AfterImport(importlib.abc.MetaPathFinder):
    """Runs ``action`` once module ``name`` has been imported, wherever that import happens
    (it finds nothing itself: it wraps the loader the other finders give)."""

    def __init__(self, name: str, action: Callable[[], Any]) -> None:
        self.name, self.action = name, action

    def find_spec(
        self, fullname: str, path: Optional[Sequence[str]], target: Optional[ModuleType] = None
    ) -> Any:
        if fullname != self.name:
            return None
        sys.meta_path = [finder for finder in sys.meta_path if finder is not self]
        spec = importlib.util.find_spec(fullname)
        if spec is None or spec.loader is None:
            return spec
        load, action = spec.loader.exec_module, self.action

        def exec_module(module: ModuleType) -> None:
            load(module)
            action()

        spec.loader.exec_module = exec_module  # type: ignore[method-assign]
        return spec


def after_import(name: str, action: Callable[[], Any]) -> None:
    """Run ``action`` now if module ``name`` is imported, else right after its import (once)."""
    if name in sys.modules:
        action()
    elif not any(isinstance(f, _AfterImport) and f.name == name for f in sys.meta_path):
        sys.meta_path.insert(0, _AfterImport(name, action))


after_import("xarray", _register_accessor)
