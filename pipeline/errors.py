"""The error a file ftsweep reads or writes raises, in the base layer so that the readers of
:mod:`ftsweep.inputs` and the writers of :mod:`ftsweep.exports` and :mod:`ftsweep.store` share
one class a command catches."""

from __future__ import annotations


class ExportError(ValueError):
    """A file cannot be read, written or verified (a header, a sidecar, a program from
    elsewhere); the message names the file, or the line, and says why."""
