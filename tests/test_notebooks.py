"""The notebooks run top to bottom, and are committed without their outputs.

Each notebook is executed with nbclient in a fresh ``python3`` kernel that runs
*this* interpreter (a throw-away kernelspec pointing at ``sys.executable``, so a
``python`` on PATH from elsewhere cannot be picked up), with the repository root
as working directory and ``MIMARBLE_NOTEBOOK_FAST=1``: the notebooks then render
tiny images with few optimisation steps (a few seconds each).

Needs ``nbformat``, ``nbclient`` and ``ipykernel`` (and ``matplotlib``, which the
notebooks use); the tests are skipped with a reason when one is missing.
Deselect them with ``-k "not notebook"``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOKS = ("01_tour", "02_inverse_marble", "03_benchmark")
MAX_COMMITTED_OUTPUT_BYTES = 200_000


def _path(name: str) -> Path:
    return ROOT / "notebooks" / f"{name}.ipynb"


@pytest.fixture
def this_interpreter_kernel(tmp_path, monkeypatch):
    """A ``python3`` kernelspec for sys.executable, first on JUPYTER_PATH."""
    spec = tmp_path / "jupyter" / "kernels" / "python3"
    spec.mkdir(parents=True)
    (spec / "kernel.json").write_text(json.dumps({
        "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
        "display_name": "Python 3 (mimarble tests)",
        "language": "python",
    }))
    monkeypatch.setenv("JUPYTER_PATH", str(tmp_path / "jupyter"))
    monkeypatch.setenv("MIMARBLE_NOTEBOOK_FAST", "1")
    monkeypatch.setenv("MPLBACKEND", "agg")   # no display needed; inline output still works
    return "python3"


@pytest.mark.parametrize("name", NOTEBOOKS)
def test_notebook_runs_top_to_bottom(name, this_interpreter_kernel):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    pytest.importorskip("matplotlib")
    notebook = nbformat.read(_path(name), as_version=4)
    client = nbclient.NotebookClient(
        notebook, kernel_name=this_interpreter_kernel, timeout=300,
        resources={"metadata": {"path": str(ROOT)}})
    client.execute()   # raises CellExecutionError, with the cell and traceback, on any error
    errors = [output for cell in notebook.cells if cell.cell_type == "code"
              for output in cell.get("outputs", []) if output.get("output_type") == "error"]
    assert not errors, errors
    assert any(cell.get("outputs") for cell in notebook.cells if cell.cell_type == "code")


@pytest.mark.parametrize("name", NOTEBOOKS)
def test_committed_notebook_has_no_outputs(name):
    """Committed notebooks carry code and text only: outputs stripped, no execution counts."""
    notebook = json.loads(_path(name).read_text(encoding="utf-8"))
    code = [cell for cell in notebook["cells"] if cell["cell_type"] == "code"]
    assert code, f"{name} has no code cells"
    size = sum(len(json.dumps(cell.get("outputs", []))) for cell in code)
    assert size < MAX_COMMITTED_OUTPUT_BYTES, f"{name}: {size} bytes of outputs"
    stale = [i for i, cell in enumerate(code) if cell.get("outputs") or cell.get("execution_count")]
    assert not stale, f"{name}: code cells {stale} carry outputs; strip them before committing"
