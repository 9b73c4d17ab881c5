"""``ftsweep keys``: the ed25519 key pairs export signs with and verify trusts
(:mod:`ftsweep.exports.origin`)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import click


@click.group("keys")
def keys() -> None:
    """Make the ed25519 key pair export signs with and verify trusts.

    \b
    A shop keeps the private key (NAME.key, mode 0600) on the machine that exports, named by
    --sign-key, FTSWEEP_SIGNING_KEY or signing_key in the config file
    ($XDG_CONFIG_HOME/ftsweep/config.toml, or FTSWEEP_CONFIG); the public key (NAME.pub) goes
    to every machine that verifies, named by --trusted-key or trusted_keys there.
    """


@keys.command("new")
@click.option(
    "-o",
    "--output",
    "stem",
    default=None,
    type=click.Path(dir_okay=False),
    help="Name of the pair: writes NAME.key (private) and NAME.pub (public); never replaces a key. "
    "Default: ftsweep-signing in the user's ftsweep config folder ($XDG_CONFIG_HOME/ftsweep/keys). "
    "A folder that gets its first private key gets a .gitignore that keeps *.key out of git.",
)
def keys_new(stem: Optional[str]) -> None:
    """Make a new ed25519 key pair (NAME.key, NAME.pub) and print its key ID."""
    from ftsweep.errors import ExportError
    from ftsweep.exports.origin import config_dir, new_keys

    try:
        private, public, ident = new_keys(Path(stem) if stem else config_dir() / "keys" / "ftsweep-signing")
    except ExportError as exc:
        raise click.ClickException(str(exc)) from None
    click.echo(f"private key  {private} (mode 0600: keep it on the exporting machine only)")
    click.echo(f"public key   {public} (give it to every machine that verifies)")
    click.echo(f"key ID       {ident}")
