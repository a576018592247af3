"""The example notebook runs headless from top to bottom, as a person would run it."""

from __future__ import annotations

from pathlib import Path

import pytest

NOTEBOOK = Path(__file__).resolve().parents[1] / "examples" / "campaign-in-a-notebook.ipynb"


@pytest.mark.slow
def test_example_notebook_runs_and_says_what_it_should():
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    assert not any(cell.get("outputs") for cell in notebook.cells if cell.cell_type == "code")
    nbclient.NotebookClient(notebook, timeout=600, kernel_name="python3").execute()
    outputs = [output for cell in notebook.cells if cell.cell_type == "code"
               for output in cell.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    text = "\n".join(o.get("data", {}).get("text/plain", "") for o in outputs)
    html = [o["data"]["text/html"] for o in outputs if "text/html" in o.get("data", {})]
    assert "<Campaign small.h5: 3 runs (table, soft-0, soft-10)>" in text
    assert "frequency_hz" in text and "m/s^2/N" in text
    assert "<Diagnosis soft-0 " in text and "rungs" in text
    assert "<Comparison soft-10 against soft-0: K_v +" in text
    assert any("Candidate effects on voigt" in page for page in html)  # the diagnosis's view
    assert "<MasterCurve eca: 19 temperatures, reference 25.00 °C" in text
    assert any("left out: the sweep(s) at -50.0 °C, -42.5 °C" in page for page in html)
    assert any("Prony series: " in page and "shift factors" in page for page in html)
