"""The cluster a sweep opens while it sets up its cube (ftsweep.sweeps.connection.EarlyCluster):
handed over once, its failure raised where it is taken, and closed when nobody takes it; a
sweep whose set-up fails, or that finds nothing to compute, closes the one it opened."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest

from ftsweep.store.cube import CubeError
from ftsweep.store.lock import LeaseLost
from ftsweep.sweeps import connection, run
from ftsweep.sweeps.connection import EarlyCluster, ExecutorError, Opened


class _Recorder:
    """Stands in for opening a cluster: counts the openings, closes the clusters it is told."""

    def __init__(self, fail: bool = False, gate: threading.Event | None = None) -> None:
        self.fail, self.gate = fail, gate
        self.opened: list[Opened] = []
        self.closed: list[object] = []

    def open(self, scheduler, workers, wait_s, warm=None):  # type: ignore[no-untyped-def]
        if self.gate is not None:
            self.gate.wait(10)
        if self.fail:
            raise ExecutorError("no dask scheduler answered")
        opened = Opened(client=object(), cluster=object(), got=connection.Cluster(workers, workers))
        self.opened.append(opened)
        return opened

    def close(self, client, cluster, scratch=None):  # type: ignore[no-untyped-def]
        self.closed.append(client)


@pytest.fixture
def recorder(monkeypatch):  # type: ignore[no-untyped-def]
    rec = _Recorder()
    monkeypatch.setattr(connection, "open_cluster", rec.open)
    monkeypatch.setattr(connection, "_close_quietly", rec.close)
    return rec


def test_a_taken_cluster_is_the_callers_and_closing_it_afterwards_does_nothing(recorder):
    early = EarlyCluster(None, 2, 1.0, None)
    opened = early.take()
    assert opened is recorder.opened[0] and opened.got.workers == 2
    early.close()
    assert recorder.closed == []


def test_a_cluster_nobody_takes_is_closed_once_it_has_opened(recorder):
    gate = threading.Event()
    recorder.gate = gate
    early = EarlyCluster(None, 2, 1.0, None)
    closer = threading.Thread(target=early.close)
    closer.start()
    gate.set()  # it opens only now: close waits for it, then closes it
    closer.join(10)
    assert len(recorder.opened) == 1 and recorder.closed == [recorder.opened[0].client]
    early.close()  # a second close changes nothing
    assert len(recorder.closed) == 1


def test_a_failure_to_open_is_raised_where_the_cluster_is_taken(recorder):
    recorder.fail = True
    early = EarlyCluster("tcp://127.0.0.1:9", 1, 1.0, None)
    with pytest.raises(ExecutorError, match="no dask scheduler"):
        early.take()
    early.close()  # nothing was opened: nothing to close, and no error here
    assert recorder.closed == []


def _sweep_spec(folder: Path, points: str) -> Path:
    spec = folder / "tiny.yaml"
    spec.write_text(f"surface: sinewave2d\nlayout: ring\naxes: {{points: {points}, aspect: [4.0]}}\n")
    return spec


def test_a_sweep_whose_set_up_fails_closes_the_cluster_it_opened(tmp_path, monkeypatch, recorder):
    def refuse(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise CubeError("the cube cannot be made")

    monkeypatch.setattr(run, "prepare_cube", refuse)
    with pytest.raises(CubeError):
        run.run_sweep(str(_sweep_spec(tmp_path, "[5000]")), tmp_path / "c.zarr", workers=1)
    assert len(recorder.opened) == 1 and recorder.closed == [recorder.opened[0].client]


def test_a_new_cube_with_nothing_to_compute_closes_the_cluster_it_opened(tmp_path, monkeypatch, recorder):
    # every case refused up front (its planning would refuse it): nothing is sent
    monkeypatch.setattr(
        run, "refuse_cases", lambda spec, out, pending, *a, **k: ({i: "refused" for i in pending}, {})
    )
    report = run.run_sweep(str(_sweep_spec(tmp_path, "[5000, 9000]")), tmp_path / "c.zarr", workers=1)
    assert report.queued == 0 and report.rows == []
    assert len(recorder.opened) == 1 and recorder.closed == [recorder.opened[0].client]


class _SlowClient:
    """A client whose close waits for ``meanwhile`` to have started: a close that ran before
    ``meanwhile`` (or after it) never sees the event, and records so."""

    def __init__(self, started: threading.Event, fail: bool = False) -> None:
        self.started, self.fail, self.saw_meanwhile = started, fail, False

    def close(self) -> None:
        self.saw_meanwhile = self.started.wait(10)
        if self.fail:
            raise OSError("the scheduler was gone")


def test_a_sweeps_last_merge_runs_while_its_cluster_closes():
    started = threading.Event()
    client = _SlowClient(started)
    opened = Opened(client=client, cluster=None, got=connection.Cluster(2, 2))
    ran: list[str] = []

    def meanwhile() -> None:
        started.set()
        ran.append(threading.current_thread().name)

    opened.close(meanwhile)
    assert client.saw_meanwhile and ran == [threading.current_thread().name]


def test_an_error_of_either_side_is_raised_once_both_are_done():
    started = threading.Event()
    client = _SlowClient(started, fail=True)
    with pytest.raises(OSError, match="scheduler was gone"):
        Opened(client=client, cluster=None, got=connection.Cluster(1, 1)).close(started.set)
    assert client.saw_meanwhile

    def merge_fails() -> None:
        started.set()
        raise LeaseLost("another writer took the lease")

    started.clear()
    client = _SlowClient(started, fail=True)
    with pytest.raises(LeaseLost, match="another writer"):  # the merge's error comes first
        Opened(client=client, cluster=None, got=connection.Cluster(1, 1)).close(merge_fails)
    assert client.saw_meanwhile
