"""``problem=my_pkg.my_module``: a problem module named by its path on the command line,
with the same jobs and costs as ``penaltyrun.tune("my_pkg.my_module")``."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pandas as pd
import pytest

import penaltyrun
from penaltyrun.cli import userconf

MODULE = textwrap.dedent('''
    import numpy as np
    from penaltyrun.problems.base import BatchEvaluation, MatrixSpec

    CASES = ("one",)
    DEFAULT_CASE = "one"
    TARGET = np.array([[2.0, 0.5], [0.5, 1.0]])


    class Fit:
        name = "fit"
        case = "one"
        matrices = (MatrixSpec("K", 2, (0.1, 10.0)),)
        scalars = ()

        def evaluate_batch(self, mats, scalars=None):
            cost = np.sum((np.asarray(mats["K"]) - TARGET) ** 2, axis=(1, 2))
            return BatchEvaluation(cost, np.ones(len(cost), bool),
                                   np.array(["converged"] * len(cost), dtype=object))

        def evaluate(self, mats, scalars=None):
            cost = float(np.sum((np.asarray(mats["K"]) - TARGET) ** 2))
            return {"cost": cost, "converged": True, "status": "converged", "t_final": 0.0}

        def simulate(self, mats, scalars=None):
            return {"t": np.zeros(1)}


    def make_problem(case, params):
        return Fit()
''')


def test_module_paths_become_problem_configs_on_the_search_path():
    argv = userconf.module_problems(["problem=lab.fit,zermelo", "hydra.searchpath=[pkg://x]"])
    assert argv[0] == "problem=lab.fit,zermelo"
    assert argv[1].startswith("hydra.searchpath=[pkg://x,file://")
    folder = argv[1].split("file://")[1].rstrip("]")
    text = open(os.path.join(folder, "problem", "lab.fit.yaml"), encoding="utf-8").read()
    assert text == "name: fit\nmodule: lab.fit\nparams: {}\n"
    assert userconf.module_problems(["problem=zermelo"]) == ["problem=zermelo"]


@pytest.mark.slow
def test_cli_module_path_runs_the_cell_the_api_runs(tmp_path, monkeypatch):
    pkg = tmp_path / "lab"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "fitmod.py").write_text(MODULE)
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    subprocess.run([sys.executable, "-m", "penaltyrun.cli", "problem=lab.fitmod",
                    "optimizer=cmaes", "optimizer.max_evals=60", "runner.n_starts=2",
                    "runner.workers=1", "runner.report=false", "runner.forecast_samples=0",
                    f"hydra.run.dir={tmp_path / 'cli'}"], cwd=tmp_path, env=env,
                   capture_output=True, text=True, timeout=600, check=True)
    cli = pd.read_parquet(tmp_path / "cli" / "results.parquet").sort_values("job_id")
    monkeypatch.syspath_prepend(str(tmp_path))
    api = penaltyrun.tune("lab.fitmod", optimizer_options={"max_evals": 60}, n_starts=2,
                          workers=1, run_dir=tmp_path / "api").records.sort_values("job_id")
    assert list(cli["problem"]) == ["fitmod", "fitmod"]
    for column in ("job_id", "seed", "config_hash", "best_cost"):
        assert list(api[column]) == list(cli[column]), column


def test_a_module_path_named_like_a_built_in_problem_is_one_line_exit_2(tmp_path):
    """``problem=lab.lqr`` would record its jobs as the built-in ``lqr`` (and pool them
    with its records): refused before the module is imported."""
    pkg = tmp_path / "lab"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "lqr.py").write_text(MODULE)
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    done = subprocess.run([sys.executable, "-m", "penaltyrun.cli", "problem=lab.lqr",
                           f"hydra.run.dir={tmp_path / 'run'}"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(
        "penaltyrun: error: problem: 'lqr' is the name of a built-in problem")
    assert "rename the module" in lines[0] and not (tmp_path / "run").exists()
