"""Bad scenario settings on the command line: one readable line, exit code 2, nothing written.

Covers the robustness issue's list: an empty training list, training and held-out sets that
overlap, and perturbations that make an invalid orbit (held-out, listed training scenario,
seeded training sample, the departure itself); single runs and sweeps.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

CASES = [
    (["problem=zermelo", "problem.params.train_scenarios=[]"],
     "problem.params.train_scenarios", "non-empty list"),
    (["problem=qlaw", "case=A", "problem.params.train_scenarios=[{},{control_step_s:40.0}]"],
     "problem.params.train_scenarios", "also in the held-out set"),
    (["problem=zermelo", "problem.params.train_scenarios=[{x0:[2.0,0.0]}]"],
     "problem.params.train_scenarios", "also in the held-out set"),
    (["problem=qlaw", "case=A", "problem.params.holdout_de=0.05"],
     "problem.params.holdout_de", "not an ellipse"),
    (["problem=qlaw", "case=C", "problem.params.train_scenarios=[{},{e0:0.9}]"],
     "problem.params.train_scenarios", "inside the Earth"),
    (["problem=qlaw", "case=A", "problem.params.train_sample=3",
      "problem.params.holdout_de=0.2", "problem.params.holdout_n_perturbed=0"],
     "problem.params.train_sample", "invalid"),
    (["problem=lyapunov_transfer", "case=A", "problem.params.a0_km=5000"],
     "problem.params.a0_km", "inside the Earth"),
]


def _run(args, cwd, multirun=False):
    cmd = [sys.executable, "-m", "penaltyrun.cli"] + (["-m"] if multirun else [])
    return subprocess.run(cmd + args + ["runner.n_starts=1"], cwd=cwd, capture_output=True,
                          text=True, timeout=300)


@pytest.mark.parametrize("args,key,words", CASES,
                         ids=["empty", "overlap-step", "overlap-start", "heldout-orbit",
                              "train-orbit", "sample-orbit", "departure-orbit"])
def test_one_line_exit_2_nothing_written(tmp_path, args, key, words):
    proc = _run(args, tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith(f"penaltyrun: error: {key}: ")
    assert words in lines[0]
    assert "Traceback" not in proc.stderr
    assert list(tmp_path.iterdir()) == []


def test_sweep_stops_before_any_job(tmp_path):
    proc = _run(["problem=qlaw", "case=A,C", "param=diagonal,full",
                 "problem.params.train_scenarios=[{},{control_step_s:40.0}]"], tmp_path,
                multirun=True)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "also in the held-out set" in lines[0]
    assert list(tmp_path.iterdir()) == []
