"""The version of ftsweep and the git revision of the code that runs, in a module of their own
so that any module can name them without importing the package's ``__init__`` (which
registers the xarray accessor)."""

from __future__ import annotations

import subprocess
from pathlib import Path
from typing import Optional

__version__ = "0.1.0"


def git_revision(source: Optional[Path] = None) -> str:
    """The git revision of ftsweep's own source checkout, or ``unknown``: when this very file
    (or ``source``) is tracked by the repository around it (an editable install of ftsweep),
    its HEAD; a regular install's is that of the checkout it was installed from, where its
    files are still the checkout's (:func:`installed_revision`). An installed copy inside a
    user's project (a virtual environment in its folder) would otherwise record the user's
    revision as ftsweep's."""
    here = Path(source or __file__).resolve()
    try:
        return _git(here.parent, "ls-files", "--error-unmatch", here.name) and _git(
            here.parent, "rev-parse", "HEAD"
        )
    except (OSError, subprocess.SubprocessError):
        return "unknown" if source is not None else installed_revision()


def _git(where: Path, *args: str) -> str:
    out = subprocess.run(["git", *args], cwd=where, capture_output=True, text=True, timeout=5, check=True)
    return out.stdout.strip()


# where setuptools puts the repository's folders in an installed package (pyproject.toml)
_INSTALLED_FROM = (
    ("ftsweep/stages/", "stages/"),
    ("ftsweep/catalogs_data/", "catalogs/"),
    ("ftsweep/", "pipeline/"),
)


def installed_revision() -> str:
    """A regular install's git revision: the checkout it was installed from (``pip install .``
    in a clone, recorded by pip as the install's origin, PEP 610 ``direct_url.json``), only
    where every installed source file is byte for byte the checkout's (the hashes of the
    install's RECORD): its HEAD, with ``+changes`` where the checkout's tracked files differ
    from HEAD; else ``unknown`` (the checkout moved on since the install, or is gone)."""
    import base64
    import hashlib
    import json
    from importlib import metadata
    from urllib.parse import unquote, urlparse

    try:
        dist = metadata.distribution("ftsweep")
        origin = json.loads(dist.read_text("direct_url.json") or "{}")
        url = urlparse(str(origin.get("url", "")))
        checkout = Path(unquote(url.path))
        if (
            url.scheme != "file"
            or origin.get("dir_info", {}).get("editable")
            or not (checkout / ".git").exists()
        ):
            return "unknown"
        for file in dist.files or ():
            name = str(file)
            if not name.endswith(".py") or file.hash is None or file.hash.mode != "sha256":
                continue
            inside, folder = next((i, f) for i, f in _INSTALLED_FROM if name.startswith(i))
            digest = hashlib.sha256((checkout / folder / name[len(inside) :]).read_bytes()).digest()
            if base64.urlsafe_b64encode(digest).rstrip(b"=").decode() != file.hash.value:
                return "unknown"
        head = _git(checkout, "rev-parse", "HEAD")
        changed = _git(checkout, "status", "--porcelain", "--untracked-files=no", "--", "pipeline", "stages")
        return f"{head}+changes" if changed else head
    except (OSError, ValueError, StopIteration, subprocess.SubprocessError, metadata.PackageNotFoundError):
        return "unknown"
