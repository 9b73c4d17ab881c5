"""Progress on stderr for long commands: a redrawn bar on a terminal, plain periodic lines
when stderr is a file or a pipe (a log), nothing for ``--json`` runs that asked for quiet."""

from __future__ import annotations

import sys
import time
from typing import Optional, TextIO

# plain lines in a log: at most one per this many seconds, plus the last
LOG_INTERVAL_S = 10.0


class Progress:
    """``progress(done, total)`` callable. On a terminal it redraws one bar line (``\\r``)
    and :meth:`close` ends that line; elsewhere it writes ``label: done/total`` lines at most
    every :data:`LOG_INTERVAL_S` seconds and when the work is complete, never a ``\\r``."""

    def __init__(self, label: str, stream: Optional[TextIO] = None, interval_s: float = LOG_INTERVAL_S):
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.interval_s = interval_s
        self._last = time.monotonic()
        self._drawn = False
        self._finished = False

    def __call__(self, done: int, total: int) -> None:
        if self.tty:
            width = 30
            filled = int(width * done / max(total, 1))
            self.stream.write(f"\r{self.label} [{'#' * filled}{'.' * (width - filled)}] {done}/{total}")
            self._drawn = True
        else:
            now = time.monotonic()
            complete = done >= total
            if (complete and not self._finished) or now - self._last >= self.interval_s:
                self.stream.write(f"{self.label}: {done}/{total}\n")
                self._last = now
                self._finished = complete
        self.stream.flush()

    def close(self) -> None:
        """End the bar's line on a terminal, so what follows starts on its own line."""
        if self._drawn:
            self.stream.write("\n")
            self.stream.flush()
            self._drawn = False


def progress(label: str, quiet: bool = False) -> Optional[Progress]:
    """A :class:`Progress` on stderr, or None when ``quiet``."""
    return None if quiet else Progress(label)


def done(bar: Optional[Progress]) -> None:
    """Close ``bar`` if there is one."""
    if bar is not None:
        bar.close()
