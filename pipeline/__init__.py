"""ftsweep orchestration: catalogs, case specs, the case runner and the CLI.

Citations in docstrings, messages and exported headers: "model §N, eq. (k)" is section N and
equation k of "The model" in the project's README.md; "[n]" is reference n listed there.

Importing ftsweep is light: the ``ds.ftsweep`` accessor (:mod:`ftsweep.accessor`) is registered
with xarray at once if xarray is loaded, else the moment it is, so that ``import ftsweep`` in
either order with ``import xarray`` gives the accessor while the command line, which may not
need xarray at all, does not pay for loading it.
"""

from __future__ import annotations

import importlib.abc
import importlib.util
import sys
from collections.abc import Sequence
from types import ModuleType
from typing import Any, Optional

__version__ = "0.1.0"


def _register_accessor() -> None:
    from ftsweep import accessor  # noqa: F401  (registers ds.ftsweep)


class _AfterXarray(importlib.abc.MetaPathFinder):
    """Registers the accessor once xarray has been imported, wherever that import happens."""

    def find_spec(
        self, fullname: str, path: Optional[Sequence[str]], target: Optional[ModuleType] = None
    ) -> Any:
        if fullname != "xarray":
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec("xarray")
        if spec is None or spec.loader is None:
            return spec
        load = spec.loader.exec_module

        def exec_module(module: ModuleType) -> None:
            load(module)
            _register_accessor()

        spec.loader.exec_module = exec_module  # type: ignore[method-assign]
        return spec


if "xarray" in sys.modules:
    _register_accessor()
elif not any(isinstance(f, _AfterXarray) for f in sys.meta_path):
    sys.meta_path.insert(0, _AfterXarray())
