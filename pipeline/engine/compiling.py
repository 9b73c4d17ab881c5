"""A first run's compile shared between processes (docs/performance.md, "A first run's
compile, shared"): the kernels a case calls are found without compiling them, on one line of
it (:func:`ftsweep.engine.startup.kernel_calls`), and compiled each once by the processes
that share a claims folder (:func:`ftsweep.engine.startup.compile_shared`).

A sweep's workers share one (:mod:`ftsweep.sweeps.executor`). A single case on a machine's
first run (``predict``) starts one helper process, ``python -m ftsweep.engine.compiling
FOLDER``, that reads the case's JSON from its standard input (validated as a
:class:`~ftsweep.engine.case.Case`, never executed) and compiles its share beside it.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Optional

from ftsweep.engine import startup
from ftsweep.engine.case import Case, Resolution

# seconds a process may spend finding the kernels a case calls, run as Python on one line of
# it (docs/performance.md, "A first run's compile, shared"); a kind whose planning runs longer
# as Python shares what was found by then
SHARE_BUDGET_S = 2.0
# seconds a process waits for a kernel another is compiling before it compiles it too
SHARE_WAIT_S = 120.0
# the case's JSON a helper reads at most [bytes]: a case is a few hundred
MAX_CASE_BYTES = 1 << 20


def shared(case: Case, kind: Any, catalog_folder: Optional[Path], claims: str) -> None:
    """On a first run (numba's cache empty), find the kernels ``case`` of ``kind`` calls (on
    one line of the kind's warm-up table, with the case's surface, machine, cutting and
    compensation: the same kernels and types, found in about a second) and compile them with
    the other processes that share the ``claims`` folder, each kernel once.
    Nothing is done for kernels cached already or a kind not sampled on spindle angles (its
    planning would run as Python). The seconds it took are recorded as this machine's first
    compile (:func:`ftsweep.caches.record_compile_s`), the figure the next first run's notice
    gives."""
    from ftsweep.caches import record_compile_s
    from ftsweep.simulate import run_case

    if kind.angular_cells is None or startup.kernels_cached():
        return
    started = time.perf_counter()
    # the same kernels on the kind's coarse warm-up table, on one line: quick as Python
    line = case.model_copy(update={"layout": kind.warm_request(), "resolution": Resolution(n_theta=2)})
    calls = startup.kernel_calls(lambda: run_case(line, catalog_folder), SHARE_BUDGET_S)
    startup.compile_shared(calls, claims, SHARE_WAIT_S)
    record_compile_s(time.perf_counter() - started)


def claims_folder() -> str:
    """A claims folder of its own for one run, in the temporary directory (not made here)."""
    return os.path.join(tempfile.gettempdir(), f"ftsweep-compiling-{uuid.uuid4().hex}")


@contextlib.contextmanager
def with_helper(case: Case, kind: Any, catalog_folder: Optional[Path], cores: int) -> Iterator[None]:
    """Around a single case's run: on a machine's first run with two or more ``cores``, a
    helper process compiles a share of the kernels while this one compiles the rest
    (:func:`shared`), and the case starts once both are done; elsewhere nothing. The helper
    is ended as soon as the kernels are compiled (what it has left is loading them), or if
    this process leaves early (an error, Ctrl-C), and its claims folder removed."""
    if cores < 2 or kind.angular_cells is None or startup.kernels_cached():
        yield
        return
    claims = claims_folder()
    env = dict(os.environ)
    if catalog_folder is not None:
        env["FTSWEEP_CATALOGS"] = str(catalog_folder)
    helper = subprocess.Popen(
        [sys.executable, "-m", "ftsweep.engine.compiling", claims],
        stdin=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=env,
    )
    try:
        assert helper.stdin is not None
        with contextlib.suppress(OSError):  # a helper that died at once: this process compiles all
            helper.stdin.write(case.model_dump_json().encode())
            helper.stdin.close()
        shared(case, kind, catalog_folder, claims)
    finally:
        if helper.poll() is None:
            helper.terminate()
        helper.wait()
        shutil.rmtree(claims, ignore_errors=True)
    yield


def _main(argv: list[str]) -> int:
    """``python -m ftsweep.engine.compiling FOLDER``: the helper of :func:`with_helper`."""
    from ftsweep.engine import plugins

    if len(argv) != 1:
        return 2
    text = sys.stdin.buffer.read(MAX_CASE_BYTES + 1)
    if len(text) > MAX_CASE_BYTES:
        return 2
    startup.install()
    case = Case.model_validate_json(text)
    folder = os.environ.get("FTSWEEP_CATALOGS")
    shared(case, plugins.kind(case.layout.kind), Path(folder) if folder else None, argv[0])
    return 0


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
