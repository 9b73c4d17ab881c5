"""What a path program commands, whatever its dialect (docs/controllers.md): the moves a
reader of :mod:`ftsweep.inputs.programs` gives and a writer of :mod:`ftsweep.exports` takes,
and how a refusal names the line it stands on."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ftsweep.errors import ExportError


class DialectError(ExportError):
    """A program cannot be read or written in its dialect; the message names the line."""


@dataclass
class Moves:
    """What a path program commands (units in the names; ``seconds`` per segment)."""

    c_deg: np.ndarray
    x_mm: np.ndarray
    z_mm: np.ndarray
    seconds: np.ndarray
    y_mm: Optional[np.ndarray] = None
    velocity: Optional[dict[str, np.ndarray]] = None  # PVT: per axis [deg/s or mm/s]
    interpolation: str = "linear"
    dialect: str = "text"
    comments: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # what the reader passed over (M codes, approach)
    # a layered program ([3]): the servo's stroke W [mm] beside the slide's Z, and the points
    # where each cut after the first starts (the segment into such a point is an approach move,
    # its entry in ``seconds`` NaN)
    w_mm: Optional[np.ndarray] = None
    cut_starts: Optional[np.ndarray] = None
    dwell_s: float = 0.0  # time the program's dwells (G04) stand still, not in ``seconds``
    # G93 blocks that move no axis (a zero-length block, C360 -> C0 read modulo 360): the
    # tool stands still for their time [s], not in ``seconds``
    still_s: float = 0.0
    # each point's physical line in the file (1-based, as an editor counts; a preamble's
    # lines negative: :func:`line_label`), for refusals that name a point
    point_lines: Optional[np.ndarray] = None
    # moves that are not cuts (approaches, returns, air moves): (line, what) in file order
    not_cut: list[tuple[int, str]] = field(default_factory=list)
    # the modal state the program was read from (a preamble's, or the profile's power-on)
    started_from: str = ""
    # a PVT program's last segment is its stop after the planned path (:func:`with_stop`)
    stopped: bool = False

    @property
    def n_points(self) -> int:
        return int(self.c_deg.size)

    def where(self, k: int) -> str:
        """Where point ``k`` (0-based) stands in the file: its line, else its number."""
        if self.point_lines is None or not 0 <= k < self.point_lines.size:
            return f"point {k + 1}"
        return line_label(int(self.point_lines[k]))

    def cuts(self) -> list[tuple[int, int]]:
        """(first, stop) point indices of every cut, in program order (one for most programs)."""
        starts = [] if self.cut_starts is None else [int(k) for k in self.cut_starts]
        edges = [0, *starts, self.n_points]
        return list(zip(edges[:-1], edges[1:], strict=True))


def physical_line(n: int, preamble: int) -> int:
    """The physical line (1-based) of a reader's line ``n`` (0-based) when its first
    ``preamble`` lines are a template's read first: the program's own numbered from its first
    line, a preamble's negative (:func:`line_label`)."""
    return n - preamble + 1 if n >= preamble else -(n + 1)


def line_label(line: int) -> str:
    """A physical line as a refusal names it: ``line N`` of the program, ``preamble line N``
    for a line of the preamble it was read after (stored negative)."""
    return f"line {line}" if line > 0 else f"preamble line {-line}"
