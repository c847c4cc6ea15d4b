"""User configs and user problems through the command line (subprocesses, as a user)."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd

from penaltyrun.io import RESULTS_FILE

TINY = ["runner.n_starts=1", "optimizer.n_particles=4", "optimizer.iters=2",
        "runner.report=false"]


def cli(*args, cwd: Path, env_path: str | None = None) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    if env_path:
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [env.get("PYTHONPATH"), env_path]))
    return subprocess.run([sys.executable, "-m", "penaltyrun.cli", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text))
    return path


def one_error_line(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("penaltyrun: error: ")
    return lines[0]


def user_experiment(conf: Path) -> None:
    write(conf / "experiment" / "mine.yaml", """\
        # @package _global_
        defaults:
          - override /problem: zermelo
        runner:
          n_starts: 1
        """)


def test_user_experiment_in_config_dir_runs(tmp_path):
    user_experiment(tmp_path / "myconf")
    proc = cli("--config-dir", "myconf", "+experiment=mine", *TINY[1:],
               f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    df = pd.read_parquet(tmp_path / "run" / RESULTS_FILE)
    assert len(df) == 1 and df["problem"].iloc[0] == "zermelo"


def test_allowed_values_list_user_files(tmp_path):
    user_experiment(tmp_path / "myconf")
    write(tmp_path / "myconf" / "problem" / "zermelo_short.yaml", "name: zermelo\n")
    write(tmp_path / "myconf" / "optimizer" / "pso_tiny.yaml", "name: pso\niters: 2\n")
    write(tmp_path / "myconf" / "param" / "full_narrow.yaml",
          "name: full\neig_bounds: [0.1, 1.0]\n")
    mine = {"experiment": ("mine", "zermelo_paper"), "problem": ("zermelo_short", "qlaw"),
            "optimizer": ("pso_tiny", "de"), "param": ("full_narrow", "givens")}
    forms = [["--config-dir", "myconf"], ["--config-dir=myconf"], ["-cd", "myconf"],
             [f"hydra.searchpath=[file://{tmp_path / 'myconf'}]"]]
    cases = [(forms[0], group) for group in mine] + [(form, "experiment") for form in forms[1:]]
    for args, group in cases:
        key = f"+{group}" if group == "experiment" else group
        line = one_error_line(cli(*args, f"{key}=nope", cwd=tmp_path))
        assert f"{group}: unknown choice 'nope'" in line
        assert all(f" {name}" in line for name in mine[group]), line


def test_malformed_user_experiment_names_file_and_line(tmp_path):
    bad = write(tmp_path / "myconf" / "experiment" / "broken.yaml", """\
        # @package _global_
        runner:
          n_starts: [1, 2
        optimizer: {iters: 3}
        """)
    line = one_error_line(cli("--config-dir", "myconf", "+experiment=broken",
                              cwd=tmp_path))
    assert f"{bad}:4:" in line and "malformed YAML" in line, line
    write(bad, "- just\n- a list\n")
    line = one_error_line(cli("--config-dir", "myconf", "+experiment=broken", cwd=tmp_path))
    assert f"{bad}:1:" in line and "mapping" in line, line


def test_config_path_with_own_primary_config(tmp_path):
    write(tmp_path / "lab" / "lab.yaml", """\
        defaults:
          - config
          - override problem: zermelo_fast
          - _self_
        runner:
          n_starts: 1
          report: false
        hydra:
          searchpath:
            - pkg://penaltyrun.conf
        """)
    write(tmp_path / "lab" / "problem" / "zermelo_fast.yaml", """\
        name: zermelo
        params:
          t_max: 500.0
        """)
    proc = cli("--config-path", "lab", "--config-name", "lab", *TINY[1:3],
               f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    df = pd.read_parquet(tmp_path / "run" / RESULTS_FILE)
    assert '"t_max": 500.0' in df["problem_params"].iloc[0]
    line = one_error_line(cli("-cp", "lab", "-cn", "lab", "problem=nope", cwd=tmp_path))
    assert "zermelo_fast" in line and "attitude_lqr" in line
    line = one_error_line(cli("--config-path", "lab", cwd=tmp_path))
    assert "--config-path" in line and "config.yaml" in line
    line = one_error_line(cli("--config-dir", "missing", cwd=tmp_path))
    assert "--config-dir" in line and "not a directory" in line


def test_problem_module_lacking_protocol_is_one_line(tmp_path):
    write(tmp_path / "mods" / "halfprob.py", "CASES = ('a',)\n")
    write(tmp_path / "conf" / "problem" / "half.yaml", "name: half\nmodule: halfprob\n")
    line = one_error_line(cli("--config-dir", "conf", "problem=half", *TINY,
                              f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path,
                              env_path=str(tmp_path / "mods")))
    assert "problem.module" in line and "halfprob lacks DEFAULT_CASE, make_problem" in line
    line = one_error_line(cli("--config-dir", "conf", "problem=half", *TINY,
                              f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path))
    assert "cannot import 'halfprob'" in line and "PYTHONPATH" in line
    assert not (tmp_path / "run" / "jobs").exists()


def test_problem_object_lacking_protocol_is_one_line(tmp_path):
    write(tmp_path / "mods" / "thinprob.py", """\
        CASES = ("a",)
        DEFAULT_CASE = "a"

        class Thin:
            name, case, matrices, scalars = "thin", "a", (), ()

            def evaluate(self, mats, scalars=None):
                return {}

        def make_problem(case, params):
            return Thin()
        """)
    write(tmp_path / "conf" / "problem" / "thin.yaml", "name: thin\nmodule: thinprob\n")
    line = one_error_line(cli("--config-dir", "conf", "problem=thin", *TINY,
                              f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path,
                              env_path=str(tmp_path / "mods")))
    assert "lacks evaluate_batch, simulate" in line, line


def test_version_is_penaltyrun_s(tmp_path):
    from penaltyrun import __version__

    proc = cli("--version", cwd=tmp_path)
    assert proc.returncode == 0 and proc.stdout.strip() == f"penaltyrun {__version__}"
    report = subprocess.run([sys.executable, "-c", "from penaltyrun.cli import report_main; "
                             "report_main()", "--version"], capture_output=True, text=True,
                            timeout=120)
    assert report.stdout.strip() == f"penaltyrun {__version__}"


def test_a_config_dir_file_named_like_a_builtin_is_one_line(tmp_path):
    """Hydra finds penaltyrun's own problem/zermelo.yaml before the user's: refused with the
    fix instead of being ignored without a word."""
    write(tmp_path / "myconf" / "problem" / "zermelo.yaml",
          "name: zermelo\nparams:\n  x0: [3.0, 4.0]\n")
    line = one_error_line(cli("--config-dir", "myconf", "problem=zermelo", *TINY, cwd=tmp_path))
    assert "myconf/problem/zermelo.yaml" in line and "pass problem=zermelo_mine" in line
