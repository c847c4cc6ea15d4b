"""Criterion settings through the configuration: the shipped configs hash and plan as before
the criteria existed, a criterion is set on the command line like any parameter, and a bad
setting is one line on stderr with exit code 2."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from penaltyrun.api.compose import compose, run_spec
from penaltyrun.runner import config_hash

#: Config hashes and first job ids of default cells, as computed before the criteria keys
#: were listed in the problem YAMLs (committed studies find their runs by them).
PINNED = {
    ("attitude_lyapunov", None): ("bc9407df8a9c4f8f",
                                  "attitude_lyapunov-default-full-pso-112ff7ca-s000"),
    ("attitude_lqr", "rest_to_rest"): ("9e44f4971654d20c",
                                       "attitude_lqr-default-full-pso-112ff7ca-s000"),
    ("mpc_rendezvous", None): ("adf906a9e718751f",
                               "mpc_rendezvous-default-full-pso-ff31ec09-s000"),
    ("lqr", None): ("412d857a70acb1a1", "lqr-default-full-pso-f0db8a83-s000"),
}


@pytest.mark.parametrize("problem,case", sorted(PINNED, key=str))
def test_default_cells_hash_and_plan_as_before(problem, case):
    config = compose(problem, None, case=case, param="full", optimizer="pso",
                     optimizer_options=None, params=None,
                     runner={"seed": 20250422, "n_starts": 10})
    assert "criterion" in config["problem"]["params"]    # listed, left null
    spec = run_spec(config)
    assert (config_hash(spec.hashed), spec.plan("default")[0].job_id) \
        == PINNED[(problem, case)]


def test_a_set_criterion_changes_the_hash_and_the_job_id():
    config = compose("mpc_rendezvous", None, case=None, param="full", optimizer="pso",
                     optimizer_options=None, params={"criterion": "time_energy"},
                     runner={"seed": 20250422, "n_starts": 10})
    spec = run_spec(config)
    old_hash, old_id = PINNED[("mpc_rendezvous", None)]
    assert config_hash(spec.hashed) != old_hash
    assert spec.plan("default")[0].job_id != old_id


def _cli(args, cwd):
    return subprocess.run([sys.executable, "-m", "penaltyrun.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


def test_cli_evaluates_a_criterion(tmp_path):
    proc = _cli(["mode=evaluate", "problem=lqr", "problem.params.criterion=time_energy",
                 "problem.params.rho=0.5", "matrices.Q=[[1,0,0],[0,1,0],[0,0,1]]",
                 "matrices.R=[[1,0],[0,1]]"], tmp_path)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["converged"] and out["t_final"] < 1000.0


@pytest.mark.parametrize("args,key,words", [
    (["problem=mpc_rendezvous", "problem.params.criterion=fastest"],
     "problem.params.criterion", "unknown criterion"),
    (["problem=attitude_lqr", "problem.params.criterion=terminal",
      "problem.params.terminal_weight=[1,2]"], "problem.params.terminal_weight", "6 diagonal"),
    (["problem=lqr", "problem.params.criterion=terminal",
      "problem.params.terminal_weight=[[1,2,0],[2,1,0],[0,0,1]]"],
     "problem.params.terminal_weight", "semidefinite"),
    (["problem=attitude_lyapunov", "problem.params.rho=-1"], "problem.params.rho", "positive"),
], ids=["mpc-name", "attitude-shape", "lqr-psd", "attitude-rho"])
def test_bad_criterion_settings_one_line_exit_2(tmp_path, args, key, words):
    proc = _cli([*args, "runner.n_starts=1"], tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith(f"penaltyrun: error: {key}: ") and words in lines[0]
    assert list(tmp_path.iterdir()) == []
