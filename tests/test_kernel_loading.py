"""Cached kernels loaded without numba's typing and lowering set-up (ftsweep.engine.startup.
lazy_cache_loads): every program kind's record is the same as with numba's own
loader, value for value, no kernel is compiled again, the registries that only a compilation
reads are not set up, and a compilation afterwards (a user's own ``@njit``) still works."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from tests.test_conformance import KindTests

# every kind's one-case sweep of the conformance suite (spiral rules and layered wrappers too)
_SWEEPS = [cls.sweep for cls in KindTests.__subclasses__()]

_RUN = """
import json, sys
lazy = sys.argv[1] == "lazy"
if lazy:
    from ftsweep.engine import startup
    startup.install()  # what the command line and every sweep worker do
from pathlib import Path
import numba
from ftsweep.simulate import run_case
from ftsweep.sweeps.spec import case_at, load_sweep
folder, sweeps = Path(sys.argv[2]), json.loads(sys.argv[3])
records = []
for i, text in enumerate(sweeps):
    spec_path = folder / f"s{i}.yaml"
    spec_path.write_text(text)
    _, spec = load_sweep(str(spec_path), folder)
    record = run_case(case_at(spec, 0), folder)
    records.append({k: (repr(v) if isinstance(v, float) else str(v)) for k, v in sorted(record.items())
                    if not k.startswith("seconds")})
misses = sum(
    sum(d._cache_misses.values())
    for name, module in list(sys.modules.items()) if name.startswith("ftsweep.stages")
    for d in vars(module).values() if isinstance(d, numba.core.registry.CPUDispatcher)
)
print(json.dumps({
    "records": records,
    "misses": misses,
    "registries": "numba.cpython.setobj" in sys.modules,
    "patched": getattr(numba.core.caching.Cache.load_overload, "_ftsweep_lazy", False),
}))
"""

_THEN_COMPILE = """
from ftsweep.engine import startup
startup.install()
import sys
import numpy as np
from numba import njit
from ftsweep.stages.kinematics import axes as kinematics
q = np.linspace(0.0, 1.0, 30).reshape(10, 3)
kinematics.extremes(q, np.full(9, 0.1), np.zeros(10, dtype=np.int64), 1)  # loaded lazily
before = "numba.cpython.setobj" in sys.modules

@njit
def distinct(a):
    return len(set(a)), np.dot(a, a)  # sets and BLAS: implementations of the skipped set-up

print(before, distinct(np.array([1.0, 2.0, 2.0, 3.0])))
"""


def _run(mode: str, folder, timeout: float = 600) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", _RUN, mode, str(folder), json.dumps(_SWEEPS)],
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.integration  # runs ftsweep in subprocesses
def test_every_kind_loads_its_kernels_lazily_with_the_same_records(catalog_dir):
    full = _run("full", catalog_dir)  # numba's own loader (compiles whatever is not cached)
    lazy = _run("lazy", catalog_dir)
    assert not full["patched"] and lazy["patched"]
    assert full["registries"]  # numba's loader sets the registries up even on cache hits
    assert lazy["misses"] == 0, "a kernel was compiled again: not loadable from numba's cache"
    assert not lazy["registries"], "numba's typing and lowering registries were set up"
    assert len(lazy["records"]) == len(_SWEEPS) >= 9
    assert lazy["records"] == full["records"]


def test_a_compilation_after_lazy_loads_sets_numba_up_and_works():
    # kinematics.extremes is cached by the test above or by this run's first call
    subprocess.run([sys.executable, "-c", _THEN_COMPILE], capture_output=True, timeout=300)
    out = subprocess.run([sys.executable, "-c", _THEN_COMPILE], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.split() == ["False", "(3,", "18.0)"]
