"""Issue 12, one subprocess test per row of its table: worker deaths, bad files, signals,
bad options and dask clusters each end the way the README's "Errors and exit codes" says."""

import os
import signal
import time

import pandas as pd
import psutil
import pytest
from cli_subprocess import (
    FAST_JOBS,
    SLOW_JOBS,
    alive,
    cli,
    one_error_line,
    popen,
    records,
    report,
    wait_for_records,
)

from penaltyrun.io import RESULTS_FILE


@pytest.mark.slow  # whole runs in subprocesses (~15 s); tests/runner/test_pool*.py stay
def test_killed_pool_worker_fails_only_its_job_which_is_retried(tmp_path):
    """Row 1: SIGKILL one local pool worker mid-run (after the first record, both workers
    still have a job: four jobs on two workers)."""
    run = tmp_path / "run"
    proc = popen(*SLOW_JOBS, "runner.n_starts=4", "runner.workers=2", f"hydra.run.dir={run}",
                 cwd=tmp_path)
    wait_for_records(run)
    victim = psutil.Process(proc.pid).children()[0]
    victim.kill()
    out, err = proc.communicate(timeout=600)
    assert proc.returncode == 0, err
    assert "SIGKILL" in out + err and "running it again" in out + err
    recs = records(run)
    assert len(recs) == 4 and {r["status"] for r in recs} == {"ok"}
    assert err.strip().splitlines()[-1] == "penaltyrun: 4 jobs: 4 ok, 0 diverged, 0 failed"
    assert len(pd.read_parquet(run / RESULTS_FILE)) == 4


#: A problem module whose evaluation divides by zero: every job fails.
BROKEN = """
from penaltyrun.problems.base import MatrixSpec

CASES = ("one",)
DEFAULT_CASE = "one"


class Broken:
    name = "broken"
    case = "one"
    matrices = (MatrixSpec("K", 2, (0.1, 10.0)),)
    scalars = ()

    def evaluate_batch(self, mats, scalars=None):
        return 1 / 0

    def evaluate(self, mats, scalars=None):
        return 1 / 0

    def simulate(self, mats, scalars=None):
        return {}


def make_problem(case, params):
    return Broken()
"""


def test_failed_job_gives_exit_code_3_and_a_summary_line(tmp_path):
    """Row 1 (exit code): a run with a failed job no longer exits 0."""
    run = tmp_path / "run"
    (tmp_path / "lab").mkdir()
    (tmp_path / "lab" / "__init__.py").write_text("", encoding="utf-8")
    (tmp_path / "lab" / "broken.py").write_text(BROKEN, encoding="utf-8")
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    proc = cli("problem=lab.broken", "optimizer=baseline", "runner.report=false",
               "runner.n_starts=2", "runner.forecast_samples=0", f"hydra.run.dir={run}",
               cwd=tmp_path, env=env)
    assert proc.returncode == 3, proc.stderr
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith("penaltyrun: 2 jobs: 0 ok, 0 diverged, 2 failed; errors in ")
    assert "ZeroDivisionError" in last and "retry_failed=true" in last


@pytest.mark.slow  # about 15 s: a run, a damaged record, a resume
def test_truncated_job_record_is_moved_aside_and_rerun(tmp_path):
    """Row 3: truncate a record, then resume (and the report on bad Parquet files, row 4)."""
    run = tmp_path / "run"
    args = [*FAST_JOBS, "runner.n_starts=3", f"hydra.run.dir={run}"]
    assert cli(*args, cwd=tmp_path).returncode == 0
    victim = sorted((run / "jobs").glob("*.json"))[1]
    victim.write_text(victim.read_text()[:25])
    proc = cli(*args, "runner.resume=true", "runner.retry_failed=true", cwd=tmp_path)
    out = proc.stderr + proc.stdout  # Hydra's log lines go to stdout
    assert proc.returncode == 0, out
    assert str(victim) in out and "corrupt" in out
    assert "Traceback" not in out
    assert "2 of 3 jobs already finished" in out
    assert len(list((run / "jobs" / "corrupt").iterdir())) == 1
    assert [r["status"] for r in records(run)] == ["ok"] * 3
    assert len(pd.read_parquet(run / RESULTS_FILE)) == 3

    # Row 4: one truncated and one garbage results.parquet beside a good one.
    folder = tmp_path / "all"
    for name in ("good", "truncated", "garbage"):
        (folder / name).mkdir(parents=True)
    good = run / RESULTS_FILE
    (folder / "good" / RESULTS_FILE).write_bytes(good.read_bytes())
    (folder / "truncated" / RESULTS_FILE).write_bytes(good.read_bytes()[:300])
    (folder / "garbage" / RESULTS_FILE).write_text("garbage")
    rep = report(str(folder), timeout=300)
    assert rep.returncode == 0, rep.stderr
    assert "Traceback" not in rep.stderr
    for name in ("truncated", "garbage"):
        assert str(folder / name / RESULTS_FILE) in rep.stderr
    assert (folder / "report" / "report.md").exists()
    assert not [p for p in (folder / "report").iterdir() if p.name.startswith(".")]
    for bad in ("truncated", "garbage"):
        rep = report(str(folder / bad / RESULTS_FILE), timeout=300)
        assert rep.returncode == 2
        assert "no readable results" in one_error_line(rep)


@pytest.mark.slow  # whole runs in subprocesses (~13 s); tests/runner/test_interrupts.py stays
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_and_sighup_stop_like_ctrl_c(tmp_path, sig):
    """Row 6: SIGTERM / SIGHUP of the main process."""
    run = tmp_path / "run"
    args = [*SLOW_JOBS, "runner.n_starts=3", "runner.workers=2", f"hydra.run.dir={run}"]
    proc = popen(*args, cwd=tmp_path)
    wait_for_records(run)
    workers = [p.pid for p in psutil.Process(proc.pid).children()]
    assert workers
    os.kill(proc.pid, sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + sig, err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert f"stopped by {signal.Signals(sig).name}" in last and "runner.resume=true" in last
    deadline = time.monotonic() + 5
    while any(alive(p) for p in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(alive(p) for p in workers)
    done = len(records(run))
    resumed = cli(*args, "runner.resume=true", cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    assert f"{done} of 3 jobs already finished" in resumed.stderr + resumed.stdout
    assert len(pd.read_parquet(run / RESULTS_FILE)) == 3


@pytest.mark.slow
def test_sigkill_of_main_process_leaves_no_worker(tmp_path):
    """Row 6: SIGKILL of the main process; the workers notice and exit."""
    run = tmp_path / "run"
    proc = popen(*SLOW_JOBS, "runner.n_starts=4", "runner.workers=2", f"hydra.run.dir={run}",
                 cwd=tmp_path)
    wait_for_records(run)
    workers = [p.pid for p in psutil.Process(proc.pid).children()]
    proc.kill()
    proc.communicate(timeout=30)
    deadline = time.monotonic() + 5
    while any(alive(p) for p in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(alive(p) for p in workers)


@pytest.mark.parametrize(("args", "fragments"), [
    (["optimizer.w=abc"], ["optimizer.w", "must be a number"]),
    (["optimizer.vh_strategy=bogus"], ["optimizer.vh_strategy", "unmodified, adjust"]),
    (["optimizer=de", "optimizer.mutation=[0.5,3]"], ["optimizer.mutation"]),
    (["runner.seed=abc"], ["runner.seed", "non-negative integer"]),
    (["runner.seed=-1"], ["runner.seed"]),
    (["runner.resume=maybe"], ["runner.resume", "true or false"]),
    (["runner.max_retries=-1"], ["runner.max_retries"]),
    (["runner.worker_timeout=0"], ["runner.worker_timeout"]),
    (["report.paper=3"], ["report.paper", "true or false"]),
    (["+foo=1"], ["foo", "unknown config key"]),
    (["+runner.fast=true"], ["runner.fast", "unknown config key", "max_retries"]),
    (["problem.params.x0=abc"], ["problem.params.x0", "list of 2 numbers"]),
    (["param.cayley_bound=abc"], ["param.cayley_bound"]),
    (["hydra.run.dir=/proc/penaltyrun/run"], ["hydra.run.dir", "cannot create"]),
    (["runner.backend=dask", "runner.scheduler=tcp://127.0.0.1:1"],
     ["runner.scheduler", "cannot reach", "127.0.0.1:1"]),
    (["runner.backend=dask", "runner.scheduler=notanaddress"],
     ["runner.scheduler", "tcp://host:port"]),
    (["runner.scheduler=tcp://127.0.0.1:8786"], ["runner.scheduler", "backend=dask"]),
    (["problem=qlaw", "case=Z"], ["case", "allowed: A, B"]),
    (["-m", "problem=qlaw", "case=A,Z"], ["case", "'Z'"]),
])
def test_bad_option_is_one_line_before_anything_runs(tmp_path, args, fragments):
    """Rows 2, 7, 8, 9, 10, 12: one line, exit 2, no run directory, no compilation."""
    run = tmp_path / "run"
    t0 = time.monotonic()
    dirs = [] if any(a.startswith("hydra.run.dir") for a in args) else \
        [f"hydra.run.dir={run}", f"hydra.sweep.dir={tmp_path / 'sweep'}"]
    proc = cli(*args, *dirs, cwd=tmp_path, timeout=120)
    assert proc.returncode == 2, proc.stderr
    line = one_error_line(proc)
    for fragment in fragments:
        assert fragment in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # no run dir, no outputs/
    assert time.monotonic() - t0 < 60  # seconds, not a numba compilation


def test_run_dir_under_a_file_is_one_line(tmp_path):
    """Row 9: hydra.run.dir under a file."""
    (tmp_path / "afile").write_text("")
    proc = cli("runner.n_starts=1", f"hydra.run.dir={tmp_path / 'afile' / 'run'}",
               cwd=tmp_path, timeout=120)
    assert proc.returncode == 2
    assert "is a file" in one_error_line(proc)


@pytest.mark.slow  # about 10 s: a local dask cluster starts and stops
def test_dask_local_cluster_logs_only_warnings(tmp_path):
    """Row 13 (and item 8): a LocalCluster run; dask's INFO lines are gone."""
    run = tmp_path / "run"
    proc = cli(*FAST_JOBS, "runner.n_starts=3", "runner.backend=dask", "runner.workers=2",
               f"hydra.run.dir={run}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    noise = [ln for ln in (proc.stderr + proc.stdout).splitlines()
             if "distributed" in ln and "INFO" in ln]
    assert noise == [], noise
    assert sorted(r["start"] for r in records(run)) == [0, 1, 2]
