"""A measured part against its design: the measurement read as it came
(:mod:`ftsweep.inputs.measurements`), registered to the catalog surface over the surface's
aperture (:mod:`ftsweep.stages.measurement`), and its residual — the part's form error —
summarised: P-V and RMS [nm] and its breakdown into Zernike terms (a circular aperture) or
Chebyshev products (a rectangle), each coefficient in nm.

Given the prediction of the program that cut it (a case's error map, model §6), the form
error splits in two: what the prediction explains (the layout, interpolation, cusps, servo:
the predicted error registered as the measurement was) and what it leaves, the machine's
share (its tool, its spindle, its set-up), which a corrected program can take out.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, NamedTuple, Optional

import numpy as np

from ftsweep.inputs import catalogs
from ftsweep.inputs.measurements import Measurement, read_measurement
from ftsweep.stages.measurement import (
    Registration,
    chebyshev_fit,
    register,
    registered_like,
    term_name,
    zernike_basis,
    zernike_fit,
)


class MeasuredPart(NamedTuple):
    """A registered measurement: what was read, the fit, and its summary (the file's hash,
    the fitted terms and their standard errors, P-V, RMS and breakdown in nm)."""

    measurement: Measurement
    registration: Registration
    summary: dict[str, Any]


def measure_part(
    path: Path,
    surface: str,
    catalog_folder: Optional[Path] = None,
    *,
    units: Optional[str] = None,
    pixel_um: Optional[float] = None,
    decentre: bool = True,
    rotation: bool = False,
    power: bool = False,
    terms: int = 15,
) -> MeasuredPart:
    """Read ``path`` and register it to catalog surface ``surface`` (its design and aperture).

    ``units`` and ``pixel_um`` state what the file does not (:func:`read_measurement`);
    ``decentre``, ``rotation``, ``power`` choose the set-up terms fitted besides piston and
    tilt (:func:`ftsweep.stages.measurement.register`); ``terms``: Zernike terms of the
    breakdown (a rectangle takes Chebyshev products up to degree 4)."""
    spec = catalogs.entry("surfaces", surface, catalog_folder)
    design = catalogs.surface_callable(spec, catalog_folder)
    aperture = catalogs.aperture_of(spec)
    measured = read_measurement(path, units=units, pixel_um=pixel_um)
    inside = aperture.contains(measured.x, measured.y)
    fit = register(
        design, measured.x, measured.y, measured.z, inside, decentre=decentre, rotation=rotation, power=power
    )
    rest = fit.residual
    found = {
        "measurement": str(path),
        "sha256": measured.sha256,
        "units": measured.units,
        "surface": surface,
        "points": fit.points,
        "terms": fit.terms,
        "sigma": fit.sigma,
        "pv_nm": pv_nm(rest),
        "rms_nm": rms_nm(rest),
        "breakdown": breakdown(aperture, measured.x, measured.y, rest, terms),
        "alike": alike(design, aperture, measured.x, measured.y, np.isfinite(rest), tuple(fit.terms)),
    }
    return MeasuredPart(measured, fit, found)


def alike(
    design: Any, aperture: Any, x: np.ndarray, y: np.ndarray, use: np.ndarray, names: tuple[str, ...]
) -> dict[str, float]:
    """How much each fitted term beyond piston and tilt looks like a low-order form error:
    the share of its column's variance (∂z/∂term of eq. 1 of
    :mod:`ftsweep.stages.measurement.registration`, at the design) that the breakdown's first
    15 Zernike terms, or Chebyshev products of degree ≤ 4, reproduce. Near 1, the fit cannot
    tell that term from a form error of the same shape: a fitted decentre of a smooth
    freeform may be the machine's error, and the correction then leaves that part in."""
    px, py = x[use], y[use]
    _, fx, fy = design(px, py)
    columns = {
        "decentre_x_um": -fx,
        "decentre_y_um": -fy,
        "rotation_rad": fx * py - fy * px,
        "power_per_um": px * px + py * py,
    }
    if aperture.shape == "circle":
        basis = zernike_basis(px, py, aperture.radius_um, 15)
    else:
        from numpy.polynomial import chebyshev

        u, v = 2 * px / aperture.width_um, 2 * py / aperture.height_um
        basis = chebyshev.chebvander2d(u, v, [4, 4])
    found = {}
    for name in names:
        if name not in columns:
            continue
        col = columns[name] - np.mean(columns[name])
        total = float(col @ col)
        if not total > 1e-24 * col.size:  # a term the design does not show: the fit refuses it
            continue
        coef, *_ = np.linalg.lstsq(basis, col, rcond=None)
        left = col - basis @ coef
        found[name] = 1.0 - float(left @ left) / total
    return found


def pv_nm(heights_um: np.ndarray) -> float:
    """P-V [nm] of heights [µm], missing ones left out."""
    return 1e3 * float(np.nanmax(heights_um) - np.nanmin(heights_um))


def rms_nm(heights_um: np.ndarray) -> float:
    """RMS about the mean [nm] of heights [µm], missing ones left out."""
    return 1e3 * float(np.nanstd(heights_um))


def breakdown(aperture: Any, x: np.ndarray, y: np.ndarray, z: np.ndarray, terms: int) -> list[dict[str, Any]]:
    """The terms of heights ``z`` [µm] over ``aperture``, in nm: Zernike on a circle, Chebyshev
    products (degree 4) on a rectangle."""
    if aperture.shape == "circle":
        coef = zernike_fit(x, y, z, aperture.radius_um, terms)
        return [{"term": term_name(j), "nm": 1e3 * c} for j, c in coef.items()]
    cheb = chebyshev_fit(x, y, z, aperture.width_um, aperture.height_um)
    return [{"term": f"T{i}(u)·T{j}(v)", "nm": 1e3 * c} for (i, j), c in cheb.items()]


def predicted_at(record: Mapping[str, Any], x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """A case's predicted form error [µm] at (x, y) [µm]: its mean error map (a record of a
    case run with ``resolution.error_map_bins``) interpolated bilinearly between bin centres;
    NaN outside the centres or next to an empty bin."""
    if "error_map_mean_nm" not in record:
        raise ValueError("the prediction has no error map: run its case with resolution.error_map_bins")
    from scipy.interpolate import RegularGridInterpolator

    centres = np.asarray(record["error_map_x_um"], dtype=float)
    grid = np.asarray(record["error_map_mean_nm"], dtype=float) * 1e-3  # (y, x) bins
    look = RegularGridInterpolator((centres, centres), grid, bounds_error=False, fill_value=np.nan)
    return np.asarray(look(np.column_stack([y.ravel(), x.ravel()]))).reshape(x.shape)


class Explained(NamedTuple):
    """The form error split: ``explained`` the registered prediction, ``unexplained`` what it
    leaves (µm, on the measurement's points, NaN where either is missing), and the summary."""

    explained: np.ndarray
    unexplained: np.ndarray
    summary: dict[str, Any]


def explain(
    part: MeasuredPart, record: Mapping[str, Any], catalog_folder: Optional[Path] = None, terms: int = 15
) -> Explained:
    """How much of ``part``'s form error the prediction ``record`` (the case that cut it, run
    with an error map) explains: the predicted error at the measured points, registered as the
    measurement was (:func:`ftsweep.stages.measurement.registered_like`), and the rest. The
    form error's variance is the prediction's, the rest's and twice their covariance: the
    shares are the first two over it (the third, 1 less both, is what the two share)."""
    spec = catalogs.entry("surfaces", part.summary["surface"], catalog_folder)
    design, aperture = catalogs.surface_callable(spec, catalog_folder), catalogs.aperture_of(spec)
    m = part.measurement
    said = registered_like(design, m.x, m.y, part.registration, predicted_at(record, m.x, m.y))
    left = part.registration.residual - said
    both = np.isfinite(left)
    total = float(np.var(part.registration.residual[both]))
    # the three breakdowns over the same points (the prediction's map ends half a bin inside
    # the aperture): linear fits, so the form error's terms are the other two's sums
    shared = np.where(both, part.registration.residual, np.nan)
    found = {
        "explained_rms_nm": rms_nm(said),
        "unexplained_rms_nm": rms_nm(left),
        "unexplained_pv_nm": pv_nm(left),
        "explained_share": float(np.var(said[both])) / total if total > 0 else 0.0,
        "unexplained_share": float(np.var(left[both])) / total if total > 0 else 0.0,
        "points": int(both.sum()),
        "form_error_terms": breakdown(aperture, m.x, m.y, shared, terms),
        "explained_terms": breakdown(aperture, m.x, m.y, said, terms),
        "unexplained_terms": breakdown(aperture, m.x, m.y, left, terms),
    }
    return Explained(said, left, found)


def prediction_of(
    *,
    cube: Any = None,
    case: Optional[str] = None,
    program: Optional[Path] = None,
    surface: Optional[str] = None,
    machine: Optional[str] = None,
    cutting: Optional[str] = None,
    bins: int = 32,
) -> tuple[str, dict[str, Any]]:
    """The surface and the prediction (a record with an error map of ``bins`` a side) of what
    cut a part: case ``case`` of cube ``cube`` (its coordinates or number, planned again from
    the cube's recorded entries) or the path program ``program`` in any dialect, read as
    ``ftsweep predict --program`` reads it on catalog surface ``surface``."""
    if (cube is None) == (program is None) or (cube is not None) != (case is not None):
        raise ValueError("the prediction comes from a cube and its case, or from a program")
    if program is not None:
        if surface is None:
            raise ValueError("a program's prediction needs the surface it was cut to (--surface)")
        from ftsweep.exports import nc

        info = nc.predict_program(Path(program), surface, machine, cutting, map_bins=bins)
        return surface, info["record"]
    from ftsweep.simulate import run_case
    from ftsweep.tools.query import find_case
    from ftsweep.tools.select import open_cube, recorded_case

    ds = open_cube(cube)
    found, specs = recorded_case(ds, find_case(ds, str(case)))
    found = found.model_copy(
        update={"resolution": found.resolution.model_copy(update={"error_map_bins": bins})}
    )
    return found.surface, run_case(found, specs=specs)


def gridded(measured: Measurement) -> tuple[np.ndarray, tuple[float, float], tuple[float, float]]:
    """A measurement's heights on its regular grid: (z [µm] of shape (ny, nx), (dx, dy),
    (x0, y0) [µm] of element [0, 0]); a map is one already, a point cloud must be one (every
    x of a set of evenly spaced columns with every y of a set of evenly spaced rows, in any
    order). A ValueError says where a point cloud is not."""
    x, y, z = (np.asarray(a, dtype=float).ravel() for a in (measured.x, measured.y, measured.z))
    xs, ys = np.unique(x), np.unique(y)
    if xs.size < 4 or ys.size < 4 or xs.size * ys.size != x.size:
        raise ValueError(
            f"the {x.size:,} points are no regular grid ({xs.size:,} distinct x by {ys.size:,} distinct y)"
        )
    steps = (np.diff(xs), np.diff(ys))
    for axis, step in zip("xy", steps, strict=True):
        if np.ptp(step) > 1e-6 * np.mean(step):
            raise ValueError(
                f"the points' {axis} values are not evenly spaced ({step.min():g} to {step.max():g} µm)"
            )
    grid = np.full((ys.size, xs.size), np.nan)
    grid[np.searchsorted(ys, y), np.searchsorted(xs, x)] = z
    return grid, (float(np.mean(steps[0])), float(np.mean(steps[1]))), (float(xs[0]), float(ys[0]))


def as_height_map(measured: Measurement, folder: Path, name: str, like: Any) -> dict[str, Any]:
    """A measured (or measured-and-corrected) surface as a catalog design: its grid
    (:func:`gridded`) saved as ``folder/name.npy`` and the ``height_map`` entry that reads it
    (aperture and layout those of catalog entry ``like``), for planning a cut to a measured
    master as to any design: tool paths from point-cloud data ([6]). Missing heights are
    refused: a design is defined everywhere."""
    grid, spacing, origin = gridded(measured)
    if not np.isfinite(grid).all():
        raise ValueError(
            f"{int((~np.isfinite(grid)).sum()):,} heights are missing: a design is defined everywhere"
        )
    np.save(Path(folder) / f"{name}.npy", grid)
    return {
        "description": f"Measured surface {measured.sha256[:12]} as a height map.",
        "family": "height_map",
        "layout": like.layout,
        "aperture": like.aperture.model_dump(mode="json"),
        "params": {"path": f"{name}.npy", "spacing_um": list(spacing), "origin_um": list(origin)},
    }
