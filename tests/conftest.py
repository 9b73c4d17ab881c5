"""Shared fixtures: a private copy of the catalogs with extra test surfaces."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import settings
from support.catalogs import make_catalog_dir
from support.settings import THOROUGH

# the tests open cubes with xarray's own zarr engine too, where ftsweep's backend entry point
# is not looked for: the accessor is registered outright (ftsweep.tools.xarray_backend)
import ftsweep.tools.accessor  # noqa: F401, E402

# numba compiles on a kernel's first call (or loads it from cache); that one-off cost is not
# what a property test measures, so examples get no deadline.
settings.register_profile("ftsweep", deadline=None, max_examples=60)
# HYPOTHESIS_PROFILE=thorough: thousands of fresh examples (the byte-mutation properties of
# exported files draw the same ones every run otherwise, so CI never fails by the draw)
settings.register_profile("thorough", deadline=None, max_examples=2000)
settings.load_profile("thorough" if THOROUGH else "ftsweep")


@pytest.fixture()
def catalog_dir(tmp_path: Path) -> Path:
    """A copy of catalogs/ with the extra test surfaces and machines appended."""
    return make_catalog_dir(tmp_path / "catalogs")


@pytest.fixture(scope="module")
def module_catalog_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """:func:`catalog_dir` shared by the tests of one module (they must not edit it)."""
    return make_catalog_dir(tmp_path_factory.mktemp("catalogs") / "catalogs")
