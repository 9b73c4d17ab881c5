"""Synthetic measured parts of known truth: a catalog design as mounted (moved by set-up
terms), plus the form error ftsweep predicts for the case that cut it, plus machine errors of
known shape, plus noise and dropouts; written as a point cloud in mm.

The machine errors are those a diamond-turning shop meets (each in µm, of (x, y) [µm]):

- ``tool_radius``: a nose radius off by ΔR from the one compensated for: the tool, offset
  along the normal, cuts ΔR·(sec α − 1) ≈ ΔR·|∇f|²/2 deeper where the slope is α (less
  its on-axis value, the tool's set height);
- ``spindle``: an axial error motion synchronous with the spindle, a·cos(kθ + φ) at every
  radius;
- ``thermal``: a drift linear in cutting time; facing from the rim in at constant feed per
  revolution the tool reaches radius r at a time ∝ R − r, so the drift is d·(1 − r/R).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ftsweep.inputs import catalogs

Field = Callable[[np.ndarray, np.ndarray], np.ndarray]


def tool_radius(surface: str, delta_um: float) -> Field:
    """The form error of a nose radius ``delta_um`` larger than compensated for [µm]."""
    design = catalogs.surface_callable(catalogs.entry("surfaces", surface))

    def error(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        _, fx, fy = design(x, y)
        return np.asarray(-delta_um * (np.sqrt(1.0 + fx * fx + fy * fy) - 1.0))

    return error


def spindle(amplitude_um: float, per_rev: int, phase_rad: float = 0.0) -> Field:
    """An axial error motion of ``per_rev`` undulations per revolution [µm]."""
    return lambda x, y: amplitude_um * np.cos(per_rev * np.arctan2(y, x) + phase_rad)


def thermal(drift_um: float, radius_um: float) -> Field:
    """A drift of ``drift_um`` over a facing cut from ``radius_um`` to the axis [µm]."""
    return lambda x, y: drift_um * (1.0 - np.hypot(x, y) / radius_um)


def summed(*fields: Field) -> Field:
    """The sum of several error fields."""
    return lambda x, y: sum((f(x, y) for f in fields), np.zeros_like(x))


def part(
    surface: str,
    half_um: float,
    shift: tuple[float, float, float],
    form: Field,
    *,
    rotation_rad: float = 0.0,
    tilt: tuple[float, float] = (0.0, 0.0),
    noise_um: float = 0.001,
    dropout: float = 0.05,
    n: int = 81,
    seed: int = 3,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (x, y, z) [µm] on an n × n grid over ±``half_um`` of ``surface`` mounted moved by
    ``shift`` (dx, dy [µm], piston [µm]), turned by ``rotation_rad`` and tilted by ``tilt``
    (µm/µm in x and y), as :mod:`ftsweep.stages.measurement.registration` models it, plus ``form(x, y)``,
    noise of ``noise_um`` RMS and a share ``dropout`` of missing points (NaN)."""
    design = catalogs.surface_callable(catalogs.entry("surfaces", surface))
    x, y = (a.ravel() for a in np.meshgrid(*(np.linspace(-half_um, half_um, n),) * 2))
    dx, dy, piston = shift
    c, s = np.cos(rotation_rad), np.sin(rotation_rad)
    u, v = c * (x - dx) + s * (y - dy), -s * (x - dx) + c * (y - dy)
    rng = np.random.default_rng(seed)
    z = design(u, v)[0] + piston + tilt[0] * x + tilt[1] * y + form(x, y) + rng.normal(0, noise_um, x.size)
    z[rng.random(x.size) < dropout] = np.nan
    return x, y, z


def write_cloud(path: Path, points: tuple[np.ndarray, np.ndarray, np.ndarray], note: str = "") -> Path:
    """The points as a CSV point cloud in mm (NaN heights written as ``nan``)."""
    x, y, z = points
    rows = "\n".join(f"{a / 1e3:.9g},{b / 1e3:.9g},{c / 1e3:.12g}" for a, b, c in zip(x, y, z, strict=True))
    head = "".join(f"# {line}\n" for line in note.splitlines())
    path.write_text(f"{head}# units: mm\nx,y,z\n{rows}\n", encoding="utf-8")
    return path


def predicted(record: dict[str, Any]) -> Field:
    """A case's predicted form error as a field [µm] (its error map, bilinear)."""
    from ftsweep.tools.measure import predicted_at

    return lambda x, y: np.nan_to_num(predicted_at(record, x, y))


# the synthetic part shipped for the guide: what cut it, and the truth it was made with
SHIPPED = "catalogs/data/zernike-part.csv"
SHIPPED_CASE = ("zernike-ring", "points=2000 aspect=1")
SHIPPED_SETUP = {"piston_um": 0.2, "tilt_x": 2e-5, "tilt_y": -1e-5}
SHIPPED_NOTE = """A synthetic measured part for ftsweep's guide ("Corrective machining"), made by
tests/support/measured.py (shipped_part): zernike_example cut by case points=2000 aspect=1
of sweep zernike-ring, as ftsweep predicts it, on a machine that adds 6 nm of astigmatism
(Z6), a 15 nm thermal ramp over the facing cut, a nose 30 um larger than compensated for and
0.5 nm of 3-per-revolution axial spindle error motion; set up with 0.2 um of piston and tilts
of 2e-5 and -1e-5; 0.3 nm RMS noise, 5 % of the points missing; 51 x 51 points over 2 mm."""


def shipped_machine() -> Field:
    """The machine's error the shipped part was cut with [µm]."""
    from ftsweep.stages.measurement import zernike_basis

    return summed(
        lambda x, y: 0.006 * zernike_basis(x, y, 1000.0, 6)[:, 5],
        thermal(0.015, 1000.0),
        tool_radius("zernike_example", 30.0),
        spindle(0.0005, 3),
    )


def shipped_part(record: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The shipped part's points [µm], given the record of the case that cut it (with an error
    map of 32 bins a side)."""
    setup = SHIPPED_SETUP
    return part(
        "zernike_example",
        1000.0,
        (0.0, 0.0, setup["piston_um"]),
        summed(predicted(record), shipped_machine()),
        tilt=(setup["tilt_x"], setup["tilt_y"]),
        noise_um=3e-4,
        n=51,
    )


def shipped_record() -> dict[str, Any]:
    """The prediction (32-bin error map) of the case that cut the shipped part, planned from
    the catalog's sweep as its cube plans it."""
    from ftsweep.simulate import run_case
    from ftsweep.sweeps.spec import case_at, coordinates, load_sweep

    name, text = SHIPPED_CASE
    spec = load_sweep(name).spec
    coords = coordinates(spec)
    want = {k: float(v) for k, v in (pair.split("=") for pair in text.split())}
    shape = tuple(v.size for v in coords.values())
    flat = next(
        f
        for f in range(int(np.prod(shape)))
        if all(
            float(coords[k][i]) == want[k] for k, i in zip(coords, np.unravel_index(f, shape), strict=True)
        )
    )
    case = case_at(spec, flat)
    case = case.model_copy(update={"resolution": case.resolution.model_copy(update={"error_map_bins": 32})})
    return run_case(case)
