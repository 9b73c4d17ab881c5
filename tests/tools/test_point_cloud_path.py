"""A tool path from point-cloud data within 1 nm of the analytic one, the figure Buhmann et al.
(Int J Adv Manuf Technol 2022, "Point cloud based tool path generation for corrective
machining in ultra-precision diamond turning") give for their method: the catalog's Zernike
freeform sampled as a point cloud on a 10 µm grid (in mm, as a probe or interferometer
exports it), read as any measurement, made a height-map design
(:func:`ftsweep.tools.measure.as_height_map`), and planned with the same case as the analytic
surface. The compensated commands of the table and of a spiral program agree to 1 nm."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import yaml
from support import measured as ms
from support.places import REPO

from ftsweep.engine.case import Case, program_request
from ftsweep.engine.planning import control_table
from ftsweep.inputs import catalogs
from ftsweep.inputs.measurements import read_measurement
from ftsweep.simulate import resolve_case
from ftsweep.tools.measure import as_height_map, gridded

TOLERANCE_UM = 1e-3  # the anchor's 1 nm


@pytest.fixture(scope="module")
def cloud_catalog(tmp_path_factory):
    """A catalog copy with ``zernike_cloud``: the Zernike freeform as read from its point cloud."""
    folder = tmp_path_factory.mktemp("cloud") / "catalogs"
    shutil.copytree(REPO / "catalogs", folder)
    like = catalogs.entry("surfaces", "zernike_example")
    points = ms.part(
        "zernike_example", 1100.0, (0.0, 0.0, 0.0), lambda x, y: 0 * x, noise_um=0.0, dropout=0.0, n=221
    )
    measured = read_measurement(ms.write_cloud(folder.parent / "cloud.csv", points))
    entry = as_height_map(measured, folder, "zernike_cloud", like)
    with (folder / "surfaces.yaml").open("a", encoding="utf-8") as fh:
        fh.write("\n" + yaml.safe_dump({"zernike_cloud": entry}))
    return folder


def test_a_point_cloud_is_read_back_as_its_grid(tmp_path):
    points = ms.part(
        "zernike_example", 500.0, (0.0, 0.0, 0.0), lambda x, y: 0 * x, noise_um=0.0, dropout=0.0, n=11
    )
    order = np.random.default_rng(5).permutation(points[0].size)  # a cloud in any order
    shuffled = tuple(a[order] for a in points)
    grid, spacing, origin = gridded(read_measurement(ms.write_cloud(tmp_path / "c.csv", shuffled)))
    assert (
        grid.shape == (11, 11)
        and spacing == pytest.approx((100.0, 100.0))
        and origin == pytest.approx((-500.0, -500.0))
    )
    assert np.allclose(grid.ravel(), points[2], atol=1e-9)
    cut = tuple(a[:-1] for a in points)
    with pytest.raises(ValueError, match="no regular grid"):
        gridded(read_measurement(ms.write_cloud(tmp_path / "cut.csv", cut)))


def test_a_tables_commands_from_the_point_cloud_are_within_1_nm_of_the_analytic(cloud_catalog):
    found = []
    for name in ("zernike_example", "zernike_cloud"):
        case = Case(surface=name, layout=program_request(kind="ring", pitch=(20.0, 2.0)))
        rcase = resolve_case(case, catalog_folder=cloud_catalog)
        table, _ = control_table(case, rcase.layout, rcase.surface_spec, rcase.nose_radius_um, cloud_catalog)
        found.append(table)
    worst = float(np.max(np.abs(found[0] - found[1])))
    print(f"table: {found[0].size:,} commands, largest difference {1e3 * worst:.2e} nm")  # -s
    assert 0.0 < worst <= TOLERANCE_UM  # two evaluators (the spline's is not the formula's), one path


def test_a_spiral_programs_commands_from_the_point_cloud_are_within_1_nm_of_the_analytic(cloud_catalog):
    found = []
    for name in ("zernike_example", "zernike_cloud"):
        case = Case(surface=name, layout=program_request(kind="spiral", points_per_rev=720))
        found.append(resolve_case(case, catalog_folder=cloud_catalog).commands_um)
    assert found[0].shape == found[1].shape
    worst = float(np.max(np.abs(found[0] - found[1])))
    print(f"spiral: {found[0].size:,} commands, largest difference {1e3 * worst:.2e} nm")  # -s
    assert 0.0 < worst <= TOLERANCE_UM
