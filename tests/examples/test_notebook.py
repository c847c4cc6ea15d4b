"""The notebook tutorial examples/tune_your_cost.ipynb runs from top to bottom, stays
within 15 lines of code, and shows what it says: full reaches the optimum, diagonal
cannot, and the report is written."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

NOTEBOOK = Path(__file__).resolve().parents[2] / "examples" / "tune_your_cost.ipynb"
TUTORIAL = Path(__file__).resolve().parents[2] / "docs" / "tutorials" / "tune-your-cost.md"


def _code_cells() -> list[str]:
    cells = json.loads(NOTEBOOK.read_text(encoding="utf-8"))["cells"]
    return ["".join(c["source"]) for c in cells if c["cell_type"] == "code"]


def test_the_notebook_is_at_most_15_lines_of_code():
    lines = [line for cell in _code_cells() for line in cell.splitlines()
             if line.strip() and not line.strip().startswith("#")]
    assert len(lines) <= 15


def test_the_tutorial_page_shows_the_notebooks_code():
    text = TUTORIAL.read_text(encoding="utf-8")
    for source in _code_cells():
        assert source in text


@pytest.mark.slow
def test_the_notebook_runs(tmp_path):
    import nbformat
    from nbclient import NotebookClient

    shutil.copy(NOTEBOOK, tmp_path)
    nb = nbformat.read(tmp_path / NOTEBOOK.name, as_version=4)
    NotebookClient(nb, timeout=600, kernel_name="python3",
                   resources={"metadata": {"path": str(tmp_path)}}).execute()
    outputs = {i: cell.outputs for i, cell in enumerate(nb.cells) if cell.cell_type == "code"}
    assert all(out.get("output_type") != "error" for cell in outputs.values() for out in cell)
    assert (tmp_path / "runs" / "report" / "report.md").is_file()
    table = outputs[3][-1]["data"]["text/plain"]
    assert "diagonal" in table and "full" in table
    assert "text/markdown" in outputs[7][-1]["data"]
    import penaltyrun

    full = penaltyrun.load(tmp_path / "runs" / "full").best
    diagonal = penaltyrun.load(tmp_path / "runs" / "diagonal").best
    assert full.cost < 1e-3 and diagonal.cost >= 2 * 0.8**2 - 1e-12
