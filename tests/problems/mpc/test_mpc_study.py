"""The MPC study profile (+experiment=mpc_study): its plan, and a reduced run of every cell
(one start, tiny budgets, a small held-out set)."""

import subprocess
import sys

import pandas as pd
import pytest


def cli(tmp_path, *args):
    return subprocess.run([sys.executable, "-m", "penaltyrun.cli", "-m",
                           "+experiment=mpc_study", *args], cwd=tmp_path, capture_output=True,
                          text=True, timeout=1200)


def test_study_plan_has_every_cell(tmp_path):
    proc = cli(tmp_path, "mode=plan", "runner.forecast_samples=0")
    assert proc.returncode == 0, proc.stderr
    assert "12 cells, 360 jobs" in proc.stdout
    for param in ("diagonal", "geagsp", "givens", "cayley"):
        for opt in ("cmaes", "pso_matlab", "pso "):
            assert f"mpc_rendezvous/scaled/{param}/{opt}" in proc.stdout


@pytest.mark.slow
def test_study_profile_runs_reduced(tmp_path):
    sweep = tmp_path / "sweep"
    proc = cli(tmp_path, "runner.n_starts=1", "optimizer.max_evals=120", "runner.workers=1",
               "runner.report=false", "runner.progress=false", "runner.forecast_samples=0",
               "problem.params.holdout_n_sphere=1", f"hydra.sweep.dir={sweep}")
    assert proc.returncode == 0, proc.stderr[-2000:]
    files = sorted(sweep.glob("*/results.parquet"))
    assert len(files) == 12
    df = pd.concat([pd.read_parquet(f) for f in files], ignore_index=True)
    assert set(df["problem"]) == {"mpc_rendezvous"} and set(df["case"]) == {"scaled"}
    assert set(df["param"]) == {"diagonal", "geagsp", "givens", "cayley"}
    assert df["status"].isin(["ok", "diverged"]).all()
    assert df["holdout"].notna().all()
    assert (df["n_evals"] <= 120).all()
