"""`make check-docs` machinery on a synthetic study: a page rendered from the data passes,
the same page with one number edited by hand fails, a study without data renders as
pending (no number)."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from penaltyrun.docsgen import resultpages
from penaltyrun.io.schema import to_table

TEMPLATE = """# Demo

{% set name = "demo" -%}
{% if study(name).available -%}
Best diagonal: {{ value(name, "best_cost", "min", {"param": "diagonal"}, ".4f") }}.

{{ summary(name, ["param"]) }}
{%- else -%}
{{ pending(name) }}
{%- endif %}
"""
ANSWERS = """| question | answer |
|---|---|
| demo | {% if study("demo").available -%}
{{ value("demo", "best_cost", "median", {"param": "full"}) }}
{%- else %}{{ pending("demo", short=True) }}{% endif %} |
"""
README = f"# demo\n\n{resultpages.README_START}\n{resultpages.README_END}\n\nend\n"


def records() -> list[dict]:
    rows = []
    for k, (param, cost) in enumerate([("diagonal", 26.5218), ("diagonal", 27.1),
                                       ("full", 24.8265), ("full", 25.0)]):
        rows.append({"job_id": f"zermelo-default-{param}-pso-x-s{k:03d}", "problem": "zermelo",
                     "case": "default", "param": param, "optimizer": "pso", "start": k,
                     "seed": k, "status": "ok", "best_cost": cost, "best_converged": True,
                     "n_evals": 100 + k, "git_commit": "abc"})
    return rows


@pytest.fixture()
def repo(tmp_path: Path) -> Path:
    study = tmp_path / "studies" / "demo"
    study.mkdir(parents=True)
    (study / "study.yaml").write_text(
        "title: Demo study\nquestion: Is full better?\ncommands:\n"
        "  - {subdir: main, args: [problem=zermelo]}\n")
    templates = tmp_path / "studies" / "templates"
    templates.mkdir()
    (templates / "demo.md").write_text(TEMPLATE)
    (templates / "answers.md").write_text(ANSWERS)
    (tmp_path / "README.md").write_text(README)
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "index.md").write_text(README.replace("# demo", "# home"))
    return tmp_path


def commit_data(root: Path) -> None:
    pq.write_table(to_table(records(), run_id="demo"),
                   root / "studies" / "demo" / "results.parquet", compression="zstd")


def test_pending_study_renders_no_number(repo):
    resultpages.render_all(repo, reference=False)
    page = (repo / "docs" / "results" / "demo.md").read_text()
    assert "make study-demo" in page
    assert not re.search(r"\d", page.replace("study-demo", ""))
    assert resultpages.check(repo, reference=False) == []


def test_numbers_come_from_the_data(repo):
    commit_data(repo)
    resultpages.render_all(repo, reference=False)
    page = (repo / "docs" / "results" / "demo.md").read_text()
    assert "Best diagonal: 26.5218." in page
    assert "| full | — | 2 of 2 | 24.83 |" in page
    readme = (repo / "README.md").read_text()
    assert "| demo | 24.91 |" in readme and readme.endswith("end\n")
    home = (repo / "docs" / "index.md").read_text()
    assert home == readme.replace("# demo", "# home")
    assert resultpages.check(repo, reference=False) == []


def test_a_number_edited_by_hand_fails_check_docs(repo, tmp_path):
    commit_data(repo)
    resultpages.render_all(repo, reference=False)
    copy = tmp_path / "copy"
    shutil.copytree(repo, copy)
    page = copy / "docs" / "results" / "demo.md"
    page.write_text(page.read_text().replace("26.5218", "26.5219"))
    problems = resultpages.check(copy, reference=False)
    assert len(problems) == 1 and "26.5219" in problems[0] and "26.5218" in problems[0]
    readme = copy / "README.md"
    page.write_text(page.read_text().replace("26.5219", "26.5218"))
    readme.write_text(readme.read_text().replace("24.91", "24.90"))
    assert any("README.md" in p for p in resultpages.check(copy, reference=False))
    readme.write_text(readme.read_text().replace("24.90", "24.91"))
    home = copy / "docs" / "index.md"
    home.write_text(home.read_text().replace("24.91", "24.90"))
    assert [p for p in resultpages.check(copy, reference=False) if "index.md" in p]


def test_new_data_makes_committed_pages_stale(repo):
    resultpages.render_all(repo, reference=False)
    commit_data(repo)
    assert resultpages.check(repo, reference=False)


def test_check_command_exit_code(repo):
    commit_data(repo)
    resultpages.render_all(repo, reference=False)
    cmd = [sys.executable, "-m", "penaltyrun.docsgen", "--root", str(repo), "check",
           "--no-reference"]
    assert subprocess.run(cmd, capture_output=True, text=True).returncode == 0
    page = repo / "docs" / "results" / "demo.md"
    page.write_text(page.read_text().replace("26.5218", "26.5200"))
    done = subprocess.run(cmd, capture_output=True, text=True)
    assert done.returncode == 1
    assert "26.5200" in done.stderr and "make docs-results" in done.stderr


def test_fidelity_page_numbers_come_from_the_experiment_files(tmp_path):
    """The fidelity-gap page is rendered from studies/fidelity_gap/*.csv (and the study it
    ends with): a changed value in a committed CSV makes the committed page stale."""
    root = Path(__file__).resolve().parents[2]
    for folder in ("fidelity_gap", "pso_matlab_fidelity"):
        shutil.copytree(root / "studies" / folder, tmp_path / "studies" / folder)
    (tmp_path / "studies" / "templates").mkdir()
    shutil.copy2(root / "studies" / "templates" / "fidelity.md",
                 tmp_path / "studies" / "templates")
    resultpages.render_all(tmp_path, reference=False)
    page = (tmp_path / "docs" / "results" / "fidelity.md").read_text()
    assert page == (root / "docs" / "results" / "fidelity.md").read_text()
    # the study tables' own check (rebuilt from the Parquet) is tested in
    # test_check_docs_data.py; here only the pages against the experiment files
    assert resultpages.check(tmp_path, reference=False, tables=False) == []
    csv = tmp_path / "studies" / "fidelity_gap" / "sat_form.csv"
    header, row = csv.read_text().splitlines()[:2]
    evals = int(row.split(",")[header.split(",").index("evals_median")])  # shown once
    csv.write_text(csv.read_text().replace(f",{evals},", f",{evals + 1},"))
    problems = resultpages.check(tmp_path, reference=False, tables=False)
    assert len(problems) == 1 and str(evals + 1) in problems[0]


def test_a_stray_figure_fails_a_whole_check_not_one_of_other_files(repo):
    """A partial check (``--only``) renders no figure, so it cannot tell a figure that no
    page draws from one that it did not render."""
    commit_data(repo)
    resultpages.render_all(repo, reference=False)
    stray = repo / "docs" / "results" / "figures" / "gone_a12.png"
    stray.parent.mkdir(parents=True, exist_ok=True)
    stray.write_bytes(b"\x89PNG")
    assert any("gone_a12.png" in p for p in resultpages.check(repo, reference=False))
    assert resultpages.check(repo, reference=False, only="docs/results/demo") == []
