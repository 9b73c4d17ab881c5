"""The synthetic measured part shipped for the guide (catalogs/data/zernike-part.csv) is what
its first lines say: the prediction of the case that cut it plus the machine errors and set-up
of tests/support/measured.py, to 1e-6 nm. `FTSWEEP_REGEN_DOCS=1` rewrites it (after a change
to the model moves the prediction)."""

from __future__ import annotations

import os

import numpy as np
from support import measured as ms
from support.places import REPO

from ftsweep.inputs.measurements import read_measurement


def test_the_shipped_part_is_made_as_its_header_says():
    path = REPO / ms.SHIPPED
    made = ms.shipped_part(ms.shipped_record())
    if os.environ.get("FTSWEEP_REGEN_DOCS"):
        ms.write_cloud(path, made, ms.SHIPPED_NOTE)
    text = path.read_text(encoding="utf-8")
    assert text.startswith("".join(f"# {line}\n" for line in ms.SHIPPED_NOTE.splitlines()))
    shipped = read_measurement(path)
    assert np.array_equal(np.isnan(shipped.z), np.isnan(made[2]))
    assert np.allclose(shipped.z, made[2], atol=1e-9, rtol=0, equal_nan=True)
    assert path.stat().st_size < 100_000  # small
