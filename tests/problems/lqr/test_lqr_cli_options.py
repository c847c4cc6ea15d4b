"""The control engineer's options end to end from the command line, on a plant written here
(not shipped): a discrete-time pendulum with expressions, a semi-definite Q, integral action
and a disk-margin constraint; tuned, stored, reported and exported; bad input exits 2."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from penaltyrun.io import read_results

PLANT = """\
name: lqr
params:
  constants: {m: 0.5, l: 0.4, g: 9.81, Ts: 0.05}
  A: [[1, Ts], ["g/l*Ts", 1]]
  B: [[0], ["Ts/(m*l**2)"]]
  dt: Ts
  integral_outputs: [[1, 0]]
  q_output: [[1, 0, 0], [0, 0, 1]]
  disk_margin_min: 0.5
  x0: [[0.1, 0], [0, 0.5]]
  t_max: 5
  holdout_n: 2
"""
CLI = [sys.executable, "-m", "penaltyrun.cli"]


def run(args, cwd, code=0):
    proc = subprocess.run(args, cwd=cwd, capture_output=True, text=True, timeout=600,
                          env=dict(os.environ))
    assert proc.returncode == code, proc.stderr
    return proc


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    where = tmp_path_factory.mktemp("lqr_options")
    (where / "conf" / "problem").mkdir(parents=True)
    (where / "conf" / "problem" / "pendulum.yaml").write_text(PLANT)
    (where / "conf" / "problem" / "blind.yaml").write_text(
        PLANT.replace("q_output: [[1, 0, 0], [0, 0, 1]]", "q_output: [[0, 1, 0]]"))
    return where


@pytest.mark.slow  # about 20 s: two tiny tuning runs, the report and the export
def test_tune_report_export(folder):
    run(CLI + ["--config-dir", "conf", "-m", "problem=pendulum", "param=diagonal,full",
               "optimizer=cmaes", "optimizer.max_evals=60", "runner.n_starts=1",
               "hydra.sweep.dir=out"], folder)
    df = read_results(folder / "out")
    assert set(df["param"]) == {"diagonal", "full"} and set(df["problem"]) == {"lqr"}
    assert (df["n_evals"] == 60).all()
    run([sys.executable, "-c", "from penaltyrun.cli import report_main; report_main()",
         "out", "-o", "out/report", "--export", "out/export"], folder)
    text = (folder / "out" / "report" / "report.md").read_text()
    assert "lqr / default" in text
    exported = list((folder / "out" / "export").glob("*.json"))
    assert len(exported) == 2


def test_evaluate_reports_the_design(folder):
    out = run(CLI + ["--config-dir", "conf", "mode=evaluate", "problem=pendulum",
                     "matrices.Q=[[10,0],[0,1]]", "matrices.R=[[1]]"], folder)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["dt"] == 0.05 and result["method"] == "stepped"
    assert np.array(result["gain"]).shape == (1, 3)  # position, velocity, integral
    assert np.array(result["state_penalty"])[1, 1] == 0.0  # semi-definite Q
    assert result["disk_margin"]["alpha"] > 0 and result["limits"]["disk_margin_min"] == 0.5
    poles = np.array(result["closed_loop_poles"])
    assert np.all(np.hypot(poles[:, 0], poles[:, 1]) < 1.0)


def test_undetectable_q_exits_2_with_one_line(folder):
    proc = run(CLI + ["--config-dir", "conf", "mode=evaluate", "problem=blind",
                      "matrices.Q=[[1]]", "matrices.R=[[1]]"], folder, code=2)
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("penaltyrun: error")]
    assert len(lines) == 1 and "not detectable" in lines[0] and "q_output" in lines[0]
