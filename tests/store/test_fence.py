"""The one home of the write-point faults (tests/support/faults.py): a cube's writer paused or
killed at its write points in turn, on a local folder, on memory:// (object storage's semantics
in one process) and on a moto S3 server, and at write points hypothesis draws; the cube ends
equal to a clean run's, bit for bit, and a writer whose lease was taken over writes nothing
that lands and stops with LeaseLost (exit status 75 on the command line)."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support.faults import SPEC, check_every_point, check_point, data, points
from support.settings import THOROUGH

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


@pytest.mark.integration  # a moto S3 server
def test_an_s3_cube_survives_a_paused_writer_at_each_write_point(s3, tmp_path, catalog_dir, monkeypatch):
    # the writer paused right before each put of a metric's and the status's blocks
    # (tests/support/faults.py; test_fence.py goes through every key point on memory://, whose
    # conditional writes have S3's semantics) while a second run takes the expired lease and
    # finishes the cube: every put after the takeover fails its condition (If-Match /
    # If-None-Match), the first writer stops with LeaseLost, the cube equals a clean run's;
    # no sleep, so it holds under load. About 15 s a point on moto.
    pytest.importorskip("s3fs")
    pytest.importorskip("moto")
    checked = check_every_point(
        SPEC,
        lambda at: f"{s3}/p{at}.zarr",
        tmp_path,
        catalog_dir,
        monkeypatch,
        "pause",
        puts_of=("pv_nm", "status"),
    )
    assert checked == 2 * 2  # two merges, two blocks


# ------------------------------------------------------------------ pause and kill, anywhere
_CLEAN: dict[str, tuple] = {}  # type: ignore[type-arg]


@pytest.mark.slow  # four faulted runs, about 15 s: with the exhaustive ones of test_fence.py
@settings(
    derandomize=not THOROUGH,
    max_examples=2000 if THOROUGH else 4,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(draw=st.data())
def test_a_merge_survives_a_pause_or_kill_at_a_random_write_point(
    draw, tmp_path_factory, module_catalog_dir, monkeypatch
):
    folder = tmp_path_factory.mktemp("fault")
    spec = folder / "fault.yaml"
    spec.write_text(SPEC)
    if "memory" not in _CLEAN:  # the clean run and its write points, once for every draw
        clean = f"memory://ftsweep-hostile/{folder.name}-clean.zarr"
        every = points(spec, clean, module_catalog_dir, monkeypatch)
        _CLEAN["memory"] = (data(clean), every)
    expected, every = _CLEAN["memory"]
    at = draw.draw(st.integers(1, len(every)), label="write point")
    fault = draw.draw(st.sampled_from(["pause", "kill"]), label="fault")
    url = f"memory://ftsweep-hostile/{folder.name}-{fault}-{at}.zarr"
    check_point(spec, url, module_catalog_dir, (at, fault), monkeypatch, (expected, every))
