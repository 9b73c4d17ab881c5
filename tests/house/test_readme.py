"""Every block of README.md and then of docs/guide.md a user copies runs as written, in order,
in one fresh folder, as a user following them would run them (the environment's installed ftsweep on PATH, a
`.venv` beside them): a block that fails, or an output a block shows that differs, fails.

The reference sweep is swept once for the whole test run (tests/conftest.py, by the README's
own command) and its cube copied into the folder where the blocks sweep it locally
(:data:`REFERENCE_CUBES`): those blocks then resume a finished cube.

Not run, each for its reason (:data:`NOT_RUN`): the test commands (they are this suite) and
the crontab entry (a line for cron, not a command). The set-up lines' `python3 -m venv .venv
&& .venv/bin/pip install …` are what CI itself ran before this test: the rest of each line
runs.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from support.clusters import group_gone
from support.places import REPO

pytestmark = pytest.mark.integration

README = REPO / "README.md"
# the pages whose blocks run, in the order a user reads them
PAGES = (README, README.parent / "docs" / "guide.md")
FENCE = re.compile(r"^```(\w*)\n(.*?)^```$", re.S | re.M)
INSTALL = re.compile(r"python3 -m venv \.venv && \.venv/bin/pip install [^&#]*(?:&& )?")
# blocks not run, recognised by their text, and why
NOT_RUN = {
    "pytest": "the test commands: they are this suite",
    "# crontab": "a crontab entry: a line for cron, not a command",
}
BLOCK_TIMEOUT_S = 1200


def blocks() -> list[tuple[str, str, str]]:
    """(where: page and line, language, text) of every fenced block of :data:`PAGES`, in order."""
    found = []
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        name = page.relative_to(README.parent)
        found += [
            (f"{name} line {text[: m.start()].count(chr(10)) + 1}", m.group(1), m.group(2))
            for m in FENCE.finditer(text)
        ]
    return found


def _skip_reason(text: str) -> str:
    return next((why for key, why in NOT_RUN.items() if key in text), "")


def _run(script: list[str], cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    """``script`` in its own session, its output in a file (servers it starts with ``&`` keep
    a pipe open, a file they do not); every process it leaves behind is ended with it."""
    log = cwd / ".block.log"
    with log.open("w") as sink:
        proc = subprocess.Popen(
            script, cwd=cwd, env=env, stdout=sink, stderr=subprocess.STDOUT, start_new_session=True
        )
        try:
            proc.wait(timeout=BLOCK_TIMEOUT_S)
        finally:
            _end_group(proc.pid)
    return subprocess.CompletedProcess(script, proc.returncode, log.read_text(errors="replace"), "")


def _end_group(pid: int) -> None:
    """End a block's session: SIGTERM, then SIGKILL for what did not stop within 5 s."""
    for sig, grace in ((signal.SIGTERM, 5.0), (signal.SIGKILL, 0.0)):
        try:
            os.killpg(pid, sig)
        except ProcessLookupError:
            return
        if group_gone(pid, grace):
            return


def _console(text: str, cwd: Path, env: dict[str, str]) -> None:
    """A console block: each ``$`` command runs; the lines it shows appear in its output, in
    order (``...`` stands for lines left out)."""
    for chunk in text.split("$ ")[1:]:
        command, *shown = chunk.rstrip("\n").split("\n")
        done = _run(["bash", "-c", command], cwd, env)
        assert done.returncode == 0, f"{command}: {done.stdout[-2000:]}"
        lines = [ln for ln in shown if ln.strip() and ln.strip() != "..."]
        out = done.stdout.split("\n")
        at = 0
        for line in lines:
            found = next((k for k in range(at, len(out)) if out[k].rstrip() == line.rstrip()), None)
            assert found is not None, (
                f"{command}: the page shows {line!r}; it printed:\n{done.stdout[-3000:]}"
            )
            at = found + 1


def _text(text: str, previous: str) -> None:
    """A text block showing what the block before it printed: each of its lines appears, but
    for what is the user's own (the cube's folder, the key, the time of signing)."""
    for line in text.strip("\n").split("\n"):
        words = line.split()
        if words[0] in ("for", "signed"):
            continue  # a folder, a key id and a time: the user's own
        assert " ".join(words) in {" ".join(ln.split()) for ln in previous.split("\n")}, (
            f"the page shows {line!r}; the block before it printed:\n{previous[-3000:]}"
        )


# the cubes of the reference sweep the pages' blocks sweep into a local folder: the run's one
# reference sweep (tests/conftest.py, swept by the README's own command) is copied in, so those
# blocks resume a finished cube, computing nothing, and every later block reads its cases
REFERENCE_CUBES = ("outputs/sinewave-ring.zarr", "outputs/ring-on-a-cluster.zarr")


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory, reference_sweep: Path) -> Path:
    """A fresh folder holding the environment (``.venv``) the README's set-up made and the
    reference sweep's cubes (:data:`REFERENCE_CUBES`)."""
    root = tmp_path_factory.mktemp("readme")
    (root / ".venv").symlink_to(Path(sys.prefix), target_is_directory=True)
    for name in REFERENCE_CUBES:
        shutil.copytree(reference_sweep, root / name)
    return root


def test_every_readme_block_runs_as_written(folder):
    env = {k: v for k, v in os.environ.items() if not k.startswith(("FTSWEEP_", "FSSPEC_", "AWS_"))}
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env["HOME"] = str(folder)  # keys and configs of this user only
    # ... but the kernels this environment compiled already (numba's cache is the user's)
    from ftsweep.caches import numba_cache_dir

    env["NUMBA_CACHE_DIR"] = str(numba_cache_dir())
    previous, ran = "", []
    for line, lang, text in blocks():
        if lang not in ("bash", "console", "python", "text") or _skip_reason(text):
            continue
        if lang == "text":
            _text(text, previous)
            continue
        if lang == "console":
            _console(text, folder, env)
            continue
        if lang == "python":
            script = folder / f"block-{len(ran)}.py"
            script.write_text(text)
            done = _run([sys.executable, str(script)], folder, env)
        else:
            done = _run(["bash", "-e", "-o", "pipefail", "-c", INSTALL.sub("", text)], folder, env)
        assert done.returncode == 0, f"{line}: the block failed:\n{done.stdout[-4000:]}"
        previous = done.stdout
        ran.append(line)
    assert len(ran) >= 10, ran
    # the notebook tour, as the README runs it: its kernel starts in docs/, the cube is the
    # reference sweep's in the folder above
    (folder / "docs").mkdir(exist_ok=True)
    (folder / "docs" / "tour.ipynb").write_bytes((README.parent / "docs" / "tour.ipynb").read_bytes())
    done = _run([str(folder / ".venv" / "bin" / "jupyter-execute"), "docs/tour.ipynb"], folder, env)
    assert done.returncode == 0, f"the notebook tour failed:\n{done.stdout[-4000:]}"


def test_only_the_named_blocks_are_left_out():
    """Every runnable block runs: those left out are the test commands and the crontab line."""
    left = [
        (line, _skip_reason(text)) for line, lang, text in blocks() if lang == "bash" and _skip_reason(text)
    ]
    assert {why for _, why in left} <= set(NOT_RUN.values()) and len(left) == 3, left
