"""Surface families are declared once: the registering decorator of
ftsweep.stages.sampling.surfaces is the only place a family is written; the catalog's validated model
is generated from it. A new family, registered in a fresh process, is validated, refused
with named keys when wrong, and predicted, without touching any other module."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from ftsweep.inputs import catalogs
from ftsweep.stages.sampling.surfaces import FAMILIES

NEW_FAMILY = textwrap.dedent(
    """
    import numpy as np
    from ftsweep.stages.sampling.surfaces import Param, surface_family

    @surface_family("tilted_plane", {
        "slope_x": Param(float, "slope along x [-]"),
        "offset_um": Param(float, "height at the centre [µm]", 0.0),
    }, gradient_bound=lambda slope_x, **_: abs(slope_x))
    def tilted_plane(x, y, *, slope_x, offset_um=0.0):
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        return offset_um + slope_x * x, np.full(x.shape, slope_x), np.zeros(y.shape)

    from pydantic import TypeAdapter
    from ftsweep.inputs import catalogs
    from ftsweep.simulate import run_case
    from ftsweep.engine.case import program_request
    from ftsweep.engine.case import Case

    entry = {"family": "tilted_plane", "layout": "mesh", "aperture": {"shape": "circle", "radius_um": 300.0},
             "params": {"slope_x": 0.0, "offset_um": 2.0}}
    spec = TypeAdapter(catalogs.SurfaceSpec).validate_python(entry)
    try:
        TypeAdapter(catalogs.SurfaceSpec).validate_python({**entry, "params": {"slope": 0.01}})
    except Exception as exc:
        print("refused:", "slope_x" in str(exc), "slope" in str(exc))
    machine, cutting = catalogs.entry("machines", "fts-1m"), catalogs.entry("cutting", "reference")
    case = Case(surface="plane", layout=program_request(kind="mesh", pitch=(20.0, 20.0)))
    record = run_case(case, specs=(spec, machine, cutting))
    print("pv", record["pv_outer_nm"], record["pv_interp_nm"], record["cusp_nm"])
    """
)


def test_a_new_family_needs_only_its_registration():
    out = subprocess.run([sys.executable, "-c", NEW_FAMILY], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    lines = dict(line.split(" ", 1) for line in out.stdout.strip().splitlines())
    assert lines["refused:"] == "True True"
    pv_outer, pv_interp, cusp = (float(v) for v in lines["pv"].split())
    # a level plane is machined to feed cusps (away from the axis, where the last passes of
    # both sides meet, model §5), and the table reproduces it exactly
    assert abs(pv_interp) <= 1e-3
    assert abs(pv_outer - cusp) <= 0.05 * cusp


def test_every_registered_family_has_a_generated_catalog_model():
    assert set(catalogs.registered_surfaces()) == set(FAMILIES)
    for name, model in catalogs.registered_surfaces().items():
        params = model.model_fields["params"].annotation
        assert set(params.model_fields) == set(FAMILIES[name].params), name
        for key, p in FAMILIES[name].params.items():
            assert params.model_fields[key].description == p.description


def test_the_commands_offer_every_registered_kind():
    # the --layout choices are the registry's names, read from the entry points without
    # importing the kinds (the CLI starts without their kernels)
    from ftsweep import registry
    from ftsweep.cli.predict import predict
    from ftsweep.cli.tools import optimize as optimize_command

    for command in (predict, optimize_command):
        layout = next(p for p in command.params if p.name == "layout")
        assert set(layout.type.choices) == set(registry.kinds()), command.name


@pytest.mark.parametrize(
    ("fields", "label"),
    [
        ({"kind": "spiral", "chord_um": 0.5}, "chord 0.5 µm"),
        ({"kind": "spiral", "points_per_rev": 500}, "points_per_rev=500"),
        ({"kind": "dpath", "spacing_um": 20.0}, "spacing 20 µm"),
        (
            {"kind": "fresnel", "facet_height_um": 10.0, "deviation_deg": 2.0},
            "facet_height 10 µm deviation 2°",
        ),
        ({"kind": "ring", "points": 1e6, "aspect": 8.0}, "N≈1,000,000 α=8"),
    ],
)
def test_a_cases_label_names_its_own_fields_with_units_never_none(fields, label):
    from ftsweep.engine.case import program_request

    text = program_request(**fields).label()
    assert text == label and "None" not in text


# ----------------------------------------------------------------------------- surface plug-ins
PLUGIN = textwrap.dedent(
    """
    import numpy as np
    from ftsweep.stages.sampling import Param, surface_family

    @surface_family("tilted_plane", {"slope_x": Param(float, "slope along x [-]")},
                    gradient_bound=lambda slope_x, **_: abs(slope_x))
    def tilted_plane(x, y, *, slope_x):
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        return slope_x * x, np.full(x.shape, slope_x), np.zeros(y.shape)
    """
)
TILTED = """
tilted:
  description: A tilted plane whose family a plug-in declares.
  family: tilted_plane
  params: {slope_x: 0.001}
  aperture: {shape: circle, radius_um: 500.0}
  layout: ring
"""


@pytest.fixture()
def plugin_folder(tmp_path, catalog_dir):
    """A plug-in module, the metadata of a package that names it by entry point (a
    dist-info folder on the path, as an installed package has), and a catalog using it."""
    import shutil

    (tmp_path / "tilted_surfaces.py").write_text(PLUGIN)
    (tmp_path / "broken_surfaces.py").write_text("raise RuntimeError('this plug-in is broken')\n")
    info = tmp_path / "tilted_optics-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: tilted-optics\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[ftsweep.surfaces]\ntilted = tilted_surfaces\n")
    cat = tmp_path / "with-tilted"
    shutil.copytree(catalog_dir, cat)
    (cat / "surfaces.yaml").write_text((cat / "surfaces.yaml").read_text() + TILTED)
    return tmp_path


def _ftsweep(folder, *args, **env):  # type: ignore[no-untyped-def]
    import os

    from support.clusters import BIN

    base = {k: v for k, v in os.environ.items() if k not in ("FTSWEEP_SURFACE_MODULES", "PYTHONPATH")}
    base.update(FTSWEEP_CATALOGS=str(folder / "with-tilted"), **env)
    return subprocess.run(
        [str(BIN / "ftsweep"), *args], capture_output=True, text=True, env=base, cwd=folder, timeout=300
    )


PREDICT = ("predict", "--surface", "tilted", "--drho-um", "20", "--dtheta-deg", "4", "--json")


def test_a_surface_plugin_named_by_an_entry_point_works_from_the_command_line(plugin_folder):
    import json

    found = _ftsweep(plugin_folder, "catalogs", PYTHONPATH=str(plugin_folder))
    assert found.returncode == 0, found.stderr
    shown = " ".join(found.stdout.split())  # wrapped to the terminal's width, whatever it is
    assert "tilted_plane: from entry point 'tilted' (tilted_surfaces) of tilted-optics" in shown
    assert f"catalogs {plugin_folder / 'with-tilted'} ($FTSWEEP_CATALOGS)" in shown
    listed = json.loads(_ftsweep(plugin_folder, "catalogs", "--json", PYTHONPATH=str(plugin_folder)).stdout)
    assert listed["surface_families"]["sinewave2d"] == "ftsweep (built in)"
    predicted = _ftsweep(plugin_folder, *PREDICT, PYTHONPATH=str(plugin_folder))
    assert predicted.returncode == 0, predicted.stderr
    assert json.loads(predicted.stdout)["pv_nm"] > 0


def test_a_surface_plugin_named_by_the_environment_and_a_broken_one(plugin_folder):
    import json

    # the module named by the variable (a notebook's, a script's), no package metadata needed
    (plugin_folder / "tilted_optics-0.1.dist-info" / "entry_points.txt").unlink()
    env = {"PYTHONPATH": str(plugin_folder), "FTSWEEP_SURFACE_MODULES": "broken_surfaces, tilted_surfaces"}
    predicted = _ftsweep(plugin_folder, *PREDICT, **env)
    assert predicted.returncode == 0, predicted.stderr
    assert json.loads(predicted.stdout)["pv_nm"] > 0
    # the broken one is warned about, named, and skipped
    assert (
        "surface plug-in module broken_surfaces (FTSWEEP_SURFACE_MODULES) failed to load" in predicted.stderr
    )
    assert "RuntimeError: this plug-in is broken" in predicted.stderr
    # without any plug-in the catalog entry is refused saying how a family is registered
    refused = _ftsweep(plugin_folder, *PREDICT, PYTHONPATH=str(plugin_folder))
    assert refused.returncode != 0 and "Traceback" not in refused.stderr
    assert "unknown surface family 'tilted_plane'" in refused.stderr
    assert (
        "entry point of group 'ftsweep.surfaces'" in refused.stderr
        and "FTSWEEP_SURFACE_MODULES" in refused.stderr
    )


def test_the_help_says_where_catalogs_and_surface_families_come_from():
    from click.testing import CliRunner

    from ftsweep.cli.main import main

    text = " ".join(CliRunner().invoke(main, ["--help"]).output.split())
    assert "$FTSWEEP_CATALOGS, else a checkout's catalogs/" in text
    assert "'ftsweep.surfaces'" in text and "$FTSWEEP_SURFACE_MODULES" in text
    listing = " ".join(CliRunner().invoke(main, ["catalogs", "--help"]).output.split())
    assert "entry points of group 'ftsweep.surfaces'" in listing
