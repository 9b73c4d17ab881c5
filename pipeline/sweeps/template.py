"""The empty cube of a sweep (docs/architecture.md, "The flow of a case"): every variable at
its fill value, status ``pending``, every case's number, the sweep's axes as coordinates with
their units, the error map's bins, and the provenance attributes (version, git revision, the
resolved spec and the catalog entries used). :mod:`ftsweep.store.cube` writes it once, before any case runs.
"""

from __future__ import annotations

import json
import time
from typing import Any

import numpy as np
import xarray as xr

from ftsweep.store.cube import (
    CASE_NUMBER,
    MAP_VARS,
    SCHEMA_VERSION,
    STATUS_MEANINGS,
    case_variables,
)
from ftsweep.sweeps.spec import SweepSpec, axis_attrs, axis_counts, coordinates
from ftsweep.version import __version__, git_revision

__all__ = ["counted", "template"]


def counted(axis: str, values: np.ndarray, kind: str) -> np.ndarray:
    """An axis of counts (target points, points per revolution, ...) as integers when every
    value is whole, so a cube's ``points`` reads 950000, not 9.5e+05; else as given."""
    if axis_counts(axis, kind) and values.dtype.kind == "f" and np.all(values == np.round(values)):
        return values.astype(np.int64)
    return values


def template(spec: SweepSpec, name: str, catalog_entries: dict[str, Any]) -> xr.Dataset:
    """The empty cube of a sweep: variables at fill values, status pending, provenance attrs."""
    coords = coordinates(spec)
    dims = tuple(coords)
    shape = tuple(v.size for v in coords.values())
    assert spec.layout is not None
    data = case_variables(dims, shape, spec.layout)
    # numbered in C order as the cube is made; growth keeps them and numbers new cases after
    data[CASE_NUMBER] = (
        dims,
        np.arange(int(np.prod(shape)), dtype=np.int64).reshape(shape),
        {
            "units": "1",
            "long_name": "case number: given as the case entered the cube, kept as the cube grows",
        },
    )
    coord_vars = {k: (k, counted(k, v, spec.layout), axis_attrs(k, spec.layout)) for k, v in coords.items()}
    bins = spec.resolution.error_map_bins
    if bins:
        from pydantic import TypeAdapter

        from ftsweep.engine.record import ErrorMap
        from ftsweep.inputs.catalogs import aperture_of, surface_spec

        surface = TypeAdapter(surface_spec()).validate_python(catalog_entries["surface"][spec.surface])
        centres = ErrorMap.over(aperture_of(surface), bins).centres_um()
        for axis in ("map_x", "map_y"):
            coord_vars[axis] = (
                axis,
                centres,
                {"units": "um", "long_name": f"{axis[-1]} of the error-map bin centre"},
            )
        for var, what in MAP_VARS.items():
            data[var] = (
                (*dims, "map_y", "map_x"),
                np.full((*shape, bins, bins), np.nan),
                {"units": "nm", "long_name": what},
            )
    ds = xr.Dataset(data, coords=coord_vars)
    ds.attrs.update(
        ftsweep_version=__version__,
        git_revision=git_revision(),
        sweep_name=name,
        sweep_spec=json.dumps(spec.model_dump(mode="json"), sort_keys=True),
        sweep_spec_hash=spec.spec_hash(),
        catalog_entries=json.dumps(catalog_entries, sort_keys=True),
        layout_method=str(spec.layout),
        ftsweep_cube_schema=SCHEMA_VERSION,
        surface=spec.surface,
        created=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        status_meanings=STATUS_MEANINGS,
    )
    return ds
