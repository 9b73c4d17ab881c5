"""Where ftsweep keeps what it learns on a machine: numba's compiled kernels and the time their
first compile took, in the user's cache directory (or ``NUMBA_CACHE_DIR``), never inside the
installed package.

numba caches a kernel beside its source file when that folder is writable, which for a regular
install is ``site-packages/ftsweep``: pip does not know those files, leaves them behind on
uninstall, and the folder they leave hides a later editable install of the same package
(``import ftsweep.stages`` then finds an empty namespace). numba's documented setting
``NUMBA_CACHE_DIR`` moves its whole cache elsewhere; :func:`use_user_numba_cache` sets it, where
the user has not, to ``<user cache>/ftsweep/numba`` before any ftsweep kernel is defined. numba
reads it per kernel (its ``UserProvidedCacheLocator``), under a folder named after each
source folder's path, so a regular and an editable install never share a kernel. The setting
is the process's: processes started from it (a sweep's workers) inherit it, and so do a
user's own cached numba functions in the same process.

The user cache directory follows each platform's convention: ``$XDG_CACHE_HOME`` (else
``~/.cache``) on Linux and the BSDs, ``~/Library/Caches`` on macOS, ``%LOCALAPPDATA%`` on Windows.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from pathlib import Path
from typing import Optional

# the record of a first compile is a few dozen bytes; anything larger is not ours
_MAX_RECORD_BYTES = 4096
COMPILE_RECORD = "first-compile.json"


def user_cache_root() -> Path:
    """``<the platform's user cache directory>/ftsweep``."""
    home = Path.home()
    if sys.platform == "win32":
        base = Path(os.environ.get("LOCALAPPDATA") or home / "AppData" / "Local")
    elif sys.platform == "darwin":
        base = home / "Library" / "Caches"
    else:
        base = Path(os.environ.get("XDG_CACHE_HOME") or home / ".cache")
    return base / "ftsweep"


def numba_cache_dir() -> Path:
    """The folder numba caches ftsweep's kernels in: ``NUMBA_CACHE_DIR`` (the user's, or the
    one :func:`use_user_numba_cache` set)."""
    return Path(os.environ.get("NUMBA_CACHE_DIR") or user_cache_root() / "numba")


def use_user_numba_cache() -> None:
    """Point numba's cache at the user cache directory unless ``NUMBA_CACHE_DIR`` is set.

    Run when ftsweep is imported, before any of its kernels is defined. Where numba is
    imported already (a notebook that imported it first), its configuration is re-read from
    the environment through its public ``numba.core.config.reload_config``."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    os.environ["NUMBA_CACHE_DIR"] = str(user_cache_root() / "numba")
    if "numba.core.config" in sys.modules:
        from numba.core import config

        config.reload_config()


def recorded_compile_s(cache: Optional[Path] = None) -> Optional[float]:
    """Seconds the kernels' first compile took when last measured on this machine (by
    :func:`record_compile_s`, beside the kernels in :func:`numba_cache_dir`), or None where
    none was measured; ``cache`` names another numba cache folder. The record is a file of
    the user's cache: read bounded and checked, a damaged one is no record."""
    path = (cache or numba_cache_dir()) / COMPILE_RECORD
    try:
        with open(path, "rb") as handle:
            text = handle.read(_MAX_RECORD_BYTES + 1)
        seconds = json.loads(text)["seconds"] if len(text) <= _MAX_RECORD_BYTES else None
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if isinstance(seconds, bool) or not isinstance(seconds, (int, float)):
        return None
    return float(seconds) if math.isfinite(seconds) and 0 < seconds < 86400 else None


def record_compile_s(seconds: float) -> None:
    """Keep ``seconds`` as this machine's measured first compile (written whole or not at
    all: a temporary file moved in; a cache that cannot be written keeps no record)."""
    root = numba_cache_dir()
    record = {"seconds": round(float(seconds), 2), "measured": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    try:
        root.mkdir(parents=True, exist_ok=True)
        staging = root / f".{COMPILE_RECORD}.{os.getpid()}"
        staging.write_text(json.dumps(record))
        os.replace(staging, root / COMPILE_RECORD)
    except OSError:
        pass
