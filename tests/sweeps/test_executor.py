"""Executors on trivial task functions: no numerics, no cube. The same
groups give the same summaries on every scheduler; a task that raises is reported through
``on_error`` and the others run on; the warm-up runs before any task."""

from __future__ import annotations

import os

import pytest

from ftsweep.sweeps.executor import SYNCHRONOUS, TaskSpec, execute

SPEC = TaskSpec(cube="/nowhere.zarr", spec_json="{}", catalog_folder=None, run_id="test-run")
GROUPS = [[0, 1], [2], [3, 4, 5]]


def square(task: TaskSpec, group: list[int]) -> list[dict]:
    """A task that only echoes its inputs (importable, so worker processes can run it)."""
    return [{"index": i, "status": "done", "value": i * i, "run_id": task.run_id} for i in group]


def fail_on_two(task: TaskSpec, group: list[int]) -> list[dict]:
    if 2 in group:
        raise OSError(28, "No space left on device")
    return square(task, group)


def as_error(task: TaskSpec, group: list[int], exc: BaseException) -> list[dict]:
    return [{"index": i, "status": "error", "message": f"{type(exc).__name__}: {exc}"} for i in group]


WARMED: list[int] = []


def warm() -> int:
    WARMED.append(os.getpid())
    return os.getpid()


def _collect(scheduler: str | None, task, **kw) -> list[dict]:  # type: ignore[no-untyped-def]
    rows: list[dict] = []
    execute(GROUPS, SPEC, scheduler, 2, rows.extend, task=task, **kw)
    return sorted(rows, key=lambda r: r["index"])


def test_synchronous_runs_every_group_after_the_warm_up():
    WARMED.clear()
    rows = _collect(SYNCHRONOUS, square, warm=warm)
    assert WARMED == [os.getpid()]
    assert [r["value"] for r in rows] == [0, 1, 4, 9, 16, 25]
    assert {r["run_id"] for r in rows} == {"test-run"}


def test_a_broken_task_is_reported_and_the_others_run_on():
    rows = _collect(SYNCHRONOUS, fail_on_two, on_error=as_error)
    assert [r["status"] for r in rows] == ["done", "done", "error", "done", "done", "done"]
    assert "No space left on device" in rows[2]["message"]


def test_nothing_to_run_starts_nothing():
    execute([], SPEC, "tcp://127.0.0.1:1", 1, lambda rows: pytest.fail("called"), task=square)


@pytest.mark.slow  # 5-7 s on 2 cores: the full command runs it, the quick one leaves it out
def test_local_cluster_gives_the_synchronous_summaries():
    assert _collect(None, square) == _collect(SYNCHRONOUS, square)
    assert _collect(None, fail_on_two, on_error=as_error) == _collect(
        SYNCHRONOUS, fail_on_two, on_error=as_error
    )


def publish_then_wait(task: TaskSpec, group: list[int]) -> list[dict]:
    """A task whose first case is published at once and whose second takes 1.5 s."""
    import time

    from ftsweep.sweeps.executor import publish

    rows = square(task, group)
    publish(task, rows[0])
    time.sleep(1.5)
    return rows


@pytest.mark.parametrize("scheduler", [SYNCHRONOUS, None])
def test_a_case_is_reported_when_it_is_written_and_only_once(scheduler):
    # progress as cases finish, not as tasks do (run_task publishes each case)
    import time

    arrivals: list[tuple[float, list[int]]] = []
    start = time.perf_counter()
    execute(
        [[0, 1]],
        SPEC,
        scheduler,
        1,
        lambda rows: arrivals.append((time.perf_counter() - start, [r["index"] for r in rows])),
        task=publish_then_wait,
    )
    assert [i for _, rows in arrivals for i in rows] == [0, 1]  # each case once, in order
    (first, _), (second, _) = arrivals
    assert second - first >= 1.0


def test_deliveries_hand_on_each_case_once_whatever_comes_first():
    from ftsweep.sweeps.executor import Deliveries

    got: list[list[int]] = []
    d = Deliveries(lambda rows: got.append([r["index"] for r in rows]))
    d.event({"index": 3})
    d.drain()
    d.deliver([{"index": 3}, {"index": 4}])
    d.event({"index": 4})
    d.drain()
    d.deliver([{"index": 5}])
    assert got == [[3], [4], [5]]


def profiler_state(task: TaskSpec, group: list[int]) -> list[dict]:
    """A task reporting whether its worker runs Dask's statistical profiler."""
    import dask

    return [{"index": i, "profile": dask.config.get("distributed.worker.profile.enabled")} for i in group]


def test_local_workers_run_without_the_statistical_profiler():
    # its thread takes the GIL every 10 ms; our tasks are kernels, nobody reads the profile
    rows = _collect(None, profiler_state)
    assert rows and all(r["profile"] is False for r in rows)


def test_the_local_dashboard_listens_on_loopback_only():
    from ftsweep.sweeps.connection import _close_quietly, _connect

    conn = _connect(None, 1)
    client, cluster = conn.client, conn.cluster
    try:
        link = cluster.dashboard_link
        assert link.startswith("http://127.0.0.1:"), link
        hosts = {sock.getsockname()[0] for sock in cluster.scheduler.http_server._sockets.values()}
        assert hosts == {"127.0.0.1"}, hosts
    finally:
        _close_quietly(client, cluster, conn.scratch)
    assert conn.scratch is not None and not os.path.exists(conn.scratch)  # the scratch folder went too


class _Future:
    """A finished task's future as the driver sees it: its status, and what reading it gives."""

    def __init__(self, status, result=None, error=None, lost=False, becomes=None):
        self.status, self._result, self._error, self._lost = status, result, error, lost
        self._becomes = becomes

    def exception(self):
        return self._error

    def result(self, timeout=None):
        if self._lost:  # its data went with its worker: the scheduler computes it again
            self.status = "pending"
            raise TimeoutError(f"no result within {timeout} s")
        if self._error is not None:
            self.status = self._becomes or self.status
            raise self._error
        return self._result


def test_a_result_lost_with_its_worker_goes_back_to_pending_instead_of_blocking():
    from ftsweep.sweeps.executor import _task_rows

    def on_error(spec, group, exc):
        return [{"index": i, "status": "error", "message": str(exc)} for i in group]

    rows = [{"index": 3, "status": "done"}]
    assert _task_rows(_Future("finished", result=rows), [3], None, on_error) == rows
    assert _task_rows(_Future("finished", lost=True), [3], None, on_error) is None
    # a task that broke, even with a TimeoutError of its own, is reported with its cases
    for error in (ValueError("disk full"), TimeoutError("cube lock")):
        out = _task_rows(_Future("error", error=error), [4, 5], None, on_error)
        assert [r["index"] for r in out] == [4, 5] and str(error) in out[0]["message"]
    # finished when looked at, broken when read (status moved on)
    broke_meanwhile = _Future("finished", error=TimeoutError("slow store"), becomes="error")
    assert _task_rows(broke_meanwhile, [6], None, on_error)[0]["status"] == "error"
