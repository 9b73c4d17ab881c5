"""Where cubes live without a server: memory:// in this process, the
lease lock's rules, and what a store without conditional writes gets."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

from ftsweep.cli.main import main
from ftsweep.store import caselog, cube
from ftsweep.store.lock import Lease, LockError
from ftsweep.store.storage import StorageError, parse_options, place
from ftsweep.sweeps import cases
from ftsweep.sweeps.run import run_sweep
from ftsweep.testing import LeaseTests

SPEC = """
surface: small_sine
layout: ring
axes: {points: [8000, 16000], aspect: [1.0, 4.0]}
"""


def test_a_sweep_into_memory_reads_back_like_a_local_one(tmp_path, catalog_dir):
    spec = tmp_path / "m.yaml"
    spec.write_text(SPEC)
    url = f"memory://ftsweep-tests/{tmp_path.name}/c.zarr"
    report = run_sweep(str(spec), url, scheduler="synchronous", catalog_folder=catalog_dir)
    assert report.done == 4 and str(report.cube) == url
    again = run_sweep(str(spec), url, scheduler="synchronous", catalog_folder=catalog_dir)
    assert again.queued == 0 and again.skipped == 4
    local = tmp_path / "c.zarr"
    run_sweep(str(spec), local, scheduler="synchronous", catalog_folder=catalog_dir)

    def data(where):  # type: ignore[no-untyped-def]
        return cube.open_dataset(where).drop_vars(list(cube.TIMING_VARS)).load()

    xr.testing.assert_equal(data(url), data(local))
    assert not place(url).listing(caselog.LOG) and not place(url + ".lock").exists()


class TestMemoryLease(LeaseTests):
    """The lease conformance suite (:class:`ftsweep.testing.LeaseTests`) on memory://."""

    @pytest.fixture
    def url(self, tmp_path):  # type: ignore[no-untyped-def]
        return f"memory://ftsweep-tests/lease-{tmp_path.name}/c.zarr"


def test_stores_without_conditional_writes_are_refused_for_writing():
    with pytest.raises(LockError, match="cannot lock a cube on gs://"):
        Lease("gs://bucket/c.zarr")


def test_storage_options_parse_json_values_and_refuse_malformed_pairs():
    assert parse_options(("endpoint_url=http://127.0.0.1:9000", "anon=true", "n=3")) == {
        "endpoint_url": "http://127.0.0.1:9000",
        "anon": True,
        "n": 3,
    }
    with pytest.raises(StorageError, match="KEY=VALUE"):
        parse_options(("endpoint_url",))


def test_case_logs_are_merged_once_and_later_runs_win(tmp_path, catalog_dir):
    spec = tmp_path / "m.yaml"
    spec.write_text(SPEC)
    out = tmp_path / "logs.zarr"
    run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    early, late = caselog.CaseLog(out, "20260101T000000-a"), caselog.CaseLog(out, "20260102T000000-b")
    late.write_failed(1, "late", "20260102T000000-b")
    early.write_failed(1, "early", "20260101T000000-a")
    early.write_failed(2, "early", "20260101T000000-a")
    status = caselog.current_status(out).ravel()
    assert status[1] == cube.FAILED and status[2] == cube.FAILED and status[0] == cube.DONE
    assert cube.read_status(out).ravel()[1] == cube.DONE  # nothing merged yet
    assert caselog.merge_logs(out) == 2
    ds = cube.open_dataset(out).load()
    assert ds["message"].values.ravel()[1] == "late" and ds["message"].values.ravel()[2] == "early"
    assert caselog.merge_logs(out) == 0 and not (out / caselog.LOG).exists()
    assert np.sum(cube.read_status(out) == cube.FAILED) == 2


def test_a_cube_in_object_storage_grows_by_copy(tmp_path, catalog_dir):
    """No rename on object storage: the grown cube is copied in, its root metadata last."""
    spec = tmp_path / "m.yaml"
    spec.write_text(SPEC)
    url = f"memory://ftsweep-tests/{tmp_path.name}/grow.zarr"
    run_sweep(str(spec), url, scheduler="synchronous", catalog_folder=catalog_dir)
    spec.write_text(SPEC.replace("[8000, 16000]", "[8000, 12000, 16000]"))
    report = run_sweep(str(spec), url, scheduler="synchronous", catalog_folder=catalog_dir)
    assert report.skipped == 4 and report.done == 2 and "points +1" in report.note
    assert not place(url + ".grow").exists()
    assert (cube.read_status(url) == cube.DONE).all()


def _done_values(out, flat: int) -> dict:  # type: ignore[no-untyped-def,type-arg]
    """The stored values of a done case of a cube, as a worker's log holds them."""
    ds = cube.open_dataset(out).load()
    names = [v for v in ds.data_vars if ds[v].dims == ds["status"].dims and v not in cube.TIMING_VARS]
    out_values = {v: ds[v].values.ravel()[flat] for v in names}
    return {v: x.item() if hasattr(x, "item") else x for v, x in out_values.items()}


def _bomb(values: dict) -> bytes:  # type: ignore[type-arg]
    """A log of one case whose ``message`` column deflates 128 MB of zeros into about 130 KB:
    refused by the sizes its zip directory declares, before anything is unpacked."""
    import io
    import zipfile

    buffer = io.BytesIO()
    good = np.load(io.BytesIO(caselog._encode([(1, values)])))
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name in (n for n in good.files if n != "message.value"):
            with archive.open(f"{name}.npy", "w") as fh:
                np.lib.format.write_array(fh, good[name])
        with archive.open("message.value.npy", "w", force_zip64=True) as fh:
            np.lib.format.write_array_header_1_0(
                fh, {"descr": "<U32000000", "fortran_order": False, "shape": (1,)}
            )
            zeros = bytes(2**24)
            for _ in range(8):
                fh.write(zeros)
    return buffer.getvalue()


@pytest.mark.parametrize(
    ("forge", "reason"),
    [
        (lambda v: v.update(pv_nm=float("nan")), "P-V or RMS is missing or not finite"),
        (lambda v: v.update(pv_nm=0.5), "is not its largest minus its smallest error"),
        (lambda v: v.update(rms_nm=float("inf")), "infinite|not finite"),
        (lambda v: v.update(status=7), "status 7"),
        (lambda v: v.update(feasible=3), "feasible = 3"),
        (lambda v: None, "case index"),  # index -1
        (lambda v: None, "case index"),  # index 10^9
        (lambda v: None, "not a readable log"),  # truncated
        (lambda v: v.update(n_points=float("nan")), "n_points: nan is not a whole number"),
        (lambda v: v.update(n_points=2.5), "n_points: 2.5 is not a whole number"),
        (lambda v: v.update(error_min_nm=float("nan"), error_max_nm=float("nan")), "error_min_nm is nan"),
        (lambda v: v.update(n_points=-4), "n_points = -4 is negative"),
        (lambda v: None, "unpacks to .* bytes, more than a log of this cube can hold"),  # bomb
    ],
    ids=[
        "nan-pv",
        "pv-0.5",
        "inf-rms",
        "status",
        "feasible",
        "index-negative",
        "index-huge",
        "truncated",
        "nan-count",
        "half-count",
        "nan-extremes",
        "negative-count",
        "bomb",
    ],
)
def test_a_bad_worker_log_is_moved_aside_and_its_case_computed_again(
    tmp_path, catalog_dir, forge, reason, request
):
    spec = tmp_path / "m.yaml"
    spec.write_text(SPEC)
    out = tmp_path / "logs.zarr"
    run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    good = _done_values(out, 1)
    cube.CubeWriter(out).write([(1, {"status": cube.PENDING})])  # as if the case had not run
    values = dict(good)
    forge(values)
    flat = {"index-negative": -1, "index-huge": 10**9}.get(request.node.callspec.id, 1)
    data = caselog._encode([(flat, values)])
    if request.node.callspec.id == "truncated":
        data = data[: len(data) // 2]
    if request.node.callspec.id == "bomb":
        data = _bomb(values)
    caselog.place(out).write(f"{caselog.LOG}/20260101T000000-x/abc-000001.npz", data)
    with pytest.warns(UserWarning, match=reason):
        report = run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    assert report.done == 1 and report.skipped == 3  # the case computed again, once
    assert np.isclose(_done_values(out, 1)["pv_nm"], good["pv_nm"], rtol=1e-12)
    kept = caselog.place(out).listing(caselog.REJECTED)
    assert len(kept) == 1 and not caselog.place(out).listing(caselog.LOG)
    again = run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    assert again.done == 0 and again.skipped == 4  # never fails over and over on one file


@pytest.mark.parametrize(
    "url, words",
    [
        ("gs://bucket/c.zarr", "not gs://"),
        ("abfs://box/c.zarr", "not abfs://"),
        ("memory://c.zarr", "cannot reach"),
    ],
)
def test_a_cube_a_sweep_cannot_write_is_a_usage_error(url, words, tmp_path, catalog_dir):
    """Refused before anything runs, with exit 2 (a usage error: a scheduler must not retry),
    saying why: stores without a writer's lock, and memory:// with worker processes."""
    spec = tmp_path / "s.yaml"
    spec.write_text("surface: small_sine\naxes: {points: [8000], aspect: [2.0]}\n")
    res = CliRunner().invoke(
        main, ["sweep", str(spec), "--out", url], env={"FTSWEEP_CATALOGS": str(catalog_dir)}
    )
    assert res.exit_code == 2, res.output
    assert words in res.output and "--out" in res.output
    ok = CliRunner().invoke(
        main,
        ["sweep", str(spec), "--out", "memory://ok.zarr", "--scheduler", "synchronous"],
        env={"FTSWEEP_CATALOGS": str(catalog_dir)},
    )
    assert ok.exit_code == 0, ok.output


def test_a_refusal_a_worker_logs_is_reconsidered_by_retry_failed(tmp_path, catalog_dir):
    # a log may say "refused" for a case its planning does not refuse: --retry-failed computes it
    spec = tmp_path / "m.yaml"
    spec.write_text(SPEC)
    out = tmp_path / "refused.zarr"
    run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    good = _done_values(out, 2)
    cube.CubeWriter(out).write([(2, {"status": cube.PENDING})])
    forged = cube.ended_values(cube.REFUSED, "refused: forged", "x")
    caselog.place(out).write(
        f"{caselog.LOG}/20260101T000000-x/abc-000001.npz", caselog._encode([(2, forged)])
    )
    plain = run_sweep(str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir)
    assert plain.done == 0 and cases.cube_counts(out)["refused"] == 1
    retried = run_sweep(
        str(spec), out, scheduler="synchronous", catalog_folder=catalog_dir, retry_failed=True
    )
    assert retried.done == 1 and cases.cube_counts(out)["done"] == 4
    assert _done_values(out, 2)["pv_nm"] == good["pv_nm"]


def test_logs_a_taken_over_run_writes_after_the_takeover_are_never_read():
    url = "memory://ftsweep-tests/fenced-run/c.zarr"
    first = Lease(url, "first", lease_s=60, run_id="R1")
    first.acquire()
    first._stop.set()  # paused: no renewal
    first._renewer.join()  # type: ignore[union-attr]
    at = place(url)
    at.write(f"{caselog.LOG}/R1/a-000001.npz", b"written before the takeover")
    lock = at.sibling(".lock")
    record = json.loads(lock.read(""))
    lock.write("", json.dumps({**record, "lease_until": 0.0}).encode())  # its term has passed
    second = Lease(url, "second", lease_s=60, run_id="R2", fence_run=lambda run: caselog.fence_run(url, run))
    second.acquire()
    try:
        at.write(f"{caselog.LOG}/R1/b-000001.npz", b"written after the takeover")
        assert second.inherited == {f"{caselog.LOG}/R1/a-000001.npz"}
        usable, dropped = caselog.fenced_out(at.listing(caselog.LOG), second.inherited)
        assert f"{caselog.LOG}/R1/a-000001.npz" in usable and dropped == [f"{caselog.LOG}/R1/b-000001.npz"]
        # a later run reads neither: the fenced run's logs are dropped unread
        assert caselog.fenced_out(at.listing(caselog.LOG))[0] == []
        with pytest.raises(LockError, match="taken over"):
            first.confirm()
    finally:
        second.release()


def test_merges_are_paced_by_their_own_duration(tmp_path, catalog_dir, monkeypatch):
    from ftsweep.sweeps import run

    assert run.merge_interval(0.0) == run.MERGE_EVERY_S
    assert run.merge_interval(0.3) == pytest.approx(0.3 / run.MERGE_SHARE)
    assert run.merge_interval(60.0) == run.MERGE_MAX_S
    # merges of 10 ms each: with no floor and a share of 10⁹ (a pause of 10 ps) the driver
    # merges at every delivery of cases, the last one's after the last task (the executor's
    # finish); with a share of 1/1000 a merge makes the next one wait 10 s, so only the first
    # delivery's (the floor is 0) and the last are left, and every case reaches the blocks
    merges: list[float] = []
    real = run._merge_fenced

    def slow(out, lease):
        merges.append(1.0)
        time.sleep(0.01)
        real(out, lease)

    monkeypatch.setattr(run, "_merge_fenced", slow)
    monkeypatch.setattr(run, "MERGE_EVERY_S", 0.0)
    spec = tmp_path / "m.yaml"
    spec.write_text(SPEC)
    for share in (1e9, 0.001):
        monkeypatch.setattr(run, "MERGE_SHARE", share)
        merges.clear()
        deliveries: list[int] = []
        told = deliveries.append
        run_sweep(
            str(spec),
            tmp_path / f"paced-{share}.zarr",
            scheduler="synchronous",
            catalog_folder=catalog_dir,
            progress=lambda report, rows, told=told: told(len(rows)),
        )
        assert sum(deliveries) == 4 and len(deliveries) >= 2
        assert len(merges) == (len(deliveries) if share > 1 else 2), (share, deliveries)
        status = cube.read_status(tmp_path / f"paced-{share}.zarr")
        assert np.sum(status == cube.DONE) == 4 and not caselog.pending_logs(tmp_path / f"paced-{share}.zarr")
