"""The ledger of a cube's exports (docs/architecture.md "Trust"): every export of a cube
appends an entry under ``_exports/<file name>/<sequence>.json`` — its sequence number for that
name, the SHA-256 of the file and of its sidecar, when — created only if absent (``O_EXCL``
locally, a conditional PUT on object storage), so entries are never rewritten. The sidecar
and the signed statement carry the sequence; verify refuses a file that is not the latest
export of its name while the cube is reachable (a rolled-back file, as TUF refuses metadata
older than the version it recorded) and says when it is not. Entries are read back as
untrusted data: capped, JSON, every field checked."""

from __future__ import annotations

import json
import re
from typing import Any, Optional

from ftsweep.store.storage import Place, StorageError

LEDGER = "_exports"
# an entry is a few hundred bytes: a larger object is not one export wrote
MAX_ENTRY_BYTES = 64 * 1024
_SEQUENCE = re.compile(r"^(\d{8})\.json$")


class LedgerError(ValueError):
    """The ledger cannot record an export, or refuses a file that is not the latest."""


def _folder(name: str) -> str:
    return f"{LEDGER}/{name}"


def sequences(at: Place, name: str) -> list[int]:
    """The sequence numbers recorded for exports named ``name``, ascending."""
    found = []
    for key in at.listing(_folder(name)):
        m = _SEQUENCE.match(key.rsplit("/", 1)[-1])
        if m:
            found.append(int(m.group(1)))
    return sorted(found)


def next_sequence(at: Place, name: str) -> int:
    """The sequence number the next export named ``name`` takes (1 for the first)."""
    recorded = sequences(at, name)
    return recorded[-1] + 1 if recorded else 1


def record(at: Place, name: str, sequence: int, entry: dict[str, Any]) -> None:
    """Append export ``sequence`` of ``name``: created only if no entry holds that number
    (another export took it: :class:`LedgerError`, and nothing should be published)."""
    key = f"{_folder(name)}/{sequence:08d}.json"
    body = json.dumps({"name": name, "sequence": sequence, **entry}, sort_keys=True).encode("ascii")
    try:
        at.create(key, body)
    except FileExistsError:
        raise LedgerError(
            f"another export of {name} took sequence {sequence} in the cube's ledger meanwhile; export again"
        ) from None
    except (OSError, StorageError) as exc:
        raise LedgerError(f"the cube's export ledger cannot be written ({exc}); nothing exported") from None


def entry(at: Place, name: str, sequence: int) -> Optional[dict[str, Any]]:
    """The recorded entry of export ``sequence`` of ``name``, checked (None if absent)."""
    try:
        raw = at.read_capped(f"{_folder(name)}/{sequence:08d}.json", MAX_ENTRY_BYTES)
        data = json.loads(raw.decode("ascii"))
    except FileNotFoundError:
        return None
    except (ValueError, UnicodeDecodeError) as exc:
        raise LedgerError(f"the ledger entry {sequence} of {name} is not one export writes ({exc})") from None
    ok = (
        isinstance(data, dict)
        and data.get("name") == name
        and data.get("sequence") == sequence
        and all(isinstance(data.get(k), str) for k in ("sha256", "sidecar_sha256", "created"))
    )
    number = data.get("case") if isinstance(data, dict) else None
    if ok and number is not None:  # the case exported (entries written before it name none)
        ok = isinstance(number, int) and not isinstance(number, bool) and number >= 0
    if not ok:
        raise LedgerError(f"the ledger entry {sequence} of {name} is not one export writes")
    return data


def carry(src: Place, dst: Place) -> int:
    """Copy every entry of ``src``'s ledger into ``dst``, each created only if absent there (a
    repeat after a kill adds what is missing): a cube rebuilt in ``src``'s place (growth,
    :mod:`ftsweep.sweeps.grow`) keeps the record of every export of it, and verify's rollback
    check with it. An object that is no ledger entry (over the cap, a special file) is left
    behind. Returns the entries copied."""
    copied = 0
    for key in src.listing(LEDGER):
        try:
            dst.create(key, src.read_capped(key, MAX_ENTRY_BYTES))
            copied += 1
        except FileExistsError:
            continue
        except ValueError:  # not an entry export writes: nothing of the record is lost
            continue
    return copied


def latest_case(at: Place) -> Optional[tuple[int, str]]:
    """The case number of the cube's most recent export (by its entry's time, then sequence)
    and the file's name, or None where no export recorded a case. An unreadable entry is no
    export here: this names a default, it judges nothing."""
    found: list[tuple[str, int, str, int]] = []
    for key in at.listing(LEDGER):
        parts = key.split("/")
        m = _SEQUENCE.match(parts[-1])
        if len(parts) != 3 or m is None:
            continue
        try:
            data = entry(at, parts[1], int(m.group(1)))
        except LedgerError:
            continue
        if data is not None and data.get("case") is not None:
            found.append((data["created"], data["sequence"], parts[1], data["case"]))
    if not found:
        return None
    _, _, name, number = max(found)
    return number, name
