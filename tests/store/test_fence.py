"""A cube's writer paused or killed at its write points in turn (tests/support/faults.py): on a local
folder and on memory:// (object storage's semantics in one process), the cube ends equal to a
clean run's, bit for bit, and a writer whose lease was taken over writes nothing that lands
and stops with LeaseLost (exit status 75 on the command line)."""

from __future__ import annotations

import pytest
from support.faults import SPEC, check_every_point

# about 3 minutes on 2 cores: the quick command leaves them to the full one
pytestmark = pytest.mark.slow


@pytest.mark.parametrize("fault", ["pause", "kill"])
def test_a_local_cube_survives_a_fault_at_each_write_point(fault, tmp_path, catalog_dir, monkeypatch):
    checked = check_every_point(
        SPEC, lambda at: str(tmp_path / f"c{at}.zarr"), tmp_path, catalog_dir, monkeypatch, fault
    )
    assert checked == 2 * (2 * 4 + 1)  # two merges: four blocks before and after, the commit


@pytest.mark.parametrize("fault", ["pause", "kill"])
def test_a_cube_on_object_storage_survives_a_fault_at_each_write_point(
    fault, tmp_path, catalog_dir, monkeypatch
):
    base = f"memory://ftsweep-fence/{tmp_path.name}-{fault}"
    checked = check_every_point(
        SPEC, lambda at: f"{base}/c{at}.zarr", tmp_path, catalog_dir, monkeypatch, fault
    )
    assert checked == 2 * (4 * 4 + 1)  # each block's put besides
