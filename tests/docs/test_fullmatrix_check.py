"""`make check-docs` guards the full-matrix page: a copy of the committed study, template,
page and figures passes; an edited number, a missing figure or changed held-out data fails.
And the page's example trajectories agree with the stored held-out costs."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from penaltyrun.docsgen import explanation, fullmatrix, resultpages

ROOT = Path(__file__).resolve().parents[2]
STUDY = "attitude_convergence"
PAGE = Path("docs") / "explanation" / "full-matrix.md"
ONLY = "docs/explanation"


@pytest.fixture()
def repo(tmp_path: Path) -> Path:
    """The files the page is made of, copied into a fresh repository root."""
    src = ROOT / "studies" / STUDY
    dst = tmp_path / "studies" / STUDY
    dst.mkdir(parents=True)
    for name in ("study.yaml", "results.parquet", "holdout_long.parquet"):
        shutil.copy2(src / name, dst / name)
    shutil.copytree(ROOT / explanation.TEMPLATES, tmp_path / explanation.TEMPLATES)
    shutil.copytree(ROOT / explanation.DOCS, tmp_path / explanation.DOCS)
    return tmp_path


def check(root: Path) -> list[str]:
    return resultpages.check(root, reference=False, tables=False, only=ONLY)


def test_an_edited_number_fails_the_check(repo):
    page = repo / PAGE
    text = page.read_text()
    edited = text.replace(" % in all ", "1 % in all ", 1)  # the training saving's upper end
    assert edited != text
    page.write_text(edited)
    problems = check(repo)
    assert problems and any("full-matrix.md (committed)" in p for p in problems)


@pytest.mark.slow
def test_the_committed_page_passes_and_a_missing_figure_fails(repo):
    assert check(repo) == []
    (repo / explanation.DOCS / fullmatrix.FIGURE_DIR / "full-matrix-modes.png").unlink()
    problems = check(repo)
    assert len(problems) == 1 and "figures/full-matrix-modes.png missing" in problems[0]


@pytest.mark.slow
def test_changed_held_out_data_fails_the_check(repo):
    path = repo / "studies" / STUDY / "holdout_long.parquet"
    long = pd.read_parquet(path)
    page = fullmatrix.Page(repo, STUDY, ("attitude_lyapunov", "detumble"))
    job = page.m.cells["full_job"].iloc[0]  # a best-known full start
    k = int(np.flatnonzero(long["job_id"] == job)[0])
    held = json.loads(long.at[k, "holdout"])
    held["cost"] = [0.01 * c for c in held["cost"]]
    long.at[k, "holdout"] = json.dumps(held)
    long.to_parquet(path, index=False)
    assert any("full-matrix.md" in p for p in check(repo))


@pytest.mark.slow
def test_cli_check_exits_1_on_an_edited_page(repo):
    page = repo / PAGE
    page.write_text(page.read_text().replace("(n = 40)", "(n = 41)", 1))
    cmd = [sys.executable, "-m", "penaltyrun.docsgen", "--root", str(repo), "check",
           "--no-reference", "--only", ONLY]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1, proc.stderr
    assert "n = 41" in proc.stderr


@pytest.mark.slow
def test_example_trajectories_end_at_the_stored_held_out_cost():
    """scipy DOP853 from the held-out start agrees with the compiled kernel's held-out run."""
    page = fullmatrix.Page(ROOT, STUDY, ("attitude_lyapunov", "detumble"))
    sims = fullmatrix.simulate_example(page.df, page.ex, n_points=50)
    for key, name in (("diag", "diagonal"), ("full", "full")):
        assert page.ex[f"{key}_converged"]
        sim = sims[name]
        assert sim["t"][-1] == pytest.approx(page.ex[f"{key}_arrival"], rel=1e-12)
        assert sim["J"][-1] == pytest.approx(page.ex[f"{key}_cost"], rel=1e-6)
        assert sim["dist"][-1] == pytest.approx(1e-4, rel=1e-3)  # arrives at the tolerance
