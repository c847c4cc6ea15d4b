"""Reports and exports of real multi-variant sweeps (the command line's ``-m``): every cell
names its own files and figures from its identity, not from a label that may be cut or
shared (two training starts ``x0`` and long variant labels, the diagonal and the full map).
"""

import json
import re
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from penaltyrun.io import RESULTS_FILE

X0 = ["[-8.123456789012345,6.123456789012345]", "[-8.123456789012345,6.523456789012345]"]


def _run(*args: str, cwd: Path) -> None:
    proc = subprocess.run([sys.executable, *args], cwd=cwd, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]


@pytest.fixture(scope="module")
def sweep(tmp_path_factory) -> Path:
    """Two training starts × two maps, with a variant label of over 80 characters."""
    root = tmp_path_factory.mktemp("sweep")
    _run("-m", "penaltyrun.cli", "-m", "problem=zermelo", "problem.params.x0=" + ",".join(X0),
         "problem.params.failure_penalty=1234.5678901234567", "problem.params.max_steps=999999",
         "param=diagonal,full", "optimizer=cmaes", "optimizer.max_evals=200",
         "runner.n_starts=2", "runner.report=false", f"hydra.sweep.dir={root / 'run'}",
         cwd=root)
    assert len(list((root / "run").rglob(RESULTS_FILE))) == 4
    return root


def _sections(text: str) -> dict[str, str]:
    """The report's per-cell sections (``## problem / case [variant]``) by heading."""
    parts = re.split(r"^(## zermelo / .*)$", text, flags=re.M)
    return {parts[i]: parts[i + 1].split("\n## ")[0] for i in range(1, len(parts) - 1, 2)}


@pytest.mark.slow  # about 20 s: four runs, a report and an export
def test_each_variant_of_a_real_sweep_has_its_own_sections_and_figures(sweep):
    _run("-m", "penaltyrun.report_cli", "run", "-o", "rep", cwd=sweep)
    out = sweep / "rep"
    sections = _sections((out / "report.md").read_text(encoding="utf-8"))
    assert len(sections) == 2
    assert all("6.123456789012345" in h or "6.523456789012345" in h for h in sections)
    figures = {head: re.findall(r"!\[[^\]]*\]\(([^)]+\.png)\)", body)
               for head, body in sections.items()}
    first, second = figures.values()
    assert len(first) >= 4 and len(first) == len(second)
    assert not set(first) & set(second)  # no figure shown in both sections
    for name in first + second:
        assert (out / name).is_file(), name
    summary = pd.read_csv(out / "summary.csv")
    assert len(summary) == 4 and summary["variant"].nunique() == 2


@pytest.mark.slow
def test_export_of_a_real_sweep_keeps_every_cell(sweep):
    _run("-m", "penaltyrun.report_cli", "run", "--export", "exp", cwd=sweep)
    files = sorted((sweep / "exp").glob("*.json"))
    cells = [json.loads(f.read_text(encoding="utf-8")) for f in files]
    assert len(cells) == 4 and len({f.stem for f in files}) == 4
    assert {(c["variant"], c["param"]) for c in cells} == {
        (v, p) for v in {c["variant"] for c in cells} for p in ("diagonal", "full")}
    diagonal = [c for c in cells if c["param"] == "diagonal"]
    for cell in diagonal:  # the diagonal map's matrices are kept, not overwritten by the full
        K = cell["matrices"]["K"]
        assert K[0][1] == 0.0 and K[1][0] == 0.0
    index = pd.read_csv(sweep / "exp" / "index.csv")
    assert len(index) == 4
