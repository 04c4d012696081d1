"""The gallery's examples as Jupyter notebooks (examples/notebooks/*.ipynb): each is in
sync with its source, examples/plot_*.py, and runs in a real Jupyter kernel
(nbclient and ipykernel) with its figures drawn."""

import importlib.util
import json
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parents[1]
SYNC = ROOT / "examples" / "sync_notebooks.py"
SPEC = importlib.util.spec_from_file_location("sync_notebooks", SYNC)
sync_notebooks = importlib.util.module_from_spec(SPEC)
SPEC.loader.exec_module(sync_notebooks)
SOURCES = sync_notebooks.sources()


def test_every_example_has_a_notebook_and_no_notebook_is_orphaned():
    notebooks = {p.stem for p in sync_notebooks.NOTEBOOKS.glob("*.ipynb")}
    assert SOURCES, "no examples/plot_*.py"
    assert notebooks == {p.stem for p in SOURCES}


@pytest.mark.parametrize("source", SOURCES, ids=[p.stem for p in SOURCES])
def test_notebook_is_in_sync_with_its_source(source):
    """The committed notebook equals a fresh conversion of its .py source (rewrite all
    with ``python examples/sync_notebooks.py``) and holds no outputs."""
    committed = (sync_notebooks.NOTEBOOKS / f"{source.stem}.ipynb").read_text()
    assert committed == sync_notebooks.notebook_text(source), (
        f"{source.name} changed: run python examples/sync_notebooks.py"
    )
    cells = json.loads(committed)["cells"]
    assert all(not c.get("outputs") for c in cells if c["cell_type"] == "code")


@pytest.mark.slow
@pytest.mark.parametrize("source", SOURCES, ids=[p.stem for p in SOURCES])
def test_notebook_runs_in_a_jupyter_kernel(source, tmp_path):
    """Every cell runs without error in an ipykernel, and each figure a cell ends with
    is drawn (a PNG output), as a user sees it in Jupyter."""
    notebook = nbformat.read(sync_notebooks.NOTEBOOKS / f"{source.stem}.ipynb", as_version=4)
    where = {"metadata": {"path": str(tmp_path)}}
    client = NotebookClient(notebook, timeout=600, kernel_name="python3", resources=where)
    client.execute()
    figures_drawn = sum(
        "image/png" in output.get("data", {})
        for cell in notebook.cells if cell.cell_type == "code"
        for output in cell.outputs
    )  # fmt: skip
    figures_ending_cells = sum(
        cell.source.splitlines()[-1].startswith("fig")
        for cell in notebook.cells if cell.cell_type == "code" and cell.source.strip()
    )  # fmt: skip
    assert figures_ending_cells >= 1
    assert figures_drawn == figures_ending_cells
