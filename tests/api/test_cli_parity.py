"""The API and the command line run the same cells: same jobs, hashes, seeds and costs."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

import penaltyrun
from penaltyrun.api.compose import compose, run_spec
from penaltyrun.runner import config_hash

#: One small cell: diagonal Zermelo, CMA-ES with 30 evaluations per start, 2 starts.
CELL = {"problem": "zermelo", "param": "diagonal", "optimizer": "cmaes"}


def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "penaltyrun.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=600, check=True)


def test_api_and_cli_give_the_same_jobs_and_best_cost(tmp_path):
    _cli(f"problem={CELL['problem']}", f"param={CELL['param']}",
         f"optimizer={CELL['optimizer']}", "optimizer.max_evals=30", "runner.n_starts=2",
         "runner.seed=5", "runner.workers=1", "runner.report=false", "runner.forecast_samples=0",
         f"hydra.run.dir={tmp_path / 'cli'}", cwd=tmp_path)
    cli = pd.read_parquet(tmp_path / "cli" / "results.parquet").sort_values("job_id")
    api = penaltyrun.tune(CELL["problem"], param=CELL["param"], optimizer=CELL["optimizer"],
                          optimizer_options={"max_evals": 30}, n_starts=2, seed=5,
                          workers=1, run_dir=tmp_path / "api").records.sort_values("job_id")
    for column in ("job_id", "seed", "config_hash", "best_cost", "n_evals", "matrices",
                   "problem_params", "optimizer_settings", "param_options"):
        assert list(api[column]) == list(cli[column]), column
    assert api["best_cost"].min() == cli["best_cost"].min()


def test_a_built_in_cells_hash_is_unchanged():
    """The composed config hashes as the command line's Hydra config does (committed
    studies deduplicate runs by it; value from Hydra's compose). It changes only when a
    built-in config file gains or changes a key (last: the held-out horizon keys)."""
    config = compose("zermelo", None, case=None, param="full", optimizer="pso",
                     optimizer_options=None, params=None,
                     runner={"seed": 20250422, "n_starts": 10})
    spec = run_spec(config)
    assert config_hash(spec.hashed) == "111f4398a2da0ab1"

    job = spec.plan("default")[0]
    assert job.job_id == "zermelo-default-full-pso-eab43454-s000"


def test_evaluate_equals_mode_evaluate(tmp_path):
    K = [[1.0, 0.2], [0.2, 0.5]]
    out = _cli("mode=evaluate", "problem=zermelo", f"matrices.K={json.dumps(K)}",
               cwd=tmp_path)
    printed = json.loads(out.stdout.strip().splitlines()[-1])
    result = penaltyrun.evaluate("zermelo", {"K": np.array(K)})
    assert json.loads(json.dumps(result, default=str)) == printed
