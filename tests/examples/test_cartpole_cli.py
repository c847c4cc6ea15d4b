"""The cart-pole example run as its README says, from a copy outside the repository."""

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.io import loadmat

from penaltyrun.io import decode_json, read_results

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "cartpole"
#: Appended to the README's optimize commands: a budget of seconds, not minutes.
TINY = ["runner.n_starts=1", "optimizer.n_particles=4", "optimizer.iters=2"]
REPORT = "from penaltyrun.cli import report_main; report_main()"


def readme_blocks(lang: str) -> list[str]:
    text = (EXAMPLE / "README.md").read_text()
    return re.findall(rf"```{lang}\n(.*?)```", text, flags=re.S)


def run_documented(line: str, cwd: Path) -> subprocess.CompletedProcess:
    """One README command line with ``penaltyrun``/``penaltyrun-report`` as this Python."""
    words = shlex.split(line)
    env = dict(os.environ)
    while "=" in words[0]:  # leading VAR=value assignments
        name, value = words.pop(0).split("=", 1)
        env[name] = os.pathsep.join(filter(None, [value, env.get(name)]))
    program = {"penaltyrun": [sys.executable, "-m", "penaltyrun.cli"],
               "penaltyrun-report": [sys.executable, "-c", REPORT]}[words[0]]
    args = words[1:]
    if words[0] == "penaltyrun" and not any(a.startswith("mode=") for a in args):
        args += TINY
    proc = subprocess.run(program + args, cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, f"{line}\n{proc.stdout}\n{proc.stderr}"
    return proc


def copy_example(tmp_path_factory) -> Path:
    """A copy of the example outside the repository, as a user would have it."""
    where = tmp_path_factory.mktemp("outside") / "cartpole"
    shutil.copytree(EXAMPLE, where, ignore=shutil.ignore_patterns("outputs", "__pycache__"))
    assert not str(where).startswith(str(EXAMPLE.parents[1]))
    return where


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    """The copied example with nothing run in it yet."""
    return copy_example(tmp_path_factory)


@pytest.fixture(scope="module")
def copied(tmp_path_factory):
    """A copy in which the README's first block (optimize + report) has run."""
    where = copy_example(tmp_path_factory)
    for line in readme_blocks("sh")[0].strip().splitlines():  # optimize + report
        run_documented(line, where)
    return where


@pytest.mark.slow  # about 18 s: a whole tuning run and its report
def test_readme_optimize_and_report_commands(copied):
    out = copied / "outputs" / "cartpole"
    df = read_results(out)
    assert set(df["problem"]) == {"lqr"} and set(df["param"]) == {"diagonal", "full"}
    assert set(df["status"]) <= {"ok", "diverged"}
    text = (out / "report" / "report.md").read_text()
    assert "| lqr | default | setup=dynamics=cartpole:dynamics#" in text
    assert "unresolved" not in text
    assert "![closed-loop state and input norms" in text  # --plant-module cartpole
    for _, row in df.iterrows():
        (mat_file,) = (out / "export").glob(f"lqr_default_*_pso_{row['param']}.mat")
        mat = loadmat(mat_file)
        mats = decode_json(row["matrices"])
        np.testing.assert_array_equal(mat["Q"], np.asarray(mats["Q"]))
        np.testing.assert_array_equal(mat["R"], np.asarray(mats["R"]))


@pytest.mark.slow
def test_readme_study_commands(copied):
    for line in readme_blocks("sh")[1].strip().splitlines():  # study + report
        run_documented(line, copied)
    out = copied / "outputs" / "study"
    df = read_results(out)
    assert set(zip(df["case"], df["param"])) == {("default", p) for p in ("diagonal", "full")}
    assert len(list((out / "export").glob("*.mat"))) == 2
    assert "| lqr | default |" in (out / "report" / "report.md").read_text()


def test_readme_evaluate_command(example):
    line = next(ln for block in readme_blocks("sh") for ln in block.splitlines()
                if "mode=evaluate" in ln)
    result = json.loads(run_documented(line, example).stdout.strip().splitlines()[-1])
    assert result["problem"] == "lqr" and np.shape(result["gain"]) == (1, 4)
    assert np.isfinite(result["cost"])


@pytest.mark.slow  # it reads the exported matrices of the README's tuning run (about 18 s)
def test_readme_python_control_snippet(copied):
    pytest.importorskip("control")
    script = copied / "snippet.py"
    script.write_text(readme_blocks("python")[0])
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [".", env.get("PYTHONPATH")]))
    proc = subprocess.run([sys.executable, str(script)], cwd=copied, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr



def test_the_export_pages_snippet_is_the_readmes():
    """The export how-to shows the README's python-control snippet, which the test above
    runs."""
    page = (EXAMPLE.parents[1] / "docs" / "how-to" / "export.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", page, flags=re.S)
    assert readme_blocks("python")[0] in blocks
