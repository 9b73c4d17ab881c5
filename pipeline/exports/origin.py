"""Who made an exported file (docs/architecture.md "Trust": consistency is not origin).

Hashes and CRCs prove that a file agrees with its sidecar; anyone with ftsweep can re-make
them. Two things prove more, and verify says which one it proved:

- **signed by KEY**: export signs what it wrote with an ed25519 key (RFC 8032, through the
  ``cryptography`` library) when one is configured. ``FILE.sig`` beside the file holds a
  signed statement (:func:`statement`, after TUF's signed target metadata) that names the
  file, its length and SHA-256, its sidecar's SHA-256, the cube and case, surface, machine,
  cutting, compensation, dialect, points and predicted P-V, the ftsweep version, the time
  of signing and an optional expiry. verify with a trusted public key refuses an unsigned
  file, another key, a wrong signature, a file under another name than it was signed as, an
  expired statement and a statement of the older scheme that named none of these.
- **consistent with this catalog**: without a trusted key, the catalog entries a sidecar
  recorded (surface, machine, cutting) must equal the local catalog's entries of the same
  names; a difference is refused naming the field (``--accept-recorded`` verifies against
  the recorded entries instead, and says so).

Keys are files: ``ftsweep keys new -o NAME`` writes ``NAME.key`` (PKCS#8 PEM, mode 0600) and
``NAME.pub`` (SubjectPublicKeyInfo PEM). The signing key comes from ``--sign-key``, else
``FTSWEEP_SIGNING_KEY`` (a path), else ``signing_key`` of the config file; trusted keys from
``--trusted-key``, else ``trusted_keys`` of the config file (``FTSWEEP_CONFIG``, default
``$XDG_CONFIG_HOME/ftsweep/config.toml``).
"""

from __future__ import annotations

import base64
import hashlib
import json
import math
import os
import re
import stat
import sys
import tomllib
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from ftsweep.errors import ExportError
from ftsweep.store.io import (
    MAX_PROGRAM_BYTES,
    MAX_SIDECAR_BYTES,
    dumps_json,
    read_regular,
    read_sidecar,
    sidecar_path,
    write_texts_atomic,
)

# what a signature covers: this line, then the statement as canonical JSON
SCHEME = "ftsweep export statement v4"
DOMAIN = SCHEME.encode("ascii") + b"\n"
MAX_KEY_BYTES = 64 * 2**10
TIME_FORMAT = "%Y-%m-%dT%H:%M:%SZ"


def signature_path(path: Path) -> Path:
    """``FILE.sig`` beside ``FILE`` (``ring.h`` → ``ring.h.sig``)."""
    return path.with_name(path.name + ".sig")


def config_dir() -> Path:
    """The user's ftsweep config folder: ``$XDG_CONFIG_HOME/ftsweep`` (else ``~/.config/ftsweep``)."""
    return Path(os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")) / "ftsweep"


def config_path() -> Path:
    """The config file: ``FTSWEEP_CONFIG``, else ``$XDG_CONFIG_HOME/ftsweep/config.toml``."""
    if os.environ.get("FTSWEEP_CONFIG"):
        return Path(os.environ["FTSWEEP_CONFIG"])
    return config_dir() / "config.toml"


def _config() -> dict[str, Any]:
    path = config_path()
    if not path.exists():
        return {}
    # whoever can change the config chooses the keys trusted and the key that signs
    warn_if_exposed(path, "config file", 0o022)
    try:
        data = tomllib.loads(read_regular(path, MAX_KEY_BYTES, "config file").decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ExportError(f"{path}: not a TOML config file ({str(exc)[:120]})") from None
    unknown = sorted(set(data) - {"signing_key", "trusted_keys"})
    if unknown:
        raise ExportError(f"{path}: unknown key {unknown[0]!r}; known: signing_key, trusted_keys")
    return data


def signing_key(option: str | None) -> Path | None:
    """The signing key's path: ``option``, else ``FTSWEEP_SIGNING_KEY``, else the config
    file's ``signing_key``; None when none is configured (export does not sign)."""
    chosen = option or os.environ.get("FTSWEEP_SIGNING_KEY") or _config().get("signing_key")
    return Path(chosen) if chosen else None


def trusted_keys(options: tuple[str, ...]) -> list[Path]:
    """The trusted public keys: ``options``, else the config file's ``trusted_keys``."""
    if options:
        return [Path(p) for p in options]
    listed = _config().get("trusted_keys", [])
    if not isinstance(listed, list) or not all(isinstance(p, str) for p in listed):
        raise ExportError(f"{config_path()}: trusted_keys must be a list of paths")
    return [Path(p) for p in listed]


def new_keys(stem: Path) -> tuple[Path, Path, str]:
    """A new ed25519 key pair written as ``STEM.key`` (private, mode 0600) and ``STEM.pub``;
    returns both paths and the key's ID. Refuses to replace either file. A folder without a
    ``.gitignore`` gets one that ignores ``*.key``, so a private key made inside a clone (the
    guide's ``secure/``) is never committed by default."""
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

    key_file, pub_file = stem.with_name(stem.name + ".key"), stem.with_name(stem.name + ".pub")
    for path in (key_file, pub_file):
        if path.exists():
            raise ExportError(f"{path} exists; a key is never replaced: choose another name")
    private = Ed25519PrivateKey.generate()
    pem = private.private_bytes(
        serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
    )
    public = private.public_key().public_bytes(
        serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo
    )
    key_file.parent.mkdir(parents=True, exist_ok=True)
    ignore = key_file.parent / ".gitignore"
    if not ignore.exists():
        note = b"# private signing keys (ftsweep keys new) stay out of version control\n*.key\n"
        write_texts_atomic({ignore: note})
    old = os.umask(0o077)  # the private key is written readable by its owner only
    try:
        write_texts_atomic({key_file: pem, pub_file: public})
    finally:
        os.umask(old)
    os.chmod(pub_file, 0o644)
    return key_file, pub_file, key_id(_raw(private.public_key()))


def _raw(public: Any) -> bytes:
    from cryptography.hazmat.primitives import serialization

    return bytes(public.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw))


def key_id(raw_public: bytes) -> str:
    """A key's ID: the first 16 hex digits of the SHA-256 of its 32 raw bytes."""
    return hashlib.sha256(raw_public).hexdigest()[:16]


def _load(path: Path, private: bool) -> Any:
    from cryptography.hazmat.primitives import serialization
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey

    if private:
        warn_if_exposed(path, "private key", 0o077)
    data = read_regular(path, MAX_KEY_BYTES, "key file")
    key: Any
    try:
        if private:
            key = serialization.load_pem_private_key(data, password=None)
        else:
            key = serialization.load_pem_public_key(data)
    except (ValueError, TypeError) as exc:
        raise ExportError(f"{path}: not a PEM {'private' if private else 'public'} key ({exc})") from None
    wanted = Ed25519PrivateKey if private else Ed25519PublicKey
    if not isinstance(key, wanted):
        raise ExportError(f"{path}: not an ed25519 key (make one with `ftsweep keys new`)")
    return key


def _now() -> datetime:
    """The time signatures are made and judged at (UTC): one place, so tests can move it."""
    return datetime.now(UTC)


def case_name_of(selection: dict[str, Any]) -> str | None:
    """A recorded selection's case named by its coordinates (``points=950000 aspect=16``):
    its ``<axis>_target`` values in their recorded order; None where it records none."""
    from ftsweep.store.values import case_name

    targets = {
        k[: -len("_target")]: v
        for k, v in selection.items()
        if k.endswith("_target") and isinstance(v, (int, float, str)) and not isinstance(v, bool)
    }
    return case_name(targets) if targets else None


def purpose(meta: dict[str, Any]) -> dict[str, Any]:
    """What an exported file is for, from its sidecar ``meta`` (read by
    :func:`~ftsweep.store.io.read_sidecar`): the cube and case it was exported from (its case
    number, which growth never changes, and its name by coordinates, :func:`case_name_of`;
    None for a study's program), surface, machine, cutting, compensation, dialect (``header``
    for a C table, ``text`` for ftsweep's lines), points and the predicted P-V [nm] of the
    file as written."""
    raw = meta.get("selection")
    selection: dict[str, Any] = raw if isinstance(raw, dict) else {}
    raw = meta.get("case") if isinstance(meta.get("case"), dict) else meta.get("inputs")
    case: dict[str, Any] = raw if isinstance(raw, dict) else {}
    index = selection.get("index")
    points = meta.get("n_points", selection.get("n_points"))
    return {
        "cube": meta.get("cube"),
        "case": index if isinstance(index, int) and not isinstance(index, bool) else None,
        "case_name": case_name_of(selection),
        **entry_names(meta),
        "compensation": meta.get("compensation", case.get("compensation")),
        "dialect": meta.get("dialect") or ("header" if "header" in meta else "text"),
        "points": points if isinstance(points, int) and not isinstance(points, bool) else None,
        "pv_nm": meta.get("pv_nm_as_written", meta.get("pv_nm")),
        **measured_by(meta, case),
    }


def measured_by(meta: dict[str, Any], case: dict[str, Any]) -> dict[str, Any]:
    """``{"measurement": {...}}`` for a file planned on a measured correction (its surface
    entry's ``correction``, :mod:`ftsweep.inputs.corrections`): the measurement's SHA-256, the
    gain and terms the case used and the registration's fit; ``{}`` for any other file (so
    the statements of other files are as they were). Read from an untrusted sidecar: only a
    64-digit hex digest and finite numbers are taken."""
    entries = meta.get("catalog_entries")
    entry = entries.get("surface") if isinstance(entries, dict) else None
    block = entry.get("correction") if isinstance(entry, dict) else None
    if not isinstance(block, dict):
        return {}
    digest = block.get("measurement_sha256")
    if not (isinstance(digest, str) and re.fullmatch(r"[0-9a-f]{64}", digest)):
        raise ExportError("the sidecar's measured correction names no SHA-256 of its measurement")
    raw = block.get("fit")
    fit: dict[Any, Any] = raw if isinstance(raw, dict) else {}
    gain = _number(case.get("correction_gain") or block.get("gain"))
    terms = _number(case.get("correction_terms") or block.get("terms"))
    if gain is None or terms is None:
        raise ExportError("the sidecar's measured correction states no gain or terms")
    named = {str(k)[:40]: _number(v) for k, v in list(fit.items())[:8]}
    return {"measurement": {"sha256": digest, "gain": gain, "terms": terms, "fit": named}}


def _number(value: Any) -> float | None:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    return float(value) if ok else None


def statement(
    name: str, file_bytes: bytes, side_bytes: bytes, meta: dict[str, Any], stamp: dict[str, Any]
) -> dict[str, Any]:
    """The statement export signs for a file named ``name`` with these bytes and this sidecar
    (its bytes and content ``meta``): the file's name, length [bytes] and SHA-256, the
    sidecar's SHA-256, :func:`purpose`, and ``stamp``: the ftsweep version, ``signed_at`` and
    ``expires`` (UTC, :data:`TIME_FORMAT`; ``expires`` None for none)."""
    return {
        "file": name,
        "length": len(file_bytes),
        "sha256": hashlib.sha256(file_bytes).hexdigest(),
        "sidecar_sha256": hashlib.sha256(side_bytes).hexdigest(),
        **purpose(meta),
        # where it was planned: verify allows one unit across platforms only on a signed platform
        "platform": meta.get("platform"),
        # its place in the cube's export ledger: the name and sequence number it was exported as
        "ledger": meta.get("ledger"),
        "ftsweep": stamp.get("ftsweep"),
        "signed_at": stamp.get("signed_at"),
        "expires": stamp.get("expires"),
    }


def _message(content: dict[str, Any]) -> bytes:
    """The bytes a signature covers: the scheme's line, then the statement as canonical JSON."""
    return DOMAIN + json.dumps(content, sort_keys=True, separators=(",", ":")).encode("ascii")


def _signature_text(raw_public: bytes, content: dict[str, Any], signature: bytes) -> str:
    """``FILE.sig`` as export writes it: JSON of the scheme, algorithm, key ID, public key, the
    statement and the signature, indented, one LF at the end."""
    document = {
        "scheme": SCHEME,
        "algorithm": "ed25519",
        "key_id": key_id(raw_public),
        "public_key": base64.b64encode(raw_public).decode("ascii"),
        "statement": content,
        "signature": base64.b64encode(signature).decode("ascii"),
    }
    return json.dumps(document, indent=2) + "\n"


def sign(path: Path, key_path: Path, expires: datetime | None = None) -> str:
    """Sign an exported file and its sidecar as they lie on disk with the private key at
    ``key_path``: the :func:`statement` of them, signed now and valid until ``expires``
    (None: no expiry); writes ``FILE.sig`` atomically and returns the key's ID."""
    from ftsweep.version import __version__

    key = _load(key_path, private=True)
    file_bytes = read_regular(path, MAX_PROGRAM_BYTES, "exported file")
    side_bytes = read_regular(sidecar_path(path), MAX_SIDECAR_BYTES, "sidecar")
    meta = read_sidecar(path, side_bytes)  # as verify will read it
    now = _now()
    if expires is not None and expires <= now:
        raise ExportError(f"--expires {expires.strftime(TIME_FORMAT)} has passed; nothing signed")
    stamp = {
        "ftsweep": __version__,
        "signed_at": now.strftime(TIME_FORMAT),
        "expires": None if expires is None else expires.astimezone(UTC).strftime(TIME_FORMAT),
    }
    content = statement(path.name, file_bytes, side_bytes, meta, stamp)
    raw = _raw(key.public_key())
    write_texts_atomic({signature_path(path): _signature_text(raw, content, key.sign(_message(content)))})
    return key_id(raw)


def check_signature(
    path: Path, file_bytes: bytes, side_bytes: bytes, meta: dict[str, Any], keys: list[Path]
) -> dict[str, Any]:
    """The signed statement of ``FILE.sig`` with the ID of the trusted key (one of ``keys``)
    that signed it (``key_id``); :class:`ExportError` for an unsigned file, a key not trusted,
    a signature that does not match, a statement of the older scheme, a statement that is
    not the one of these bytes under this name (a renamed or swapped file: the first field
    that differs is named), an expired statement, or a signature file that is not byte for
    byte what export writes."""
    from cryptography.exceptions import InvalidSignature

    sig = signature_path(path)
    if not sig.exists():
        raise ExportError(f"{path} is not signed ({sig.name} is missing) and a trusted key is required")
    text = read_regular(sig, MAX_KEY_BYTES, "signature")
    content, signature, claimed = _signed_parts(sig, text)
    trusted = {key_id(_raw(k)): k for k in (_load(p, private=False) for p in keys)}
    if claimed not in trusted:
        raise ExportError(
            f"{path} is signed by key {claimed[:16]!r}, which is not trusted here "
            f"(trusted: {', '.join(sorted(trusted)) or 'none'}); do not load it"
        )
    try:
        trusted[claimed].verify(signature, _message(content))
    except InvalidSignature:
        raise ExportError(
            f"{path}: the signature of key {claimed} does not match its statement: {sig.name} was changed "
            "after it was signed; do not load it"
        ) from None
    if text.decode("ascii") != _signature_text(_raw(trusted[claimed]), content, signature):
        raise ExportError(f"{sig}: its fields are not the ones export writes for this file; do not load it")
    _check_statement(path, content, statement(path.name, file_bytes, side_bytes, meta, content))
    return {**content, "key_id": claimed}


def _signed_parts(sig: Path, text: bytes) -> tuple[dict[str, Any], bytes, str]:
    """The statement, signature and claimed key ID of a signature file of this scheme."""
    try:
        document = json.loads(text.decode("ascii"))
        if not isinstance(document, dict):
            raise TypeError("not an object")
    except (ValueError, TypeError) as exc:
        raise ExportError(f"{sig}: not an ftsweep signature ({type(exc).__name__})") from None
    if document.get("scheme") != SCHEME:
        raise ExportError(
            f"{sig}: a signature of an older scheme, which names no file, case or expiry: export the "
            "file again to sign a statement of what it is for"
        )
    try:
        signature = base64.b64decode(document["signature"], validate=True)
        claimed, content = str(document["key_id"]), document["statement"]
        if not isinstance(content, dict):
            raise TypeError("the statement is not an object")
    except (ValueError, KeyError, TypeError) as exc:
        raise ExportError(f"{sig}: not an ftsweep signature ({type(exc).__name__})") from None
    return content, signature, claimed


def _check_statement(path: Path, signed: dict[str, Any], found: dict[str, Any]) -> None:
    """Refuse a file whose signed statement is not the one of the file as found (its name
    first: a renamed file), or whose statement has expired."""
    if signed.get("file") != found["file"]:
        raise ExportError(
            f"{path}: signed as {str(signed.get('file'))[:80]!r}, not {found['file']!r}: a renamed or "
            "copied file is not the file that was signed; do not load it"
        )
    differ = [k for k in found if signed.get(k) != found[k]] + [k for k in signed if k not in found]
    if differ:
        raise ExportError(
            f"{path}: the signed statement's {differ[0]} is {str(signed.get(differ[0]))[:80]!r}, the file "
            f"and its sidecar give {str(found.get(differ[0]))[:80]!r}; do not load it"
        )
    if signed["expires"] is not None:
        try:
            until = datetime.strptime(str(signed["expires"]), TIME_FORMAT).replace(tzinfo=UTC)
        except ValueError:
            raise ExportError(
                f"{path}: the signed expiry {str(signed['expires'])[:40]!r} is not a time"
            ) from None
        if _now() >= until:
            raise ExportError(
                f"{path}: its signature expired at {signed['expires']} (signed at {signed['signed_at']}); "
                "export it again for a new signature; do not load it"
            )


_WARNED: set[tuple[Path, int]] = set()


def warn_if_exposed(path: Path, what: str, bits: int) -> None:
    """One line on stderr when the file at ``path`` grants others ``bits`` of its mode (a
    private key readable, a config file writable by group or others), naming the fix."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return
    if mode & bits and (path, bits) not in _WARNED:
        _WARNED.add((path, bits))
        sys.stderr.write(
            f"warning: {what} {path} is {stat.filemode(mode)}: others can "
            f"{'read' if bits & 0o044 else 'change'} it; chmod {'600' if bits & 0o044 else 'go-w'} {path}\n"
        )


def entry_names(meta: dict[str, Any]) -> dict[str, str]:
    """The catalog entry names a sidecar used: its case's, or its study's inputs'."""
    source = meta.get("case") if isinstance(meta.get("case"), dict) else meta.get("inputs")
    if not isinstance(source, dict):
        raise ExportError("the sidecar names no case and no study inputs")
    return {key: str(source.get(key)) for key in ("surface", "machine", "cutting")}


def check_catalog(meta: dict[str, Any], side: Path, folder: Path | None = None) -> str:
    """Refuse a sidecar whose recorded entries differ from the local catalog's entries of the
    same names (``folder``, default the catalog in use), naming the first field that does;
    returns the catalog folder compared with."""
    from ftsweep.inputs.catalogs import CatalogError, catalog_dir, entry
    from ftsweep.inputs.trust import first_difference

    folder = folder or catalog_dir()
    names = entry_names(meta)
    recorded = meta.get("catalog_entries")
    if not isinstance(recorded, dict):
        raise ExportError(f"{side}: no recorded catalog entries")
    for key, kind in (("surface", "surfaces"), ("machine", "machines"), ("cutting", "cutting")):
        try:
            local = entry(kind, names[key], folder).model_dump(mode="json")
        except CatalogError as exc:
            raise ExportError(
                f"{side}: {exc}; give --accept-recorded to verify against the recorded entries"
            ) from None
        found = first_difference(recorded.get(key), json.loads(dumps_json(local)), f"{key} '{names[key]}'")
        if found:
            raise ExportError(
                f"{side}: the recorded entry differs from the local catalog ({folder}): {found}; the file "
                "was made from another catalog, or its sidecar was re-made: give --accept-recorded to verify "
                "against the recorded entries, or --trusted-key to prove who exported it"
            )
    return str(folder)


def signed(
    out: Path, key: Path | None, meta: dict[str, Any], expires: datetime | None = None
) -> dict[str, Any]:
    """``meta`` of a file a study just wrote in place, after signing it with ``key`` (valid
    until ``expires``; ``signature`` then holds the key's ID) or, with no key, removing a
    signature left by an earlier export."""
    if key is None:
        signature_path(out).unlink(missing_ok=True)
        return meta
    return {**meta, "signature": sign(out, key, expires)}
