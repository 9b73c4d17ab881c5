"""The corrected cut: a new target made from the design and the part's unexplained error (what
the prediction of its program does not explain: the machine's share,
:func:`ftsweep.tools.measure.explain`), planned with the same case, and its residual predicted
before it is cut.

The correction is the unexplained error low-passed and scaled by a gain g:

    target = design − g·L(U)                                                        (1)

L keeps the unexplained error's first ``terms`` Zernike terms (a circle; Chebyshev products
of degree ≤ 4 on a rectangle) less piston and tilt, which the set-up gives anyway. A Zernike
term of radial order n varies on a length of about 2R/n over an aperture of radius R, so
``terms`` is the low-pass: keep it to orders whose length is many of the layout's pitches,
which the servo and the table can follow. The target is a height map (the ``height_map``
family) on a grid of ``grid`` points a side over the aperture and a margin, in a private copy
of the catalogs, and the case is planned on it as on any surface.

The residual the corrected program is predicted to leave, registered as the measurement was:
its own predicted error, plus what (1) moved from the design, plus the machine's error (the
unexplained part, taken as repeatable): P' − g·L(U) + U.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any, NamedTuple, Optional

import numpy as np
import yaml

from ftsweep.engine.case import Case
from ftsweep.inputs import catalogs
from ftsweep.stages.measurement import registered_like, zernike_basis
from ftsweep.tools.measure import Explained, MeasuredPart, predicted_at


class Correction(NamedTuple):
    """The corrected case (its surface the target, in ``catalog_folder``), its prediction and
    the summary: gain, filter, the residual's RMS before and after [nm]."""

    case: Case
    catalog_folder: Path
    record: dict[str, Any]
    summary: dict[str, Any]


def low_pass(aperture: Any, x: np.ndarray, y: np.ndarray, u: np.ndarray, terms: int) -> Any:
    """L of (1): a function (x, y) → µm, the first ``terms`` Zernike terms of ``u`` [µm] but
    piston and tilt (Chebyshev products of degree ≤ 4 on a rectangle, but T0·T0, T1·T0, T0·T1)."""
    from ftsweep.stages.measurement import chebyshev_fit, zernike_fit

    if aperture.shape == "circle":
        coef = zernike_fit(x, y, u, aperture.radius_um, terms)
        kept = np.array([0.0 if j <= 3 else c for j, c in coef.items()])

        def zernike_part(px: np.ndarray, py: np.ndarray) -> np.ndarray:
            basis = zernike_basis(px.ravel(), py.ravel(), aperture.radius_um, terms)
            return np.asarray(basis @ kept).reshape(px.shape)

        return zernike_part
    from numpy.polynomial import chebyshev

    cheb = chebyshev_fit(x, y, u, aperture.width_um, aperture.height_um)
    grid = np.zeros((5, 5))
    for (i, j), c in cheb.items():
        grid[i, j] = 0.0 if i + j <= 1 else c
    return lambda px, py: chebyshev.chebval2d(2 * px / aperture.width_um, 2 * py / aperture.height_um, grid)


def correct(
    part: MeasuredPart,
    split: Explained,
    case: Case,
    record: dict[str, Any],
    folder: Path,
    *,
    gain: float = 1.0,
    terms: int = 15,
    grid: int = 201,
    catalog_folder: Optional[Path] = None,
) -> Correction:
    """The corrected case of ``case`` (the one that cut ``part``, predicted as ``record``): its
    target (1) written as a height map into a catalog copy under ``folder``, planned and
    predicted with an error map of ``record``'s bins; its predicted residual against the
    uncorrected one."""
    if not 0.0 < gain <= 1.5:
        raise ValueError(f"gain {gain}: a correction's gain lies in (0, 1.5]")
    spec = catalogs.entry("surfaces", case.surface, catalog_folder)
    design = catalogs.surface_callable(spec, catalog_folder)
    aperture = catalogs.aperture_of(spec)
    m = part.measurement
    use = np.isfinite(split.unexplained)
    lp = low_pass(aperture, m.x[use], m.y[use], split.unexplained[use], terms)
    name = f"{case.surface}-corrected"
    cats = _target_catalog(folder, name, spec, design, aperture, lp, gain, grid, catalog_folder)
    corrected = case.model_copy(update={"surface": name})
    from ftsweep.simulate import run_case

    after_record = run_case(corrected, cats)
    after_pred = registered_like(design, m.x, m.y, part.registration, predicted_at(after_record, m.x, m.y))
    after = after_pred - gain * lp(m.x, m.y) + split.unexplained
    before = split.explained + split.unexplained
    found = {
        "gain": gain,
        "filter_terms": terms,
        "surface": name,
        "measurement_sha256": part.summary["sha256"],
        "residual_before_rms_nm": 1e3 * float(np.nanstd(before)),
        "residual_after_rms_nm": 1e3 * float(np.nanstd(after)),
        "residual_before_pv_nm": 1e3 * float(np.nanmax(before) - np.nanmin(before)),
        "residual_after_pv_nm": 1e3 * float(np.nanmax(after) - np.nanmin(after)),
    }
    return Correction(corrected, cats, after_record, found)


def _target_catalog(
    folder: Path,
    name: str,
    spec: Any,
    design: Any,
    aperture: Any,
    lp: Any,
    gain: float,
    grid: int,
    catalog_folder: Optional[Path],
) -> Path:
    """A copy of the catalogs under ``folder`` with surface ``name``: the target (1) on a grid
    over the aperture and a 5 % margin, as a ``height_map``."""
    cats = folder / "catalogs"
    shutil.copytree(catalog_folder or catalogs.catalog_dir(), cats)
    half_w, half_h = aperture.half_extent_um
    xs, ys = (
        np.linspace(-1.05 * half_w, 1.05 * half_w, grid),
        np.linspace(-1.05 * half_h, 1.05 * half_h, grid),
    )
    gx, gy = np.meshgrid(xs, ys)
    target = design(gx, gy)[0] - gain * lp(gx, gy)
    np.save(cats / f"{name}.npy", target)
    entry = {
        name: {
            "description": f"{spec.description} Corrected by a measurement (gain {gain}).",
            "family": "height_map",
            "layout": spec.layout,
            "aperture": _aperture_entry(aperture),
            "params": {
                "path": f"{name}.npy",
                "spacing_um": [float(xs[1] - xs[0]), float(ys[1] - ys[0])],
                "origin_um": [float(xs[0]), float(ys[0])],
            },
        }
    }
    with (cats / "surfaces.yaml").open("a") as fh:
        fh.write("\n" + yaml.safe_dump(entry, allow_unicode=True))
    return cats


def _aperture_entry(aperture: Any) -> dict[str, Any]:
    if aperture.shape == "circle":
        return {"shape": "circle", "radius_um": float(aperture.radius_um)}
    return {
        "shape": "rectangle",
        "width_um": float(aperture.width_um),
        "height_um": float(aperture.height_um),
    }
