"""The conformance suite of :mod:`ftsweep.testing` on the tests' catalog, which every kind's
subclass in tests/kinds/ uses."""

from __future__ import annotations

import pytest

from ftsweep import testing


class KindTests(testing.KindTests):
    """The suite on the tests' catalog (small surfaces, short machines)."""

    @pytest.fixture(scope="class")
    @classmethod
    def catalog_folder(cls, module_catalog_dir):  # type: ignore[no-untyped-def,override]
        return module_catalog_dir
