"""The notebooks run clean through a real Jupyter kernel in small mode, every figure appears as an
image, and they are committed without outputs.

Each notebook is executed by nbclient in an ipykernel (what Jupyter does when a user runs all
cells), with COSSERAT_NOTEBOOK_SMALL=1 in the kernel's environment (the notebooks shrink their
grids). A figure cell is a code cell that calls ``display(...)``: it must produce one
``image/png`` output per call, not the ``<Figure size ...>`` text a figure gives when nothing
renders it.
"""

import json
import os
import pathlib

import nbclient  # the `test` extra installs nbclient, nbformat and ipykernel
import nbformat
import pytest
from jupyter_client.manager import KernelManager

ROOT = pathlib.Path(__file__).resolve().parent.parent
NOTEBOOKS = ROOT / "notebooks"
NAMES = ["01_quickstart", "02_paper_figures", "03_solvability_regions", "04_work_precision",
         "05_calibration"]
SLOW = {"03_solvability_regions", "04_work_precision"}  # 20-30 s each in their kernel


@pytest.mark.parametrize("name", NAMES)
def test_notebook_committed_without_outputs(name):
    """Every code cell has no outputs and no execution count."""
    nb = json.loads((NOTEBOOKS / f"{name}.ipynb").read_text())
    for cell in nb["cells"]:
        if cell["cell_type"] == "code":
            assert cell["outputs"] == [] and cell["execution_count"] is None


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW else n
                                  for n in NAMES])
def test_notebook_runs_in_a_kernel_and_shows_every_figure(name, tmp_path, monkeypatch):
    """All cells run without error in a kernel; each display(...) of a figure is a PNG image."""
    nb = nbformat.read(NOTEBOOKS / f"{name}.ipynb", as_version=4)
    # The kernel inherits this process's environment: small mode, and no MPLBACKEND that a
    # developer's shell or CI may set (it must not matter: the figures never use pyplot).
    monkeypatch.setenv("COSSERAT_NOTEBOOK_SMALL", "1")
    monkeypatch.delenv("MPLBACKEND", raising=False)
    # The kernel runs in tmp_path: a relative PYTHONPATH (``PYTHONPATH=src``) would not reach
    # this tree's sources there, and the kernel would import an installed copy instead.
    paths = [str(ROOT / "src")] + [os.path.abspath(p) for p in
                                   os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(paths))
    # The kernel's channels are sockets in tmp_path: over TCP, jupyter_client picks free ports by
    # binding and releasing them, and the kernel dies at start if another process (the other
    # test process starts clusters and servers) binds one of them first.
    km = KernelManager(kernel_name="python3", transport="ipc", ip=str(tmp_path / "kernel"))
    # A cell's outputs may reach this process after its reply (the kernel sends them on another
    # channel, from another thread): they are waited for as long as the cell itself, and a wait
    # that runs out is an error. nbclient's default waits 4 s and then goes on without them.
    client = nbclient.NotebookClient(nb, km=km, timeout=600, iopub_timeout=600,
                                     raise_on_iopub_timeout=True,
                                     resources={"metadata": {"path": str(tmp_path)}})
    client.execute()  # raises CellExecutionError, with the traceback, if a cell fails

    figure_cells = 0
    for cell in nb.cells:
        if cell.cell_type != "code":
            continue
        errors = [o for o in cell.outputs if o.output_type == "error"]
        assert not errors, errors
        calls = cell.source.count("display(")
        if not calls:
            continue
        figure_cells += 1
        images = [o for o in cell.outputs
                  if o.output_type in ("display_data", "execute_result") and "image/png" in o.data]
        texts = [o.data.get("text/plain", "") for o in cell.outputs
                 if o.output_type == "display_data" and "image/png" not in o.data]
        assert len(images) == calls, (
            f"cell shows {len(images)} image(s) for {calls} display call(s): {cell.source[:200]!r}"
            f"; text outputs instead: {texts}"
        )
        for o in images:
            assert o.data["image/png"]  # base64 of a real PNG (starts with the PNG signature)
            assert o.data["image/png"].startswith("iVBORw0KGgo")
    assert figure_cells > 0
