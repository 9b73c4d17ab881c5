"""Commands that answer at once: ``ftsweep --help`` and every command's
``--help`` load no numba, xarray or zarr; ``import ftsweep`` stays light and still gives the
``ds.ftsweep`` accessor on a cube whichever of ftsweep and xarray is imported first. Timings are printed
by ``ftsweep bench``, never asserted here."""

from __future__ import annotations

import json
import subprocess
import sys

import click
import pytest
from click.testing import CliRunner

from ftsweep.cli.main import commands, main, short_help

HEAVY = ("numba", "xarray", "zarr", "pandas", "dask", "distributed", "scipy", "matplotlib")


def _modules_after(code: str) -> set[str]:
    """The top-level modules loaded by ``code`` in a fresh interpreter."""
    probe = code + "\nimport json, sys\nprint(json.dumps(sorted({m.split('.')[0] for m in sys.modules})))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    return set(json.loads(out.stdout.strip().splitlines()[-1]))


@pytest.mark.parametrize(
    "argv", [["--help"], *[[name, "--help"] for name in commands()], ["catalogs", "--help"]]
)
def test_help_loads_no_heavy_library(argv):
    code = (
        f"import sys\nfrom ftsweep.cli.main import main\ntry:\n    main({argv!r})\n"
        "except SystemExit:\n    pass"
    )
    loaded = _modules_after(code)
    assert not loaded & set(HEAVY), sorted(loaded & set(HEAVY))


OTHER_KINDS = ("ftsweep.kinds.spiral.kind", "ftsweep.kinds.dpath.kind", "ftsweep.kinds.fresnel.kind")


def test_a_case_loads_its_own_kind_and_no_other():
    """A ring case, from predict's options to its record, loads the table kind only: no other
    kind's planner, kernels or request model."""
    code = (
        "from ftsweep import registry\n"
        "from ftsweep.engine.case import Case, Resolution, program_request\n"
        "from ftsweep.simulate import run_case\n"
        "options = {'points': 2000, 'aspect': 4.0, 'drho_um': None, 'dtheta_deg': None, 'dx_um': None,"
        " 'dy_um': None, 'chord_um': None}\n"
        "request, _ = registry.request_from_options('ring', options)\n"
        "record = run_case(Case(surface='sinewave2d', layout=program_request(**request),"
        " resolution=Resolution(n_theta=16)))\n"
        "assert record['pv_nm'] > 0\n"
        "import json, sys\nprint(json.dumps(sorted(m for m in sys.modules if m.startswith('ftsweep.kinds'))))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    loaded = set(json.loads(out.stdout.strip().splitlines()[-1]))
    assert "ftsweep.kinds.table.kind" in loaded
    assert not loaded & set(OTHER_KINDS), sorted(loaded & set(OTHER_KINDS))


def test_import_ftsweep_is_light_and_a_cube_opened_in_either_order_has_the_accessor(tmp_path):
    """``import ftsweep`` loads no heavy library; after xarray it registers ``ds.ftsweep`` at
    once, before it xarray's first look for an engine does (ftsweep's backend entry point),
    and ``ftsweep.open_cube`` gives it in any case."""
    assert not _modules_after("import ftsweep") & set(HEAVY)
    from ftsweep.sweeps import run
    from ftsweep.sweeps.spec import load_sweep

    name, spec = load_sweep("sinewave-ring", None)
    at = tmp_path / "c.zarr"
    run.prepare_cube(name, spec, str(at), False, None)
    for code in (
        "import xarray as xr, ftsweep\nassert hasattr(xr.Dataset(), 'ftsweep')",
        f"import ftsweep, xarray as xr\nds = xr.open_dataset({str(at)!r}, engine='ftsweep')\n"
        "assert hasattr(ds, 'ftsweep')",
        f"import ftsweep, xarray as xr\nassert hasattr(xr.open_dataset({str(at)!r}), 'ftsweep')",
        f"import ftsweep\nassert hasattr(ftsweep.open_cube({str(at)!r}), 'ftsweep')",
    ):
        subprocess.run([sys.executable, "-c", code], check=True)


def test_group_help_lists_every_command_with_its_own_summary():
    ctx = click.Context(main)
    for name in commands():
        command = main.get_command(ctx, name)
        assert command is not None
        # the summary read from the source is the one click makes from the loaded command
        for limit in (40, 45, 80):
            assert short_help(name, limit) == command.get_short_help_str(limit)
    text = main.get_help(ctx)
    for name in (*commands(), "catalogs"):
        assert f"  {name} " in text


@pytest.mark.parametrize(
    ("argv", "code", "stream", "text"),
    [
        (["catalogs", "--json"], 0, "stdout", '"surfaces"'),
        (["predict", "--surface", "nope"], 1, "stderr", "unknown surface 'nope'"),
        (["predict", "--bogus"], 2, "stderr", "No such option"),
    ],
)
def test_console_script_exit_codes_and_output(argv, code, stream, text):
    # as the console script runs it: main() with no arguments reads sys.argv
    run = f"import sys\nfrom ftsweep.cli.main import main\nsys.argv = ['ftsweep', *{argv!r}]\nmain()"
    done = subprocess.run([sys.executable, "-c", run], capture_output=True, text=True)
    assert done.returncode == code, done.stderr
    assert text in getattr(done, stream)


def test_plots_leave_the_callers_matplotlib_backend_alone():
    # a notebook's ds.ftsweep.plot_* switched pyplot to Agg, and every later
    # plot of the session showed nothing
    code = (
        "import matplotlib\nmatplotlib.use('svg')\n"
        "from ftsweep.tools.accessor import _axes\nax = _axes()\n"
        "assert matplotlib.get_backend() == 'svg', matplotlib.get_backend()"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_the_top_level_help_lists_a_runs_commands_in_order():
    """sweep → status → select → export → verify first, as a run goes; every command listed once."""
    out = CliRunner().invoke(main, ["--help"]).output
    listed = [line.split()[0] for line in out.split("Commands:")[1].splitlines() if line.strip()]
    assert listed[:5] == ["sweep", "status", "select", "export", "verify"]
    assert sorted(listed) == sorted({*commands(), "catalogs"})


def test_predict_help_groups_each_kinds_options_under_its_layouts():
    out = CliRunner().invoke(main, ["predict", "--help"]).output
    common, _, by_kind = out.split("\nOptions:\n")[1].partition("Options of --layout")
    assert "--surface" in common and "--feed-um" in common and "--drho-um" not in common
    sections = {
        s.split(":")[0].strip(): s for s in ("Options of --layout" + by_kind).split("Options of --layout")[1:]
    }
    assert "--drho-um" in sections["mesh, ring"] and "--dx-um" in sections["mesh, ring"]
    assert "--chord-um" in sections["spiral"] and "--spacing-um" in sections["dpath"]
    assert "--facet-height-um" in sections["fresnel"]


def test_a_sweep_worker_logs_its_cases_without_xarray_pandas_or_zarr(tmp_path):
    """What a worker imports to run a task and log its cases: the driver alone opens the store."""
    code = (
        "from ftsweep.sweeps.executor import run_task\n"
        "from ftsweep.store.caselog import CaseLog\n"
        f"log = CaseLog({str(tmp_path)!r}, 'run')\n"
    )
    (tmp_path / "zarr.json").write_text("{}")  # a cube's folder, as the log checks
    code += "log.write_failed(3, 'a message', 'run')\n"
    loaded = _modules_after(code)
    assert not loaded & {"xarray", "pandas", "zarr"}, sorted(loaded & {"xarray", "pandas", "zarr"})
    assert list((tmp_path / "_log" / "run").glob("*.npz"))
