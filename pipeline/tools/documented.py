"""The times the README documents, measured again (``ftsweep bench --documented``).

A figure a user reads before running something ("48 s", "about 15 s") goes stale silently
when the code changes; this runs what each figure describes, as a user on a fresh install
would, and prints the documented figure beside the measured one. Three sources:

- the README's quickstart block: every ``ftsweep …`` line ending in a comment ``…: N s``,
  run in order in a fresh folder, with an empty numba cache so that the first sweep compiles
  the kernels as on a fresh install;
- the README's first-compile sentence ("a first `predict` of a ring: N s against M s once
  they are cached"): the same predict with an empty cache, then with the cache it filled;
- the compile figure a first run's notice gives (the first predict's own record,
  :func:`ftsweep.caches.recorded_compile_s`), against the difference of those two.

The README is the checkout's where ftsweep runs from one (an editable install), else the copy
every install carries in its package metadata (the project's long description), so the bench
runs from a regular install too.

The install line and the test commands are not run here (the network and half an hour):
their figures come from a fresh clone's CI log. Nothing is asserted about time.
"""

from __future__ import annotations

import os
import re
import shlex
import tempfile
from pathlib import Path
from typing import Any, NamedTuple, Optional

# a quickstart line: the command, then a comment ending in the seconds it took
_TIMED_LINE = re.compile(r"^(ftsweep [^#]*?)\s*#.*?(\d+(?:\.\d+)?) s\s*$")
_QUICKSTART = re.compile(r"^## Quickstart.*?^```\w*\n(.*?)^```", re.S | re.M)
_FIRST_PREDICT = re.compile(r"a first\s+`predict` of an? [\w-]+: (\d+(?:\.\d+)?) s against (\d+(?:\.\d+)?) s")
# the prediction the first-compile sentence times: the tour's first, as its "$ " line shows it
_TOUR_PREDICT = re.compile(r"^## A short tour.*?^\$ (ftsweep predict [^\n#]*?)\s*$", re.S | re.M)


class Documented(NamedTuple):
    """One documented time: what it is, the figure [s] (None: the text no longer states
    it), and the command that measures it (None: a figure derived from other rows)."""

    label: str
    seconds: Optional[float]
    command: Optional[str]


def readme_text() -> tuple[str, str]:
    """The README whose figures are measured, and where it was read: the checkout's beside
    this ftsweep (an editable install), else the one the installed package's metadata carries
    (``readme`` of pyproject.toml, read through :mod:`importlib.metadata`)."""
    from importlib import metadata

    # the package's folder (pipeline/ in a checkout) is two above this module
    path = Path(__file__).resolve().parents[2] / "README.md"
    if path.is_file() and (path.parent / "pyproject.toml").is_file():
        return path.read_text(encoding="utf-8"), str(path)
    try:
        # the description is the metadata's body (Core Metadata 2.1), an email.message.Message
        text = getattr(metadata.metadata("ftsweep"), "get_payload", lambda: None)()
    except metadata.PackageNotFoundError:
        text = None
    if not isinstance(text, str) or "## Quickstart" not in text:
        raise ValueError(
            "this ftsweep carries no README: neither a checkout's beside it nor its package "
            "metadata's description (reinstall it: pip install ftsweep)"
        )
    return text, "the installed package's metadata"


def documented_times(readme: str) -> list[Documented]:
    """The quickstart's timed lines, then the first-compile pair, from the README's text."""
    rows = []
    block = _QUICKSTART.search(readme)
    for line in (block.group(1) if block else "").splitlines():
        m = _TIMED_LINE.match(line.strip())
        if m:
            rows.append(Documented(m.group(1), float(m.group(2)), m.group(1)))
    if not rows:
        rows.append(Documented("the quickstart's timed ftsweep lines", None, None))
    pair = _FIRST_PREDICT.search(" ".join(readme.split()))
    first, cached = (float(pair.group(1)), float(pair.group(2))) if pair else (None, None)
    tour = _TOUR_PREDICT.search(readme)
    command = tour.group(1) if tour else None
    rows.append(Documented(FIRST_LABEL, first, command))
    rows.append(Documented(CACHED_LABEL, cached, command))
    return rows


# the first-compile pair's rows: they run in a cache of their own
FIRST_LABEL = "the tour's first predict, kernels compiled"
CACHED_LABEL = "the same predict, kernels cached"


def measure(rows: list[Documented], executable: str = "ftsweep") -> list[dict[str, Any]]:
    """Run every row's command as :mod:`this module <ftsweep.tools.documented>` describes
    (``executable`` stands for the leading ``ftsweep``) and return the rows with their
    measured seconds, then the compile figure the first predict recorded (what a later first
    run's notice prints) against the measured compile time."""
    from ftsweep.caches import recorded_compile_s
    from ftsweep.tools.bench import timed_process

    out: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="ftsweep-documented-") as folder:
        root = Path(folder)
        caches = {"quickstart": root / "cache-quickstart", "predict": root / "cache-predict"}
        for name, cache in caches.items():
            cache.mkdir()
            (root / name).mkdir()
        for row in rows:
            if row.command is None:
                out.append({**row._asdict(), "measured": None})
                continue
            group = "predict" if row.label in (FIRST_LABEL, CACHED_LABEL) else "quickstart"
            env = {**os.environ, "NUMBA_CACHE_DIR": str(caches[group])}
            command = executable + row.command[len("ftsweep") :]
            took, _ = timed_process(shlex.split(command), f"`{command}`", root / group, env)
            out.append({**row._asdict(), "measured": took})
        recorded = recorded_compile_s(caches["predict"])
    compiled = [r["measured"] for r in out if r["label"] in (FIRST_LABEL, CACHED_LABEL)]
    out.append(
        {
            "label": "compile figure a first run's notice gives (recorded by it)",
            "seconds": recorded,
            "command": None,
            "measured": compiled[0] - compiled[1] if len(compiled) == 2 else None,
        }
    )
    return out


def format_documented(rows: list[dict[str, Any]]) -> str:
    """The documented figure beside the measured one, and their ratio."""

    def sec(v: Optional[float]) -> str:
        return "—" if v is None else f"{v:.1f}"

    head = f"{'documented time (README, sweep)':66s} {'written s':>9s} {'measured s':>10s} {'ratio':>6s}"
    lines = [head, "-" * len(head)]
    for r in rows:
        both = r["seconds"] is not None and r["measured"] is not None and r["seconds"] > 0
        ratio = f"{r['measured'] / r['seconds']:6.2f}" if both else "     —"
        lines.append(f"{r['label'][:66]:66s} {sec(r['seconds']):>9s} {sec(r['measured']):>10s} {ratio}")
    lines.append("written: the figure in the text ('—': the text no longer states it)")
    lines.append("measured: in a fresh folder with an empty numba cache, as a fresh install's first run")
    lines.append("not run here: the install and test times (a fresh clone's CI log has them)")
    return "\n".join(lines)
