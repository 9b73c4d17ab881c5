"""xarray's ``engine="ftsweep"``: a result cube opened as xarray opens any dataset, checked
first, with the ``ds.ftsweep`` accessor (:mod:`ftsweep.tools.accessor`) registered.

xarray finds backends other than its own through the entry points of group
``xarray.backends``, loaded when it first looks for one (an ``open_dataset`` that names
``engine="ftsweep"`` or guesses its engine), so the accessor is there by the time a cube is
opened so, whichever of xarray and ftsweep was imported first, while ``import ftsweep``
itself stays light (the command line never needs xarray for ``--help``). ``xr.open_zarr``
takes xarray's own zarr engine without looking: after ``import ftsweep`` *then* ``import
xarray``, open with :func:`open_cube` (``ftsweep.open_cube``) or the engine::

    import ftsweep, xarray as xr
    ds = ftsweep.open_cube("outputs/sinewave-ring.zarr")  # or xr.open_dataset(..., engine="ftsweep")
    ds.ftsweep.best(budget_points=950_000)
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from typing import Any, Optional

import xarray as xr
from xarray.backends import BackendEntrypoint

from ftsweep.tools import accessor  # noqa: F401  (registers ds.ftsweep)


class FtsweepBackend(BackendEntrypoint):
    """Opens an ftsweep result cube (a folder or URL) lazily, after checking it is one this
    version reads (:func:`ftsweep.store.cube.read_attrs`: an unfinished template or an older
    layout is refused with the command that recomputes it)."""

    description = "ftsweep result cubes (Zarr v3), checked, with the ds.ftsweep accessor"
    url = "docs/guide.md#the-cube-in-a-notebook"
    open_dataset_parameters = ("filename_or_obj", "drop_variables")

    def open_dataset(  # type: ignore[override]
        self,
        filename_or_obj: str | os.PathLike[str],
        *,
        drop_variables: Optional[str | Iterable[str]] = None,
    ) -> xr.Dataset:
        from ftsweep.store import cube

        cube.read_attrs(os.fspath(filename_or_obj))
        ds = cube.open_dataset(os.fspath(filename_or_obj))
        return ds.drop_vars(drop_variables) if drop_variables is not None else ds

    def guess_can_open(self, filename_or_obj: Any) -> bool:
        """Never guessed: a cube is a Zarr store, which xarray's own zarr engine opens too;
        ``engine="ftsweep"`` asks for the check."""
        return False


def open_cube(where: str | os.PathLike[str]) -> xr.Dataset:
    """The result cube at ``where`` (a folder or URL) as a lazy :class:`xarray.Dataset`,
    checked as :class:`FtsweepBackend` checks it, with the ``ds.ftsweep`` accessor."""
    return FtsweepBackend().open_dataset(where)
