"""`make run` (the quick start) compares the maps at equal budgets, so its map-vs-map test
runs: the Makefile's command uses a profile that spends its whole budget, and a reduced run
of that very command ends with a tested comparison in the report."""

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from penaltyrun.io import read_results

ROOT = Path(__file__).resolve().parents[2]
PROFILES = ROOT / "penaltyrun" / "conf" / "optimizer"


def run_recipe():
    text = ROOT.joinpath("Makefile").read_text()
    recipe = re.search(r"^run:.*?\n((?:\t.*\n)+)", text, flags=re.M).group(1)
    return recipe.replace("\\\n", " ")


def cli_args():
    line = next(ln for ln in run_recipe().splitlines() if "penaltyrun.cli" in ln)
    return shlex.split(line.split("penaltyrun.cli", 1)[1])


def test_quickstart_uses_an_equal_budget_profile():
    args = dict(a.split("=", 1) for a in cli_args() if "=" in a)
    profile = PROFILES / f"{args['optimizer']}.yaml"
    assert re.search(r"spends its whole|until spent", profile.read_text())
    assert "optimizer.max_evals" in args and args["param"] == "diagonal,full"


@pytest.mark.slow  # about 40 s: the quick start's command at a small budget, and its report
def test_reduced_quickstart_runs_the_map_vs_map_test(tmp_path):
    args = [a for a in cli_args() if not a.startswith(("runner.workers", "hydra.sweep.dir",
                                                        "runner.n_starts",
                                                        "optimizer.max_evals"))]
    args += ["runner.n_starts=3", "optimizer.max_evals=300", "runner.report=false",
             f"hydra.sweep.dir={tmp_path / 'qs'}"]
    env = dict(os.environ)
    for cmd in ([sys.executable, "-m", "penaltyrun.cli", *args],
                [sys.executable, "-m", "penaltyrun.report_cli", str(tmp_path / "qs"), "-o",
                 str(tmp_path / "qs" / "report")]):
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=env,
                              cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
    df = read_results(tmp_path / "qs")
    assert (df["n_evals"] == 300).all()
    text = (tmp_path / "qs" / "report" / "report.md").read_text()
    row = next(ln for ln in text.splitlines() if ln.startswith("| cmaes | diagonal | full |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert "no test" not in row, row
    float(cells[-2])  # the Holm p of the test that ran
