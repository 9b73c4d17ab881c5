"""Who made an exported file (docs/architecture.md "Trust": consistency is not origin).

Hashes and CRCs prove that a file agrees with its sidecar; anyone with ftsweep can re-make
them. Two things prove more, and verify says which one it proved:

- **signed by KEY**: export signs what it wrote with an ed25519 key (RFC 8032, through the
  ``cryptography`` library) when one is configured; ``FILE.sig`` beside the file holds the
  signature over the SHA-256 of the file's bytes and of its sidecar's bytes. verify with a
  trusted public key refuses an unsigned file, another key and a wrong signature.
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
import os
import tomllib
from pathlib import Path
from typing import Any

from ftsweep.store.io import (
    MAX_PROGRAM_BYTES,
    MAX_SIDECAR_BYTES,
    ExportError,
    dumps_json,
    read_regular,
    sidecar_path,
    write_texts_atomic,
)

# what a signature covers, in this order; the first line names the scheme
DOMAIN = b"ftsweep export signature v1\n"
MAX_KEY_BYTES = 64 * 2**10


def signature_path(path: Path) -> Path:
    """``FILE.sig`` beside ``FILE`` (``ring.h`` → ``ring.h.sig``)."""
    return path.with_name(path.name + ".sig")


def config_path() -> Path:
    """The config file: ``FTSWEEP_CONFIG``, else ``$XDG_CONFIG_HOME/ftsweep/config.toml``."""
    if os.environ.get("FTSWEEP_CONFIG"):
        return Path(os.environ["FTSWEEP_CONFIG"])
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "ftsweep" / "config.toml"


def _config() -> dict[str, Any]:
    path = config_path()
    if not path.exists():
        return {}
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
    returns both paths and the key's ID. Refuses to replace either file."""
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


def _message(file_sha: str, side_sha: str) -> bytes:
    return DOMAIN + f"file {file_sha}\nsidecar {side_sha}\n".encode("ascii")


def _signature_text(raw_public: bytes, file_sha: str, side_sha: str, signature: bytes) -> str:
    """``FILE.sig`` as export writes it: JSON of the algorithm, key ID, public key, both
    hashes and the signature, indented, one LF at the end."""
    content = {
        "algorithm": "ed25519",
        "key_id": key_id(raw_public),
        "public_key": base64.b64encode(raw_public).decode("ascii"),
        "file_sha256": file_sha,
        "sidecar_sha256": side_sha,
        "signature": base64.b64encode(signature).decode("ascii"),
    }
    return json.dumps(content, indent=2) + "\n"


def sign(path: Path, key_path: Path) -> str:
    """Sign an exported file and its sidecar as they lie on disk with the private key at
    ``key_path``; writes ``FILE.sig`` atomically and returns the key's ID."""
    key = _load(key_path, private=True)
    file_sha = hashlib.sha256(read_regular(path, MAX_PROGRAM_BYTES, "exported file")).hexdigest()
    side_sha = hashlib.sha256(read_regular(sidecar_path(path), MAX_SIDECAR_BYTES, "sidecar")).hexdigest()
    raw = _raw(key.public_key())
    text = _signature_text(raw, file_sha, side_sha, key.sign(_message(file_sha, side_sha)))
    write_texts_atomic({signature_path(path): text})
    return key_id(raw)


def check_signature(path: Path, file_bytes: bytes, side_bytes: bytes, keys: list[Path]) -> str:
    """The ID of the trusted key (one of ``keys``) whose signature ``FILE.sig`` holds over
    these bytes of the file and its sidecar; :class:`ExportError` for an unsigned file, a
    key not trusted, a signature that does not match, or a signature file that is not byte
    for byte what export writes for them."""
    from cryptography.exceptions import InvalidSignature

    sig = signature_path(path)
    if not sig.exists():
        raise ExportError(f"{path} is not signed ({sig.name} is missing) and a trusted key is required")
    text = read_regular(sig, MAX_KEY_BYTES, "signature")
    try:
        content = json.loads(text.decode("ascii"))
        signature = base64.b64decode(content["signature"], validate=True)
        claimed = str(content["key_id"])
    except (ValueError, KeyError, TypeError) as exc:
        raise ExportError(f"{sig}: not an ftsweep signature ({type(exc).__name__})") from None
    trusted = {key_id(_raw(k)): k for k in (_load(p, private=False) for p in keys)}
    if claimed not in trusted:
        raise ExportError(
            f"{path} is signed by key {claimed[:16]!r}, which is not trusted here "
            f"(trusted: {', '.join(sorted(trusted)) or 'none'}); do not load it"
        )
    file_sha, side_sha = hashlib.sha256(file_bytes).hexdigest(), hashlib.sha256(side_bytes).hexdigest()
    try:
        trusted[claimed].verify(signature, _message(file_sha, side_sha))
    except InvalidSignature:
        raise ExportError(
            f"{path}: the signature of key {claimed} does not match the file and its sidecar: one of them "
            "was changed after it was signed; do not load it"
        ) from None
    if text.decode("ascii") != _signature_text(_raw(trusted[claimed]), file_sha, side_sha, signature):
        raise ExportError(f"{sig}: its fields are not the ones export writes for this file; do not load it")
    return claimed


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
