"""The example notebooks of docs/notebooks/ execute from top to bottom (nbclient, a fresh kernel each, in
their own folder as a reader would run them), so they never go stale: every cell runs without an error
and the notebooks that draw a figure draw one."""
from __future__ import annotations

import nbformat
import pytest
from nbclient import NotebookClient

from paths import ROOT

FOLDER = ROOT / "docs" / "notebooks"
NOTEBOOKS = {"simulate": True, "sweep_pandas": True, "calibrate": False, "pyabc": True}   # name: draws a figure


def test_every_notebook_is_listed():
    assert sorted(p.stem for p in FOLDER.glob("*.ipynb")) == sorted(NOTEBOOKS)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(NOTEBOOKS))
def test_the_notebook_executes(name):
    notebook = nbformat.read(FOLDER / f"{name}.ipynb", as_version=4)
    for cell in notebook.cells:
        if cell.cell_type == "code":
            cell.outputs = []
    NotebookClient(notebook, timeout=600, kernel_name="python3", allow_errors=False,
                   resources={"metadata": {"path": str(FOLDER)}}).execute()
    outputs = [o for cell in notebook.cells if cell.cell_type == "code" for o in cell.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    figures = [o for o in outputs if o.output_type == "display_data" and "image/png" in o.get("data", {})]
    assert bool(figures) == NOTEBOOKS[name]
