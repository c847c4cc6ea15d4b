"""Command lines that Hydra would run silently in a way the user did not mean, or refuse with
a message that does not say the fix: each is one line on stderr, exit code 2 and the fix.
Also a report over an interrupted run, and help piped into a reader that stops early."""

import subprocess
import sys
import textwrap

import pytest
from cli_subprocess import FAST_JOBS, cli, cli_forked, one_error_line, report
from hypothesis import given
from hypothesis import strategies as st

from penaltyrun.cli.args import matlab_to_yaml
from penaltyrun.io import RESULTS_FILE

LQR_FILE = textwrap.dedent("""\
    name: lqr
    params:
      A: [[0, 1], [0, 0]]
      B: [[0], [1]]
    """)
K = "matrices.K=[[1,0],[0,1]]"


def _files(root) -> None:
    """Config files in the wrong places, as a newcomer puts them."""
    for rel in ("myconf/two_carts.yaml", "other/experiment/plant.yaml", "lab/problem/near.yaml",
                "loose.yaml"):
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(LQR_FILE)


#: (arguments, fragments the one error line must hold). ``{cwd}`` is the case's directory.
CASES = [
    (["-m", "optimizer=baseline", "hydra.run.dir={cwd}/mine"],
     ["hydra.run.dir: a sweep (-m) ignores hydra.run.dir", "hydra.sweep.dir={cwd}/mine"]),
    (["-m", "mode=evaluate", K, "param=diagonal,full", "hydra.sweep.dir={cwd}/ev"],
     ["param: mode=evaluate does not read param", "same matrices 2 times", "drop it"]),
    (["-m", "mode=evaluate", K, "optimizer.iters=5,10,20", "hydra.sweep.dir={cwd}/ev"],
     ["optimizer.iters: mode=evaluate does not read optimizer", "3 times"]),
    (["mode=evaluate", "matrices.K=[1 0; 0 1]"],
     ["matrices.K: MATLAB matrix syntax '[1 0; 0 1]'", "'matrices.K=[[1,0],[0,1]]'"]),
    (["mode=evaluate", "matrices.K=[1 0 0 1]"],
     ["MATLAB matrix syntax", "'matrices.K=[1,0,0,1]'"]),
    (["mode=evaluate", "matrices.K=[2,-1;-1,2]"], ["'matrices.K=[[2,-1],[-1,2]]'"]),
    (["optimizer=baseline", "hydra.run.dir={cwd}/résultats"],
     ["hydra.run.dir: Hydra reads 'é' only inside quotes",
      "'hydra.run.dir=\"{cwd}/résultats\"'"]),
    (["optimizer=baseline", "report.output=报告"], ["report.output", "'report.output=\"报告\"'"]),
    (["optimizer=baseline", "runner.n_starts=１"],
     ["runner.n_starts: '１' is written in full-width", "write runner.n_starts=1"]),
    (["--config-dir", "myconf", "problem=two_carts"],
     ["problem: unknown choice 'two_carts'", "myconf/two_carts.yaml is outside the problem/",
      "move it to myconf/problem/two_carts.yaml"]),
    (["--config-dir", "other", "problem=plant"],
     ["other/experiment/plant.yaml is outside the problem/", "other/problem/plant.yaml"]),
    (["problem=myconf/two_carts.yaml"],
     ["must be in a problem/ folder", "pass --config-dir myconf problem=two_carts"]),
    (["problem=lab/problem/near.yaml"],
     ["a choice is a name, not a path: pass --config-dir lab problem=near"]),
    (["problem=near"], ["lab/problem/near.yaml is not searched: pass --config-dir lab"]),
    (["problem=two_carts"], ["move it to myconf/problem/two_carts.yaml and pass --config-dir "
                             "myconf problem=two_carts"]),
    (["problem=loose"], ["move it to conf/problem/loose.yaml and pass --config-dir conf"]),
    (["--config-path", "myconf", "--config-name", "two_carts"],
     ["--config-name: myconf/two_carts.yaml is a problem config (name: lqr), not a primary",
      "--config-dir myconf problem=two_carts"]),
    (["--config-dir", "myconf", "--config-name", "two_carts"], ["is a problem config"]),
]


@pytest.fixture(scope="module")
def hint_runs(tmp_path_factory):
    """Every case at once, each in a fresh directory of its own (see ``cli_forked``)."""
    cwds = [tmp_path_factory.mktemp("hint") for _ in CASES]
    for cwd in cwds:
        _files(cwd)
    runs = cli_forked([([a.replace("{cwd}", str(cwd)) for a in args], cwd)
                       for (args, _), cwd in zip(CASES, cwds)])
    return list(zip(runs, cwds))


@pytest.mark.parametrize("case", range(len(CASES)), ids=[" ".join(a) for a, _ in CASES])
def test_each_case_is_one_line_with_the_fix(hint_runs, case):
    proc, cwd = hint_runs[case]
    assert proc.returncode == 2, proc.stderr
    line = one_error_line(proc)
    assert line.startswith("penaltyrun: error: ")
    for fragment in CASES[case][1]:
        assert fragment.replace("{cwd}", str(cwd)) in line, line
    assert not list(cwd.rglob("jobs")) and not (cwd / "outputs").exists()


@pytest.mark.slow  # about 18 s: four runs, each compiling its kernels
def test_the_fixes_run(tmp_path):
    """What the lines above propose is accepted: the quoted unicode folder, the YAML matrix,
    hydra.sweep.dir with -m, and a sweep of evaluate over matrices."""
    cwd = tmp_path
    runs = cli_forked([
        ([*FAST_JOBS, f'hydra.run.dir="{cwd}/résultats"'], cwd),
        (["mode=evaluate", "matrices.K=[[1,0],[0,1]]"], cwd),
        (["-m", *FAST_JOBS, f"hydra.sweep.dir={cwd}/sweep"], cwd),
        (["-m", "mode=evaluate", "matrices.K=[[1,0],[0,1]],[[2,0],[0,2]]"], cwd)])
    assert [r.returncode for r in runs] == [0, 0, 0, 0], [r.stderr for r in runs]
    assert (cwd / "résultats" / RESULTS_FILE).is_file()
    assert len(list((cwd / "sweep").rglob(RESULTS_FILE))) == 1
    assert runs[3].stdout.count('"converged": true') == 2


def test_a_refused_evaluation_leaves_the_current_directory_alone(tmp_path):
    """An evaluation writes nothing, so its Hydra run directory is the current one: a
    matrix refused inside the run must not remove it with the log files in it; a run
    directory Hydra made for the evaluation (hydra.run.dir) is removed."""
    here = tmp_path / "here"
    here.mkdir()
    (here / "notes.log").write_text("mine")
    bad = "matrices.K=[[1,0,0],[0,1,0],[0,0,1]]"  # refused inside the run: its size
    for extra in ([], [f"hydra.run.dir={tmp_path / 'made'}"]):
        proc = cli("mode=evaluate", bad, *extra, cwd=here, timeout=300)
        assert proc.returncode == 2 and "2x2" in one_error_line(proc)
    assert (here / "notes.log").read_text() == "mine"
    assert not (tmp_path / "made").exists()


@pytest.mark.parametrize("value, yaml", [
    ("[1 0; 0 1]", "[[1,0],[0,1]]"), ("[1 0 0 1]", "[1,0,0,1]"), ("[1,0;0,1]", "[[1,0],[0,1]]"),
    ("[ 1.5e-3 -2 ; -2 4 ;]", "[[1.5e-3,-2],[-2,4]]"), ("[.5]", None), ("[1, 2, 3]", None),
    ("[[1,0],[0,1]]", None), ("[a b; c d]", None), ("2", None), ("[]", None)])
def test_matlab_to_yaml(value, yaml):
    assert matlab_to_yaml(value) == yaml


@given(st.lists(st.lists(st.integers(-99, 99), min_size=2, max_size=2), min_size=2,
                max_size=4))
def test_matlab_rows_become_the_same_yaml_matrix(rows):
    import yaml

    matlab = "[" + "; ".join(" ".join(str(v) for v in row) for row in rows) + "]"
    assert yaml.safe_load(matlab_to_yaml(matlab)) == rows


@pytest.mark.slow  # about 12 s: a run and a report (tests/io covers the reading cheaply)
def test_report_of_an_interrupted_run_reports_its_finished_records(tmp_path):
    run = tmp_path / "run"
    done = cli_forked([([*FAST_JOBS, "runner.n_starts=3", f"hydra.run.dir={run}"], tmp_path)])
    assert done[0].returncode == 0, done[0].stderr
    (run / RESULTS_FILE).unlink()  # as if the run was stopped before collecting
    (run / "jobs" / "garbage.json").write_text("{not json")
    proc = report(str(tmp_path), "-o", str(tmp_path / "rep"))
    assert proc.returncode == 0, proc.stderr
    warning = [ln for ln in proc.stderr.splitlines() if "no results.parquet" in ln]
    assert len(warning) == 1 and "its 3 finished job records" in warning[0]
    assert "runner.resume=true" in warning[0]
    assert "garbage.json" in proc.stderr  # left out, named, not moved: the run may be live
    assert (run / "jobs" / "garbage.json").exists()
    assert "3 jobs" in (tmp_path / "rep" / "report.md").read_text()


@pytest.mark.parametrize("module, flag", [("penaltyrun.cli", "--help"),
                                          ("penaltyrun.cli", "--version"),
                                          ("penaltyrun.report_cli", "--help"),
                                          ("penaltyrun.report_cli", "--version")])
def test_help_into_a_closed_pipe_ends_quietly(module, flag):
    """``penaltyrun --help | head``: the reader closes the pipe before the text is written."""
    proc = subprocess.Popen([sys.executable, "-m", module, flag], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 0, err
    assert err == ""
