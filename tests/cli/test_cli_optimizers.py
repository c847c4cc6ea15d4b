"""Command-line errors of the budget, CMA-ES, grid and warm-start settings (one line, exit 2)."""

import subprocess
import sys

import pytest


@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (["optimizer=cmaes", "optimizer.sigma0=3"], ["optimizer.sigma0", "(0, 1]"]),
        (["optimizer=cmaes", "optimizer.restarts=-2"], ["optimizer.restarts"]),
        (["optimizer=cmaes", "optimizer.popsize=1"], ["optimizer.popsize"]),
        (["optimizer.max_evals=0"], ["optimizer.max_evals", "positive"]),
        (["optimizer.polish=newton"], ["optimizer.polish", "L-BFGS-B"]),
        (["optimizer=grid", "problem=attitude_lyapunov", "param=diagonal"],
         ["optimizer", "at most 4", "6"]),
        (["optimizer=grid", "optimizer.max_evals=100"], ["optimizer.max_evals", "grid needs"]),
        (["runner.warm_start=true"], ["runner.warm_start", "optimizer.max_evals"]),
        (["runner.warm_start=true", "optimizer.max_evals=100", "runner.warm_start_share=1.5"],
         ["runner.warm_start_share", "(0, 1)"]),
    ],
)
def test_bad_optimizer_settings_are_one_line(tmp_path, args, fragments):
    proc = subprocess.run([sys.executable, "-m", "penaltyrun.cli", "runner.n_starts=1", *args,
                           f"hydra.run.dir={tmp_path / 'run'}"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    for fragment in fragments:
        assert fragment in proc.stderr, proc.stderr
    assert not (tmp_path / "run" / "jobs").exists()
