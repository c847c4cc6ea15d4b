"""The crash-proof process pool: a dead worker fails only its job, which is retried;
workers never outlive the main process."""

import functools
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import psutil
import pytest

from penaltyrun.runner import plan_jobs
from penaltyrun.runner.pool import describe_exit, run_pool


def _jobs(n):
    return plan_jobs("zermelo", "default", "diagonal", "pso", n_starts=n, root_seed=1,
                     meta={"run_id": "t"})


def _fake_job(job, marker_dir: Path, kill_starts=(), always=False):
    """A job function: kills its own worker for the starts in ``kill_starts`` (the first
    attempt only, unless ``always``), otherwise returns an ok record."""
    marker = marker_dir / f"{job.start}.attempt"
    first = not marker.exists()
    marker.write_text(str(os.getpid()))
    if job.start in kill_starts and (first or always):
        os.kill(os.getpid(), signal.SIGKILL)
    time.sleep(0.05)
    return {"job_id": job.job_id, "status": "ok", "pid": os.getpid()}


def test_dead_worker_fails_only_its_job_which_is_retried(tmp_path):
    func = functools.partial(_fake_job, marker_dir=tmp_path, kill_starts=(1,))
    out = list(run_pool(_jobs(6), workers=2, max_retries=1, func=func))
    ids = [job.job_id for job, _ in out]
    assert sorted(ids) == sorted(j.job_id for j in _jobs(6))  # every job exactly once
    assert all(rec["status"] == "ok" for _, rec in out)


def test_job_killing_its_worker_every_time_is_recorded_failed(tmp_path, caplog):
    func = functools.partial(_fake_job, marker_dir=tmp_path, kill_starts=(2,), always=True)
    out = dict((job.start, rec) for job, rec in run_pool(_jobs(4), 2, max_retries=1, func=func))
    assert sorted(out) == [0, 1, 2, 3]
    assert [out[i]["status"] for i in range(4)] == ["ok", "ok", "failed", "ok"]
    assert "SIGKILL" in out[2]["error"] and "2 attempts" in out[2]["error"]
    assert out[2]["run_id"] == "t"  # run metadata kept in the failure record
    assert "running it again" in caplog.text


def test_no_retry_with_max_retries_zero(tmp_path):
    func = functools.partial(_fake_job, marker_dir=tmp_path, kill_starts=(0,))
    out = dict((job.start, rec) for job, rec in run_pool(_jobs(2), 2, max_retries=0, func=func))
    assert out[0]["status"] == "failed" and out[1]["status"] == "ok"


def test_describe_exit():
    assert "SIGKILL" in describe_exit(-9) and "out of memory" in describe_exit(-9)
    assert "SIGSEGV" in describe_exit(-11)
    assert "code 3" in describe_exit(3)


SCRIPT = textwrap.dedent("""
    import os, sys, time
    from penaltyrun.runner import plan_jobs
    from penaltyrun.runner.pool import run_pool

    def sleeper(job):
        os.write(1, f"{os.getpid()}\\n".encode())  # one write: atomic on a pipe
        time.sleep(120)
        return {}

    jobs = plan_jobs("zermelo", "default", "diagonal", "pso", n_starts=2, root_seed=1)
    for _ in run_pool(jobs, 2, func=sleeper):
        pass
""")


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_workers_exit_when_the_main_process_dies(tmp_path, sig):
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT], stdout=subprocess.PIPE,
                            text=True, start_new_session=True)
    try:
        pids = [int(proc.stdout.readline()) for _ in range(2)]
        assert all(psutil.pid_exists(p) for p in pids)
        os.kill(proc.pid, sig)
        proc.wait(timeout=10)
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and any(_alive(p) for p in pids):
            time.sleep(0.1)
        assert not any(_alive(p) for p in pids)
    finally:
        os.killpg(proc.pid, signal.SIGKILL) if _alive(proc.pid) else None


def _alive(pid):
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def test_an_optimizers_heavy_imports_happen_once_before_the_fork():
    """``import pyswarms`` is done in the parent (forked workers share it), only when a job
    runs the pyswarms PSO (its registry entry's ``shared_imports``); a module that cannot be
    imported is left to the job."""
    import subprocess
    import sys
    import textwrap

    script = textwrap.dedent("""
        import sys
        from types import SimpleNamespace as J
        from penaltyrun.runner import pool
        assert pool.import_shared([J(optimizer="cmaes")]) == []
        assert "pyswarms" not in sys.modules
        assert pool.import_shared([J(optimizer="pso"), J(optimizer="cmaes")]) == [
            "penaltyrun.optim.pso:load_pyswarms"]
        assert "pyswarms" in sys.modules
        assert pool.import_shared([J(optimizer="lbfgs")]) == ["scipy.optimize"]
        import dataclasses
        from penaltyrun import optim
        optim.OPTIMIZERS["pso"] = dataclasses.replace(
            optim.OPTIMIZERS["pso"], shared_imports=("penaltyrun_no_such_module",))
        assert pool.import_shared([J(optimizer="pso")]) == []
        print("ok")
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=120)
    assert proc.stdout.strip() == "ok", proc.stderr
