"""docs/tutorials/tune-your-lqr.md works as written: its YAML file and its commands (the
optimize command with a budget of seconds), from a folder outside the repository."""

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from penaltyrun.io import read_results

DOC = Path(__file__).resolve().parents[3] / "docs" / "tutorials" / "tune-your-lqr.md"
TINY = ["runner.n_starts=1", "optimizer.max_evals=40"]
PROGRAMS = {"penaltyrun": [sys.executable, "-m", "penaltyrun.cli"],
            "penaltyrun-report": [sys.executable, "-c",
                                  "from penaltyrun.cli import report_main; report_main()"]}


def blocks(lang):
    return re.findall(rf"```{lang}\n(.*?)```", DOC.read_text(), flags=re.S)


def run(line, cwd):
    words = shlex.split(line)
    args = words[1:]
    if words[0] == "penaltyrun" and not any(a.startswith("mode=") for a in args):
        args = [a for a in args if not a.startswith(("optimizer.max_evals", "runner.n_starts"))]
        args += TINY
    proc = subprocess.run(PROGRAMS[words[0]] + args, cwd=cwd, capture_output=True, text=True,
                          timeout=600, env=dict(os.environ))
    assert proc.returncode == 0, f"{line}\n{proc.stderr}"
    return proc


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    where = tmp_path_factory.mktemp("tutorial")
    (where / "myconf" / "problem").mkdir(parents=True)
    (where / "myconf" / "problem" / "two_carts.yaml").write_text(blocks("yaml")[0])
    return where


def test_yaml_is_a_valid_problem(folder):
    from penaltyrun import problems

    params = yaml.safe_load(blocks("yaml")[0])["params"]
    prob = problems.make("lqr", None, params)
    assert [s.size for s in prob.matrices] == [4, 2] and prob.u_max is not None


@pytest.mark.slow  # about 18 s: a whole tuning run and its report
def test_tune_and_report_commands(folder):
    for line in blocks("sh")[0].strip().splitlines():
        run(line, folder)
    out = folder / "outputs" / "two_carts"
    df = read_results(out)
    assert set(df["param"]) == {"diagonal", "full"} and set(df["problem"]) == {"lqr"}
    assert (out / "report" / "report.md").is_file()
    assert len(list((out / "export").glob("*.mat"))) == 2


def test_evaluate_command(folder):
    result = json.loads(run(blocks("sh")[1].strip(), folder).stdout.strip().splitlines()[-1])
    for key in ("cost", "status", "start_costs", "start_status", "gain", "closed_loop_poles",
                "optimum"):
        assert key in result
    assert result["cost"] >= result["optimum"]  # J* bounds the infinite-horizon cost; tail ~0


@pytest.mark.slow
def test_known_answer_commands(folder):
    for line in blocks("sh")[2].strip().splitlines():
        run(line.strip(), folder)
    out = folder / "outputs" / "known_answer"
    assert set(read_results(out)["param"]) == {"diagonal", "full"}
    text = (out / "report" / "report.md").read_text()
    assert "Best-known optima" in text


def test_options_section_yaml_and_evaluate(folder):
    from penaltyrun import problems

    params = yaml.safe_load(blocks("yaml")[1])["params"]
    prob = problems.make("lqr", None, params)
    assert prob.dt == params["constants"]["Ts"] and prob.plant.n_states == 3
    assert [s.size for s in prob.matrices] == [2, 1]
    (folder / "myconf" / "problem" / "pendulum.yaml").write_text(blocks("yaml")[1])
    line = blocks("sh")[3].strip()
    assert "problem=pendulum" in line
    def refuse(token):
        raise AssertionError(f"not strict JSON: {token}")

    # strict JSON: an output that never settles has no number, and is null, not Infinity
    result = json.loads(run(line, folder).stdout.strip().splitlines()[-1],
                        parse_constant=refuse)
    for key in ("state_penalty", "disk_margin", "settling_time", "overshoot_percent", "dt",
                "limits"):
        assert key in result
    assert None in result["settling_time"]
    assert np.asarray(result["state_penalty"])[1, 1] == 0.0
