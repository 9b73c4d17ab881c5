"""A sweep's progress as a person sees it: on a terminal one live bar, in a pipe or log at
most one line every 10 s and the last; progress, summary and exit status on one clock and
one count."""

from __future__ import annotations

import os
import pty
import re
import subprocess
import time
from pathlib import Path

import pytest
from support.clusters import BIN

pytestmark = pytest.mark.integration  # subprocesses, a pseudo-terminal

SPEC = "surface: small_sine\nlayout: ring\naxes: {points: [8000, 16000, 3000000], aspect: [1.0, 4.0]}\n"


def _cmd(tmp_path: Path) -> list[str]:
    spec = tmp_path / "p.yaml"
    spec.write_text(SPEC)
    return [
        str(BIN / "ftsweep"),
        "sweep",
        str(spec),
        "--out",
        str(tmp_path / "p.zarr"),
        "--scheduler",
        "synchronous",
    ]


def test_a_terminal_shows_one_live_bar(tmp_path, catalog_dir):
    env = dict(os.environ, FTSWEEP_CATALOGS=str(catalog_dir), COLUMNS="120")
    leader, follower = pty.openpty()
    proc = subprocess.Popen(_cmd(tmp_path), stdin=follower, stdout=subprocess.PIPE, stderr=follower, env=env)
    os.close(follower)
    seen = b""
    while True:
        try:
            chunk = os.read(leader, 4096)
        except OSError:  # the terminal closed with the process
            break
        if not chunk:
            break
        seen += chunk
    proc.wait(timeout=300)
    os.close(leader)
    text = seen.decode("utf-8", "replace")
    assert "\r" in text and "sweep: 6/6 |" in text  # tqdm redraws one line: 4 computed, 2 refused up front
    # ftsweep's counts add up to the bar's total; one clock and one ETA, ftsweep's: no tqdm rate
    assert "4 done, 0 failed, 2 refused, 0 pending | " in text and "ETA 0 s" in text
    assert "case/s" not in text and "it/s" not in text and text.count("ETA") == text.count(" pending | ")
    assert not re.search(r"^\[\s*\d+/\d+\]", text, re.M)  # no scrolling log lines on a terminal
    assert proc.returncode == 1  # two cases refused: the cube cannot be completed as specified


def test_a_pipe_gets_at_most_a_line_every_ten_seconds(tmp_path, catalog_dir):
    env = dict(os.environ, FTSWEEP_CATALOGS=str(catalog_dir))
    start = time.monotonic()
    run = subprocess.run(_cmd(tmp_path), capture_output=True, text=True, env=env, timeout=300)
    elapsed = time.monotonic() - start
    lines = [line for line in run.stderr.splitlines() if re.match(r"^\[\s*\d+/\d+\]", line)]
    assert "\r" not in run.stderr
    assert 1 <= len(lines) <= 1 + elapsed / 10.0, run.stderr
    assert lines[-1].startswith("[4/4] 0 failed, 2 refused, 0 pending")  # the last line, always
    summary = next(line for line in run.stdout.splitlines() if line.startswith("wall time"))
    shown = float(re.search(r"\| +([\d.]+) s,", lines[-1]).group(1))
    assert float(summary.split()[2]) >= shown  # one clock: the summary's wall time is the command's
    assert "refused      2 case(s)" in run.stdout and run.returncode == 1
    again = subprocess.run(_cmd(tmp_path), capture_output=True, text=True, env=env, timeout=300)
    assert "nothing to do: no case is pending" in again.stdout and "cluster" not in again.stderr
