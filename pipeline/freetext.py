"""Free text is data, never syntax (docs/architecture.md "Trust").

Every string that export renders into a header or program (generator, creation time,
surface, machine and cutting names, file names, kind names) is held to one strict character
set where it enters ftsweep (a sidecar or a cube's recorded spec being read, a catalog entry's
name, an output file name) and again where it is rendered. The set is printable ASCII
without anything that means something to a C preprocessor or compiler (backslash, quotes,
``*`` so neither ``/*`` nor ``*/``, ``#``, ``?`` so no trigraph) or to a controller's program
(line ends, ``(``, ``)``, ``;``, ``%``): such a string can be written as it is, so export
escapes nothing because nothing needs escaping.
"""

from __future__ import annotations

import re
from typing import Any

# letters, digits, space and the punctuation of names, versions, times, paths and URLs
ALLOWED = "A-Za-z0-9 _.,:+=/@\\[\\]-"
_TEXT = re.compile(f"[{ALLOWED}]*")
_BAD = re.compile(f"[^{ALLOWED}]")
MAX_TEXT = 256
# sidecar keys whose strings are never rendered into a file: prose, provenance and how the
# case was chosen (select's rule, as `select` prints it)
UNRENDERED = frozenset({"description", "cube", "selection"})


class TextError(ValueError):
    """A string that would become syntax in an exported file; the message names its field."""


def check_text(value: Any, field: str) -> str:
    """``value`` if it is a string of the strict set (at most :data:`MAX_TEXT` characters),
    else :class:`TextError` naming ``field`` and the first character outside the set."""
    if not isinstance(value, str):
        raise TextError(f"{field} must be text, not {type(value).__name__}")
    if len(value) > MAX_TEXT:
        raise TextError(f"{field} is {len(value)} characters long; at most {MAX_TEXT} are allowed")
    if _TEXT.fullmatch(value) is None:
        bad = _BAD.search(value)
        assert bad is not None
        raise TextError(
            f"{field} holds {bad.group()!r} at character {bad.start() + 1}: only letters, digits, "
            "space and _ . , : + = / @ [ ] - are allowed in text written into a header or program"
        )
    return value


def check_strings(data: Any, field: str) -> None:
    """Every string (values and keys) of a JSON-like document ``data`` held to
    :func:`check_text`, except under the keys of :data:`UNRENDERED`; the error names the
    path of the first offending field (``field.key[3].key``)."""
    if isinstance(data, str):
        check_text(data, field)
    elif isinstance(data, dict):
        for key, value in data.items():
            check_text(key, f"a key of {field}")
            if key not in UNRENDERED:
                check_strings(value, f"{field}.{key}")
    elif isinstance(data, list):
        for i, value in enumerate(data):
            check_strings(value, f"{field}[{i}]")
