"""A user problem that misbehaves costs one job (subprocess tests of the command line): a
job that sleeps or spins past ``runner.job_timeout`` is killed and recorded ``timeout``;
KeyboardInterrupt, SystemExit, ``os._exit`` and a segmentation fault in the problem's code
are recorded ``failed``; each gives one line and no traceback, the other jobs finish, and
nothing hangs. A Ctrl-C of the run still stops it."""

from __future__ import annotations

import json
import os
import signal
import textwrap
import time

import pandas as pd
import pytest
from cli_subprocess import cli, cli_forked, popen

from penaltyrun.io import RESULTS_FILE

#: The first job (of any process) to evaluate a candidate misbehaves as its case says.
MODULE = textwrap.dedent('''
    import os
    import signal
    import sys
    import time

    import numpy as np

    from penaltyrun.problems.base import BatchEvaluation, MatrixSpec

    CASES = ("sleep", "spin", "interrupt", "sysexit", "osexit", "segv")
    DEFAULT_CASE = "sleep"


    def misbehave(case):
        try:
            os.close(os.open("misbehaved.flag", os.O_CREAT | os.O_EXCL))
        except FileExistsError:
            return
        if case == "sleep":
            time.sleep(3600)
        elif case == "spin":
            while True:
                pass
        elif case == "interrupt":
            raise KeyboardInterrupt
        elif case == "sysexit":
            sys.exit(3)
        elif case == "osexit":
            os._exit(3)
        elif case == "segv":
            os.kill(os.getpid(), signal.SIGSEGV)


    class Bad:
        name = "bad"
        matrices = (MatrixSpec("K", 1, (0.1, 10.0)),)
        scalars = ()

        def __init__(self, case):
            self.case = case

        def evaluate_batch(self, mats, scalars=None):
            misbehave(self.case)
            cost = np.sum(np.asarray(mats["K"]) ** 2, axis=(1, 2))
            return BatchEvaluation(cost, np.ones(len(cost), bool),
                                   np.array(["converged"] * len(cost), dtype=object))

        def evaluate(self, mats, scalars=None):
            return {"cost": float(np.sum(np.asarray(mats["K"]) ** 2)), "converged": True,
                    "status": "converged", "t_final": 0.0}

        def simulate(self, mats, scalars=None):
            return {"t": np.zeros(1)}


    def make_problem(case, params):
        return Bad(case)
''')
#: Three one-evaluation jobs of the module's problem (diagonal map: no compiled kernel).
ARGS = ["problem=lab.bad", "param=diagonal", "optimizer=baseline", "runner.n_starts=3",
        "runner.report=false", "runner.forecast_samples=0", "runner.progress=false"]


@pytest.fixture
def lab(tmp_path, monkeypatch):
    """A folder on PYTHONPATH holding the package ``lab`` with the module ``lab.bad``."""
    (tmp_path / "lab").mkdir()
    (tmp_path / "lab" / "__init__.py").write_text("")
    (tmp_path / "lab" / "bad.py").write_text(MODULE)
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    return tmp_path


def _run_cases(lab, cases):
    """Run each ``(case, extra args)`` in a folder of its own (one interpreter, forked per
    case); returns ``(completed process, run folder)`` per case."""
    runs = []
    for case, extra in cases:
        cwd = lab / f"{case}-{len(runs)}"
        cwd.mkdir()
        runs.append(([*ARGS, f"case={case}", *extra, f"hydra.run.dir={cwd / 'run'}"], cwd))
    t0 = time.monotonic()
    procs = cli_forked(runs, timeout=120)
    assert time.monotonic() - t0 < 120
    return [(proc, cwd / "run") for proc, (_, cwd) in zip(procs, runs)]


def _check(proc, run, status, fragment):
    """One job ``status`` with ``fragment`` in its error, two ok; exit 3; one line (and no
    traceback) about the job besides the progress line and the summary."""
    assert proc.returncode == 3, proc.stderr
    output = proc.stdout + proc.stderr
    assert "Traceback" not in output, output
    df = pd.read_parquet(run / RESULTS_FILE)
    assert sorted(df["status"]) == sorted(["ok", "ok", status])
    bad = df[df["status"] == status].iloc[0]
    assert fragment in bad["error"] and "\n" not in bad["error"]
    about = [ln for ln in output.splitlines() if bad["job_id"] in ln
             and "[INFO]" not in ln and not ln.startswith("penaltyrun: 3 jobs")]
    assert len(about) == 1, output
    assert proc.stderr.strip().splitlines() == [ln for ln in proc.stderr.strip().splitlines()
                                                if ln.startswith("penaltyrun: 3 jobs")]
    with open(run / "jobs" / f"{bad['job_id']}.json", encoding="utf-8") as fh:
        assert json.load(fh)["status"] == status


def test_a_hanging_and_an_interrupting_user_problem_cost_one_job_each(lab):
    cases = [("sleep", ["runner.workers=2", "runner.job_timeout=1"]),
             ("interrupt", ["runner.workers=2"])]
    sleep, interrupt = _run_cases(lab, cases)
    _check(*sleep, "timeout", "runner.job_timeout=1 s")
    _check(*interrupt, "failed", "KeyboardInterrupt: raised by the job's code")


@pytest.mark.slow
def test_more_misbehaving_user_code(lab):
    cases = [("osexit", ["runner.workers=2"]),
             ("segv", ["runner.workers=2"]),
             ("spin", ["runner.workers=2", "runner.job_timeout=1"]),
             ("sleep", ["runner.workers=1", "runner.job_timeout=1"]),
             ("sysexit", ["runner.workers=2"]),
             ("interrupt", ["runner.workers=1"]),
             ("sysexit", ["runner.workers=1"])]
    osexit, segv, spin, sleep1, sysexit, interrupt1, sysexit1 = _run_cases(lab, cases)
    _check(*osexit, "failed", "exited with code 3")
    _check(*segv, "failed", "died of SIGSEGV")
    _check(*spin, "timeout", "runner.job_timeout=1 s")
    _check(*sleep1, "timeout", "runner.job_timeout=1 s")
    _check(*sysexit, "failed", "SystemExit: the job's code called sys.exit(3)")
    _check(*interrupt1, "failed", "KeyboardInterrupt: raised by the job's code")
    _check(*sysexit1, "failed", "SystemExit: the job's code called sys.exit(3)")


@pytest.mark.slow
def test_a_timed_out_job_runs_again_on_resume_with_retry_failed(lab):
    run = lab / "run"
    args = [*ARGS, "case=sleep", "runner.workers=2", f"hydra.run.dir={run}"]
    first = cli(*args, "runner.job_timeout=1", cwd=lab, timeout=120)
    assert first.returncode == 3 and "1 timeout" in first.stderr
    kept = cli(*args, "runner.resume=true", cwd=lab, timeout=120)
    assert kept.returncode == 3 and "3 of 3 jobs already finished" in kept.stdout + kept.stderr
    again = cli(*args, "runner.resume=true", "runner.retry_failed=true", cwd=lab,
                timeout=120)  # the flag exists now: the job runs normally
    assert again.returncode == 0, again.stderr
    assert "2 of 3 jobs already finished" in again.stdout + again.stderr
    assert set(pd.read_parquet(run / RESULTS_FILE)["status"]) == {"ok"}


@pytest.mark.slow
@pytest.mark.parametrize("extra", [["runner.workers=1"],
                                   ["runner.workers=1", "runner.job_timeout=600"]])
def test_ctrl_c_still_stops_a_run_whose_job_hangs(lab, extra):
    run = lab / "run"
    proc = popen(*ARGS, "case=sleep", *extra, f"hydra.run.dir={run}", cwd=lab)
    try:
        deadline = time.monotonic() + 60
        while not (lab / "misbehaved.flag").exists():
            assert time.monotonic() < deadline and proc.poll() is None
            time.sleep(0.1)
        time.sleep(0.5)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "runner.resume=true" in err.strip().splitlines()[-1]


@pytest.mark.slow
def test_a_module_edited_before_resume_is_a_new_configuration(lab):
    run = lab / "run"
    args = [*ARGS, "case=interrupt", "runner.workers=2", f"hydra.run.dir={run}"]
    first = cli(*args, cwd=lab, timeout=120)
    assert first.returncode == 3, first.stderr
    old = set(pd.read_parquet(run / RESULTS_FILE)["job_id"])
    with open(lab / "lab" / "bad.py", "a", encoding="utf-8") as fh:
        fh.write("\nEDITED = True\n")
    resumed = cli(*args, "runner.resume=true", cwd=lab, timeout=120)
    assert resumed.returncode == 0, resumed.stderr  # the flag exists: every job runs well
    output = resumed.stdout + resumed.stderr
    assert "0 of 3 jobs already finished" in output
    warned = [ln for ln in output.splitlines() if "was edited since" in ln]
    assert len(warned) == 1 and "problem module lab.bad" in warned[0], output
    new = pd.read_parquet(run / RESULTS_FILE)
    assert len(new) == 3 and not set(new["job_id"]) & old  # nothing mixed
    assert len(list((run / "jobs").glob("*.json"))) == 6


def test_a_problem_whose_construction_misbehaves_is_one_line_and_exit_2(lab):
    """``make_problem`` itself runs in the main process before any job: with
    ``runner.job_timeout`` it is first built in a process of its own (a hang or an ended
    process is one line, not a run that never starts or a silent exit); without one, a
    SystemExit or KeyboardInterrupt it raises is one line too."""
    source = MODULE.replace("    return Bad(case)", "    misbehave(case)\n    return Bad(case)")
    (lab / "lab" / "build.py").write_text(source.replace('name = "bad"', 'name = "build"'))
    cases = [("sleep", ["runner.job_timeout=1"], "ran longer than runner.job_timeout=1 s"),
             ("osexit", ["runner.job_timeout=30"], "exited with code 3"),
             ("sysexit", [], "its code raised SystemExit (3)"),
             ("interrupt", [], "its code raised KeyboardInterrupt")]
    runs = []
    for k, (case, extra, _) in enumerate(cases):
        cwd = lab / f"build-{k}"
        cwd.mkdir()
        runs.append((["problem=lab.build", *ARGS[1:], f"case={case}", *extra,
                      f"hydra.run.dir={cwd / 'run'}"], cwd))
    t0 = time.monotonic()
    procs = cli_forked(runs, timeout=120)
    assert time.monotonic() - t0 < 60
    for proc, (_, _, fragment) in zip(procs, cases):
        assert proc.returncode == 2, proc.stderr
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and "problem.module: building problem 'build'" in lines[0]
        assert fragment in lines[0], lines[0]
