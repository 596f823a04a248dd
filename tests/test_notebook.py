"""examples/quickstart.ipynb runs from top to bottom and shows the viewer inline."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

NOTEBOOK = Path(__file__).resolve().parents[1] / "examples" / "quickstart.ipynb"

nbformat = pytest.importorskip("nbformat", reason="needs the test extra (nbformat)")
nbclient = pytest.importorskip("nbclient", reason="needs the test extra (nbclient)")
pytest.importorskip("ipykernel", reason="needs the test extra (ipykernel)")
pytest.importorskip("plotly", reason="the notebook shows the viewer (plotly)")


def test_quickstart_notebook_runs(tmp_path):
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    with warnings.catch_warnings():  # the Jupyter machinery's own deprecation notices
        warnings.simplefilter("ignore")
        nbclient.NotebookClient(
            notebook,
            timeout=300,
            kernel_name="python3",
            resources={"metadata": {"path": str(tmp_path)}},
        ).execute()
    outputs = [o for cell in notebook.cells if cell.cell_type == "code" for o in cell.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    # no Python warning in a cell's output (the kernel's own "WARNING |" lines are not)
    printed = [o.text for o in outputs if o.output_type == "stream" and o.name == "stderr"]
    assert not [text for text in printed if "Warning:" in text], printed
    shown = [o["data"].get("text/html", "") for o in outputs if "data" in o]
    assert any("<iframe srcdoc=" in text and "Plotly" in text for text in shown)
    assert any("image/png" in o.get("data", {}) for o in outputs)  # the figures
    assert (tmp_path / "quickstart-viewer.html").exists()
