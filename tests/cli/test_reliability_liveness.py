"""No hangs, no unbounded plans, the minor cases (subprocess tests): a stopped worker is
killed and its job retried, a lost dask scheduler is exit 4, huge n_starts is one line,
booleans are no matrix entries, profile sweeps are checked before anything runs."""

import json
import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import psutil
import pytest
from cli_subprocess import FAST_JOBS, SLOW_JOBS, cli, one_error_line, popen, wait_for_records

from penaltyrun.io import RESULTS_FILE


def _cpu_seconds(proc: psutil.Process) -> float:
    """User + system CPU seconds of ``proc``; NaN once it has exited (a short-lived child
    of the runner, e.g. the ``git`` that reads the commit, can end between two reads)."""
    try:
        return sum(proc.cpu_times()[:2])
    except psutil.NoSuchProcess:
        return float("nan")


@pytest.mark.slow  # about 10 s: waits out the stall timeout
def test_stopped_pool_worker_is_killed_and_its_job_retried(tmp_path):
    run = tmp_path / "run"
    proc = popen(*SLOW_JOBS, "runner.n_starts=6", "runner.workers=2",
                 "runner.stall_timeout=3", f"hydra.run.dir={run}", cwd=tmp_path)
    try:
        wait_for_records(run)
        workers = psutil.Process(proc.pid).children()
        used = {p.pid: _cpu_seconds(p) for p in workers}
        time.sleep(0.5)  # the worker that is running a job is the one using CPU
        spent = {p: _cpu_seconds(p) - used[p.pid] for p in workers}
        victim = max((p for p in workers if not math.isnan(spent[p])), key=spent.__getitem__)
        victim.suspend()  # SIGSTOP
        out, err = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 0, err
    assert "runner.stall_timeout" in out + err and "running it again" in out + err
    assert not psutil.pid_exists(victim.pid) or victim.status() == psutil.STATUS_ZOMBIE
    df = pd.read_parquet(run / RESULTS_FILE)
    assert len(df) == 6 and set(df["status"]) == {"ok"}


@pytest.mark.parametrize("args", [["mode=plan", "runner.n_starts=1000000000"],
                                  ["runner.n_starts=100001"]])
def test_huge_n_starts_is_one_line_in_seconds(tmp_path, args):
    t0 = time.monotonic()
    proc = cli(*FAST_JOBS, *args, f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path,
               timeout=120)
    assert proc.returncode == 2
    line = one_error_line(proc)
    assert "runner.n_starts" in line and "limit of 100000" in line
    assert time.monotonic() - t0 < 60
    assert not (tmp_path / "run").exists()


@pytest.mark.slow
def test_plan_at_the_limit_answers(tmp_path):
    proc = cli(*FAST_JOBS, "mode=plan", "runner.n_starts=100000", "runner.forecast_samples=0",
               cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "100000 jobs" in proc.stdout


def test_booleans_are_no_matrix_entries(tmp_path):
    proc = cli("mode=evaluate", "problem=zermelo", "matrices.K=[[true,false],[false,true]]",
               cwd=tmp_path, timeout=120)
    assert proc.returncode == 2
    assert "matrices.K: entries must be numbers, got True" in one_error_line(proc)


def test_graded_penalty_never_decreases_with_the_failure():
    from penaltyrun.dynamics import integrate
    from penaltyrun.problems import make
    from penaltyrun.problems.attitude.reference import graded_cost

    prob = make("zermelo", "default", {}, None)
    status = np.full(3, integrate.HORIZON)
    dist = np.array([1e3, 1e44, 1e308])
    cost = prob._graded(np.ones(3), np.zeros(3), dist, status, 62.6).cost
    assert np.all(np.diff(cost) >= 0) and np.all(np.isfinite(cost))
    blown = prob._graded(np.ones(1), np.zeros(1), np.array([10.0]),
                         np.array([integrate.NONFINITE]), 10.0).cost
    assert blown[0] >= cost[-1]
    att = graded_cost(np.zeros(3), dist, 1.0, status, 1.0)
    assert np.all(np.diff(att) >= 0) and np.all(np.isfinite(att))


@pytest.mark.slow
def test_gain_1e308_costs_no_less_than_gain_1e44(tmp_path):
    costs = []
    for k in ("1e44", "1e308"):
        proc = cli("mode=evaluate", "problem=zermelo", f"matrices.K=[[{k},0],[0,{k}]]",
                   cwd=tmp_path, timeout=300)
        assert proc.returncode == 0, proc.stderr
        costs.append(json.loads(proc.stdout.strip().splitlines()[-1])["cost"])
    assert costs[1] >= costs[0]


@pytest.mark.parametrize(("sweep", "fragment"), [
    ("optimizer.iters: 5,abc,10", "optimizer.iters: must be an integer, got 'abc'"),
    ("param: diagonal,bogus,full", "param: unknown choice 'bogus'"),
])
def test_profile_sweep_values_are_checked_before_anything_runs(tmp_path, sweep, fragment):
    conf = tmp_path / "conf" / "experiment"
    conf.mkdir(parents=True)
    (conf / "bad.yaml").write_text(f"# @package _global_\nhydra:\n  sweeper:\n    params:\n"
                                   f"      {sweep}\n")
    proc = cli("-m", "--config-dir", str(tmp_path / "conf"), "+experiment=bad",
               "problem=zermelo", f"hydra.sweep.dir={tmp_path / 'sweep'}", cwd=tmp_path,
               timeout=120)
    assert proc.returncode == 2, proc.stderr
    line = one_error_line(proc)
    assert fragment in line and "hydra.sweeper.params" in line
    assert not (tmp_path / "sweep").exists()


@pytest.mark.slow
@pytest.mark.parametrize("evaluate_on", ["local", "dask"])
def test_lost_scheduler_is_exit_4_and_finished_jobs_stay(tmp_path, evaluate_on, dask_cluster):
    run = tmp_path / "run"
    proc = popen(*SLOW_JOBS, "runner.n_starts=6", "runner.backend=dask",
                 f"runner.evaluate_on={evaluate_on}", f"runner.scheduler={dask_cluster.address}",
                 f"hydra.run.dir={run}", cwd=tmp_path)
    wait_for_records(run)
    os.killpg(dask_cluster.scheduler.pid, signal.SIGKILL)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 4, err
    assert "Traceback" not in out + err
    last = err.strip().splitlines()[-1]
    assert last.startswith("penaltyrun: error: lost the dask scheduler")
    assert "runner.resume=true" in last
    kept = [json.loads(p.read_text()) for p in (run / "jobs").glob("*.json")]
    assert kept and all(r["status"] == "ok" for r in kept), \
        [(r["status"], r.get("error")) for r in kept]


@pytest.mark.slow
def test_damaged_numba_cache_is_named_with_how_to_clear_it(tmp_path):
    cache = tmp_path / "numba-cache"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    args = [sys.executable, "-m", "penaltyrun.cli", "problem=zermelo", "optimizer=baseline",
            "runner.n_starts=1", "runner.report=false"]
    first = subprocess.run([*args, f"hydra.run.dir={tmp_path / 'a'}"], cwd=tmp_path, env=env,
                           capture_output=True, text=True, timeout=900)
    assert first.returncode == 0, first.stderr
    for index in cache.rglob("*.nbi"):
        index.write_bytes(b"garbage")
    proc = subprocess.run([*args, f"hydra.run.dir={tmp_path / 'b'}"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 3
    last = proc.stderr.strip().splitlines()[-1]
    assert f"numba's cache of compiled kernels under {cache} is damaged" in last
    assert f"find {cache} -name '*.nbi' -delete" in last
