"""Fixtures of every area: a private copy of the catalogs with extra test surfaces, and the
reference sweep, swept once for the whole run."""

from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
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


REFERENCE_SWEEP = "sinewave-ring"


@pytest.fixture(scope="session")
def reference_sweep(tmp_path_factory: pytest.TempPathFactory, worker_id: str) -> Path:
    """The catalog's reference sweep (84 cases), swept once for the whole run as the README's
    main command sweeps it: ``ftsweep sweep sinewave-ring`` on a local cluster of two workers.
    Every xdist worker that needs it waits, under a lock in the run's shared temporary folder,
    for the first to finish it. Tests copy it before they use it: an export writes into
    the cube (its ledger)."""
    from support.clusters import BIN

    root = tmp_path_factory.getbasetemp()
    root = root if worker_id == "master" else root.parent  # shared by the run's workers alone
    folder = root / "reference-sweep"
    out = folder / f"{REFERENCE_SWEEP}.zarr"
    with (root / "reference-sweep.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (folder / "swept.txt").exists():
            shutil.rmtree(folder, ignore_errors=True)
            folder.mkdir()
            env = {k: v for k, v in os.environ.items() if not k.startswith("FTSWEEP_")}
            cmd = [str(BIN / "ftsweep"), "sweep", REFERENCE_SWEEP, "--out", str(out), "--workers", "2"]
            done = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900)
            assert done.returncode == 0, done.stderr[-4000:]
            (folder / "swept.txt").write_text(done.stdout)  # last: the mark of a finished sweep
    return out
