"""Fixtures of the export tests: a shop's signing key pair, made as a user makes one."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from ftsweep.cli.main import main


@pytest.fixture(scope="module")
def shop_keys(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(private key, public key) of ``ftsweep keys new -o shop``, shared by a module's tests
    (they sign and verify with it, and change neither file)."""
    folder = tmp_path_factory.mktemp("keys")
    res = CliRunner().invoke(main, ["keys", "new", "-o", str(folder / "shop")])
    assert res.exit_code == 0, res.output
    return folder / "shop.key", folder / "shop.pub"
