"""The notebook tour in a real Jupyter kernel: every ``ds.ftsweep.plot_*``
shows its figure inline, and a plain matplotlib cell run after them still shows its own (a
plot once switched pyplot to Agg, and every later figure of the session was lost)."""

from __future__ import annotations

import pytest

from ftsweep.sweeps.run import run_sweep

# a Jupyter kernel
pytestmark = pytest.mark.integration

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")
pytest.importorskip("ipykernel")

SPEC = """
surface: small_sine
layout: ring
resolution: {error_map_bins: 16}
axes: {points: [8000, 16000], aspect: [1.0, 4.0]}
"""
PLOTS = ("plot_pv", "plot_aspect", "plot_heatmap", "plot_error_map")


def _images(cell) -> int:
    return sum(1 for out in cell.get("outputs", []) if "image/png" in out.get("data", {}))


def test_every_plot_shows_inline_and_later_matplotlib_cells_still_show(tmp_path, catalog_dir, monkeypatch):
    # the kernel inherits this process's environment: a CLI test run before sets MPLBACKEND=Agg
    # here (the command line's own choice), which a user's Jupyter does not have
    monkeypatch.delenv("MPLBACKEND", raising=False)
    spec = tmp_path / "nb.yaml"
    spec.write_text(SPEC)
    cube = tmp_path / "nb.zarr"
    run_sweep(str(spec), cube, scheduler="synchronous", catalog_folder=catalog_dir)
    cells = [
        nbformat.v4.new_code_cell(
            f"import xarray as xr\nimport ftsweep\nds = xr.open_zarr({str(cube)!r})\n"
            "import pint_xarray\nfloat(ds.load().pint.quantify().pv_nm.pint.to('um').pint.magnitude.max())"
        ),
        *(nbformat.v4.new_code_cell(f"ds.ftsweep.{name}();") for name in PLOTS),
        nbformat.v4.new_code_cell(
            "import matplotlib, matplotlib.pyplot as plt\nplt.plot([0, 1, 2], [0, 1, 4]);"
        ),
        nbformat.v4.new_code_cell("matplotlib.get_backend()"),
    ]
    notebook = nbformat.v4.new_notebook(cells=cells)
    notebook.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    client = nbclient.NotebookClient(
        notebook,
        timeout=300,
        kernel_name="python3",
        resources={"metadata": {"path": str(tmp_path)}},
    )
    client.execute()
    first, *plots, plain, backend = notebook.cells
    assert float(first.outputs[0]["data"]["text/plain"]) > 0  # units convert in the kernel
    for name, cell in zip(PLOTS, plots, strict=True):
        assert _images(cell) == 1, (name, cell.outputs)
    assert _images(plain) == 1, plain.outputs
    assert "inline" in backend.outputs[0]["data"]["text/plain"]
