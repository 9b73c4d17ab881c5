"""The corrected cut: a new target made from the design and the part's unexplained error (what
the prediction of its program does not explain: the machine's share,
:func:`ftsweep.tools.measure.explain`), planned with the same case, and its residual predicted
before it is cut.

The target is the design less a gain g times the unexplained error low-passed to its first N
terms but piston and tilt (eq. 1 of :mod:`ftsweep.inputs.corrections`): a surface entry
``<surface>-corrected`` with a ``correction`` block, written into a copy of the catalogs, so
every cube and file planned on it names the measurement (its SHA-256) and the fit. A sweep of
the case over ``correction_gain`` × ``correction_terms`` makes a cube of the trade
(:func:`correction_sweep`); its best case is exported and signed as any other.

The residual the corrected program is predicted to leave, registered as the measurement was:
its own predicted error against its target, plus what the target moved from the design, plus
the machine's error (the unexplained part, taken as repeatable):

    R = P' − g·L_N(U) + U                                                              (2)
"""

from __future__ import annotations

import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple, Optional

import numpy as np
import yaml

from ftsweep.engine.case import Case
from ftsweep.inputs import catalogs
from ftsweep.inputs.case_entries import Entries
from ftsweep.inputs.corrections import MeasuredCorrection, low_pass_callable
from ftsweep.stages.measurement import chebyshev_fit, registered_like, zernike_fit
from ftsweep.tools.measure import Explained, MeasuredPart, predicted_at, pv_nm, rms_nm

# the unexplained error's breakdown a correction keeps: every Zernike term to radial order 7
# (Noll 36), every Chebyshev product to degree 4 a side; the low-pass N chooses among them
ZERNIKE_TERMS = 36
CHEBYSHEV_DEGREE = 4


class Correction(NamedTuple):
    """The corrected case (its surface the target, in ``catalog_folder``), its prediction and
    the summary: gain, filter, the residual's RMS and P-V before and after [nm]."""

    case: Case
    catalog_folder: Path
    record: dict[str, Any]
    summary: dict[str, Any]


def measured_correction(part: MeasuredPart, split: Explained, aperture: Any, gain: float, terms: int) -> Any:
    """The ``correction`` block of the target: the unexplained error's breakdown over
    ``aperture`` (µm), the gain and terms kept, the measurement's SHA-256 and fit."""
    m, u = part.measurement, split.unexplained
    use = np.isfinite(u)
    given: dict[str, Any] = {
        "measurement_sha256": part.summary["sha256"],
        "gain": gain,
        "terms": terms,
        "fit": {k: float(v) for k, v in part.registration.terms.items()},
    }
    if aperture.shape == "circle":
        coef = zernike_fit(m.x[use], m.y[use], u[use], aperture.radius_um, ZERNIKE_TERMS)
        given["zernike_um"] = {int(j): float(c) for j, c in coef.items()}
    else:
        cheb = chebyshev_fit(m.x[use], m.y[use], u[use], aperture.width_um, aperture.height_um)
        side = CHEBYSHEV_DEGREE + 1
        given["chebyshev_um"] = [[float(cheb[(i, j)]) for j in range(side)] for i in range(side)]
    return MeasuredCorrection.model_validate(given)


def corrected_catalog(
    folder: Path, design_spec: Any, name: str, correction: Any, catalog_folder: Optional[Path] = None
) -> Path:
    """A copy of the catalogs (``catalog_folder``, default the one in use) under ``folder``
    with surface ``name``: the design's entry with ``correction``. Returns the copy's folder."""
    cats = Path(folder) / "catalogs"
    shutil.copytree(catalog_folder or catalogs.catalog_dir(), cats)
    entry = design_spec.model_dump(mode="json")
    entry["description"] = (
        f"{design_spec.description} Corrected by measurement {correction.measurement_sha256[:12]}."
    )
    entry["correction"] = correction.model_dump(mode="json")
    with (cats / "surfaces.yaml").open("a", encoding="utf-8") as fh:
        fh.write("\n" + yaml.safe_dump({name: entry}, allow_unicode=True, sort_keys=False))
    return cats


def residual(
    part: MeasuredPart,
    split: Explained,
    design: Any,
    correction: Any,
    aperture: Any,
    after: Mapping[str, Any],
) -> np.ndarray:
    """R of (2) at the measured points [µm]: ``after``'s predicted error (a corrected case's
    record with its error map) registered as the measurement was, less g·L_N(U), plus U."""
    m = part.measurement
    said = registered_like(design, m.x, m.y, part.registration, predicted_at(after, m.x, m.y))
    kept = low_pass_callable(correction, aperture)(m.x, m.y)[0]
    return np.asarray(said - correction.gain * kept + split.unexplained)


def correct(
    part: MeasuredPart,
    split: Explained,
    case: Case,
    folder: Path,
    *,
    gain: float = 1.0,
    terms: int = 15,
    specs: Optional[Entries] = None,
    catalog_folder: Optional[Path] = None,
) -> Correction:
    """The corrected case of ``case`` (the one that cut ``part``; its error map's bins set the
    corrected one's): its target written into a catalog copy under ``folder``, planned and
    predicted; its residual (2) against the uncorrected one, both as registered."""
    from ftsweep.simulate import run_case

    design_spec = (
        specs.surface if specs is not None else catalogs.entry("surfaces", case.surface, catalog_folder)
    )
    aperture = catalogs.aperture_of(design_spec)
    correction = measured_correction(part, split, aperture, gain, terms)
    name = f"{case.surface}-corrected"
    cats = corrected_catalog(folder, design_spec, name, correction, catalog_folder)
    corrected = case.model_copy(update={"surface": name})
    after_specs = None if specs is None else specs._replace(surface=catalogs.entry("surfaces", name, cats))
    after_record = run_case(corrected, cats, specs=after_specs)
    design = catalogs.surface_callable(design_spec, catalog_folder)
    after = residual(part, split, design, correction, aperture, after_record)
    before = split.explained + split.unexplained
    return Correction(
        corrected, cats, after_record, {**_summary(part, correction, before, after), "surface": name}
    )


def _summary(part: MeasuredPart, correction: Any, before: np.ndarray, after: np.ndarray) -> dict[str, Any]:
    return {
        "gain": correction.gain,
        "filter_terms": correction.terms,
        "measurement_sha256": part.summary["sha256"],
        "residual_before_rms_nm": rms_nm(before),
        "residual_after_rms_nm": rms_nm(after),
        "residual_before_pv_nm": pv_nm(before),
        "residual_after_pv_nm": pv_nm(after),
    }


def correction_spec(
    cube_spec: Any,
    coords: Mapping[str, Any],
    name: str,
    gains: Sequence[float],
    terms: Sequence[int],
    bins: int,
) -> dict[str, Any]:
    """The sweep of a cube's case (its coordinates ``coords``) on the corrected surface ``name``
    over gains × terms, with error maps of ``bins`` a side: the cube's spec with every axis
    fixed to the case's value."""
    spec = cube_spec.model_dump(mode="json")
    spec["surface"] = name
    spec["description"] = f"The corrected cut of {cube_spec.surface} over gains and low-passes."
    axes = {axis: [value] for axis, value in coords.items()}
    axes["correction_gain"] = [float(g) for g in gains]
    axes["correction_terms"] = [int(t) for t in terms]
    spec["axes"] = axes
    spec["resolution"] = {**spec.get("resolution", {}), "error_map_bins": int(bins)}
    return spec


def correction_sweep(
    cube_path: Any,
    case_name: str,
    folder: Path,
    part: MeasuredPart,
    split: Explained,
    gains: Sequence[float],
    terms: Sequence[int],
    *,
    bins: int = 32,
    workers: Optional[int] = None,
    scheduler: Optional[str] = None,
    plan_case: Optional[str] = None,
) -> Path:
    """Sweep case ``case_name`` of cube ``cube_path`` (the one that cut ``part``) on its
    corrected surface over ``gains`` × ``terms`` into ``folder/corrected.zarr``, with the
    catalog copy it plans on in ``folder/catalogs`` and its spec in ``folder/corrected.yaml``
    (:func:`ftsweep.sweeps.run.run_sweep` on a local cluster of ``workers`` or ``scheduler``).
    The correction block takes the first gain and terms; each case sets its own. ``plan_case``
    (another case of the cube, e.g. a finer layout) plans the corrected cut instead: the
    machine's error is the machine's, whatever the layout that showed it."""
    from ftsweep.sweeps.run import run_sweep
    from ftsweep.sweeps.spec import LoadedSweep, SweepSpec
    from ftsweep.tools.query import coordinates_of, find_case
    from ftsweep.tools.select import open_cube, recorded_case

    ds = open_cube(cube_path)
    flat = find_case(ds, plan_case or case_name)
    case, specs = recorded_case(ds, flat)
    aperture = catalogs.aperture_of(specs.surface)
    correction = measured_correction(part, split, aperture, float(gains[0]), int(terms[0]))
    name = f"{case.surface}-corrected"
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    cats = corrected_catalog(folder, specs.surface, name, correction)
    cube_spec = SweepSpec.model_validate_json(ds.attrs["sweep_spec"])
    given = correction_spec(cube_spec, coordinates_of(ds, flat), name, gains, terms, bins)
    (folder / "corrected.yaml").write_text(yaml.safe_dump(given, sort_keys=False), encoding="utf-8")
    spec = SweepSpec.model_validate(given, context={"catalog_folder": cats})
    out = folder / "corrected.zarr"
    run_sweep(LoadedSweep("corrected", spec), out, scheduler=scheduler, workers=workers, catalog_folder=cats)
    return out


def trade(ds: Any, part: MeasuredPart, split: Explained) -> Any:
    """The predicted residual (2) of every done case of a correction cube ``ds`` (its error
    maps), RMS and P-V [nm], as an xarray Dataset over the cube's axes of more than one value
    (``correction_gain`` × ``correction_terms``), with the uncorrected residual's as attributes."""
    import xarray as xr

    from ftsweep.engine.planning import cased_surface
    from ftsweep.store import cube
    from ftsweep.tools.query import position
    from ftsweep.tools.select import recorded_case

    if "error_map_mean_nm" not in ds:
        raise ValueError("the cube has no error maps: sweep the correction with resolution.error_map_bins")
    shape = ds["status"].shape
    rms, pv = np.full(shape, np.nan), np.full(shape, np.nan)
    done = np.flatnonzero(ds["status"].values.ravel() == cube.DONE)
    design: Any = None  # one for every case: the cube records one surface, its cases their gain and terms
    for flat in done:
        case, specs = recorded_case(ds, int(flat))
        entry = cased_surface(case, specs.surface)
        if design is None:
            design = catalogs.surface_callable(entry.model_copy(update={"correction": None}))
        at = position(ds, int(flat))
        after = {
            "error_map_x_um": ds["map_x"].values,
            "error_map_mean_nm": ds["error_map_mean_nm"].isel(at).values,
        }
        r = residual(part, split, design, entry.correction, catalogs.aperture_of(entry), after)
        index = np.unravel_index(int(flat), shape)
        rms[index], pv[index] = rms_nm(r), pv_nm(r)
    dims = ds["status"].dims
    found = xr.Dataset(
        {
            "residual_rms_nm": (dims, rms, {"units": "nm", "long_name": "predicted residual RMS, eq. (2)"}),
            "residual_pv_nm": (dims, pv, {"units": "nm", "long_name": "predicted residual P-V, eq. (2)"}),
        },
        coords={d: ds[d] for d in dims},
    )
    before = split.explained + split.unexplained
    found.attrs.update(
        measurement_sha256=part.summary["sha256"],
        uncorrected_rms_nm=rms_nm(before),
        uncorrected_pv_nm=pv_nm(before),
    )
    return found.squeeze([d for d in dims if found.sizes[d] == 1], drop=False)
