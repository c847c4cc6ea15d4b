"""Bad parameters of the rendezvous MPC: a ConfigError naming the key, and on the command
line one line and exit code 2; the acceptance evaluation as a user runs it."""

import json
import subprocess
import sys

import numpy as np
import pytest

from penaltyrun import problems
from penaltyrun.errors import ConfigError

Q_ARG = "matrices.Q=" + str([[1.0 if i == j and i < 3 else 100.0 if i == j else 0.0
                              for j in range(6)] for i in range(6)]).replace(" ", "")
R_ARG = "matrices.R=[[1e4,0,0],[0,1e4,0],[0,0,1e4]]"


@pytest.mark.parametrize(("overrides", "key"), [
    ({"horizon": 0}, "problem.params.horizon"),
    ({"horizon": 2.5}, "problem.params.horizon"),
    ({"u_max": -1.0}, "problem.params.u_max"),
    ({"t_max": 3010.0}, "problem.params.t_max"),
    ({"s0": [1.0, 2.0]}, "problem.params.s0"),
    ({"state_scale": [1, 1, 1, 1, 1, 0]}, "problem.params.state_scale"),
    ({"q_eig_bounds": [10.0, 1.0]}, "problem.params.q_eig_bounds"),
    ({"r_eig_bounds": [0.0, 1.0]}, "problem.params.r_eig_bounds"),
    ({"plant": "hill"}, "problem.params.plant"),
    ({"plant_eccentricity": 0.1}, "problem.params.plant_eccentricity"),
    ({"plant": "keplerian", "plant_eccentricity": 0.5}, "problem.params.plant_eccentricity"),
    ({"holdout_thrust_scales": [1.0]}, "problem.params.holdout_thrust_scales"),
    ({"holdout_eccentricities": [-0.1]}, "problem.params.holdout_eccentricities"),
    ({"holdout_n_sphere": -1}, "problem.params.holdout_n_sphere"),
    ({"qp_primal_tol": 0.0}, "problem.params.qp_primal_tol"),
    ({"sample_time": 20.0}, "problem.params.sample_time"),
])
def test_bad_parameter_names_its_key(overrides, key):
    with pytest.raises(ConfigError) as err:
        problems.make("mpc_rendezvous", None, overrides)
    assert err.value.key == key


@pytest.mark.parametrize(("mats", "key"), [
    ({"Q": np.eye(6), "R": [[1.0]]}, "matrices.R"),
    ({"Q": np.eye(6)}, "matrices.R"),
    ({"Q": -np.eye(6), "R": np.eye(3)}, "matrices.Q"),
])
def test_bad_matrices_name_their_key(mats, key):
    prob = problems.make("mpc_rendezvous", None, {})
    with pytest.raises(ConfigError) as err:
        prob.evaluate(mats)
    assert err.value.key == key


def run_cli(tmp_path, *args):
    return subprocess.run([sys.executable, "-m", "penaltyrun.cli", "mode=evaluate",
                           "problem=mpc_rendezvous", *args, f"hydra.run.dir={tmp_path}/run"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300)


def test_cli_reference_evaluation(tmp_path):
    proc = run_cli(tmp_path, Q_ARG, R_ARG)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["converged"] and out["t_final"] == 820.0
    assert out["delta_v"] == pytest.approx(10.42, abs=0.005)


@pytest.mark.parametrize(("args", "key"), [
    (("problem.params.horizon=0",), "problem.params.horizon"),
    (("problem.params.t_max=3010",), "problem.params.t_max"),
    (("matrices.R=[[1,0],[0,1]]",), "matrices.R"),
])
def test_cli_bad_input_is_one_line_and_exit_2(tmp_path, args, key):
    rest = [a for a in (Q_ARG, R_ARG) if not any(a.split("=")[0] == b.split("=")[0]
                                                   for b in args)]
    proc = run_cli(tmp_path, *args, *rest)
    assert proc.returncode == 2
    lines = [ln for ln in proc.stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and key in lines[0]
