"""numba's BLAS probe given its one module (ftsweep.engine.startup): no scipy.linalg when
numba's CPU target is set up (a process's first compilation), and the module the probe gets
is scipy's own, which works through numba and through scipy.linalg imported afterwards."""

from __future__ import annotations

import subprocess
import sys

_FRESH = """
import sys
from ftsweep.engine import startup
startup.install()
assert any(isinstance(f, startup._BeforeProbe) for f in sys.meta_path)
import numpy as np
from numba import njit

@njit
def first(a):
    return a.sum()

first(np.ones(3))  # a first compilation: numba's full set-up (cached kernels load without it)
print("linalg", "scipy.linalg" in sys.modules)
print("probed", startup.PROBED in sys.modules)
print("hook", any(isinstance(f, startup._BeforeProbe) for f in sys.meta_path))

@njit
def dot(a, b):
    return np.dot(a, b)  # numba's BLAS path: the preloaded module's C functions

a = np.arange(6.0).reshape(2, 3)
print("numba_dot", dot(a, a.T).tolist() == (a @ a.T).tolist())
import scipy.linalg
from scipy.linalg import cython_blas
print("same", cython_blas is sys.modules[startup.PROBED])
print("solve", scipy.linalg.solve(np.eye(2) * 2.0, np.ones(2)).tolist())
"""


def _run(code: str) -> dict[str, str]:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return dict(line.split(" ", 1) for line in out.stdout.strip().splitlines())


def test_first_kernel_imports_no_scipy_linalg_and_blas_still_works():
    got = _run(_FRESH)
    assert got == {
        "linalg": "False",
        "probed": "True",
        "hook": "False",
        "numba_dot": "True",
        "same": "True",
        "solve": "[0.5, 0.5]",
    }


def test_install_after_numba_probed_changes_nothing():
    got = _run(
        "import sys\n"
        "import numba.np.arraymath\n"  # numba's probe has run: scipy.linalg is in
        "from ftsweep.engine import startup\n"
        "startup.install()\n"
        "print('hook', any(isinstance(f, startup._BeforeProbe) for f in sys.meta_path))\n"
        "print('preload', startup.preload_blas_probe())\n"
    )
    assert got == {"hook": "False", "preload": "True"}


def test_without_the_hook_numba_imports_scipy_linalg():
    # the cost the hook removes exists: the probe's import pulls in the package (else the
    # test above would pass without any hook)
    got = _run("import sys\nimport numba.np.arraymath\nprint('linalg', 'scipy.linalg' in sys.modules)\n")
    assert got == {"linalg": "True"}


def test_the_hook_leaves_the_other_finders_of_the_probing_import_their_turn():
    # the hook fires while the import system walks sys.meta_path: it must not shift the
    # finders after it (a finder right behind it would be skipped for that import)
    got = _run(
        "import sys\n"
        "from ftsweep.engine import startup\n"
        "startup.install()\n"
        "seen = []\n"
        "class Recorder:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        seen.append(name)\n"
        "        return None\n"
        "sys.meta_path.insert(sys.meta_path.index(startup._HOOK) + 1, Recorder())\n"
        "import numba.np.arraymath\n"
        "print('recorded', 'numba.np.arraymath' in seen)\n"
        "print('hook', any(isinstance(f, startup._BeforeProbe) for f in sys.meta_path))\n"
        "print('linalg', 'scipy.linalg' in sys.modules)\n"
    )
    assert got == {"recorded": "True", "hook": "False", "linalg": "False"}
