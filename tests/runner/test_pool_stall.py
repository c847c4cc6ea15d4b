"""A worker that stops answering (SIGSTOP) is killed after runner.stall_timeout and its
job retried, then recorded failed with the cause."""

import functools
import os
import signal
import time
from pathlib import Path

from penaltyrun.runner import plan_jobs
from penaltyrun.runner.pool import cpu_ticks, run_pool


def _jobs(n):
    return plan_jobs("zermelo", "default", "diagonal", "pso", n_starts=n, root_seed=1,
                     meta={"run_id": "t"})


def _stopping_job(job, marker_dir: Path, stop_starts=(), always=False):
    marker = marker_dir / f"{job.start}.attempt"
    first = not marker.exists()
    marker.write_text(str(os.getpid()))
    if job.start in stop_starts and (first or always):
        os.kill(os.getpid(), signal.SIGSTOP)
    time.sleep(0.05)
    return {"job_id": job.job_id, "status": "ok"}


def test_stopped_worker_is_killed_and_its_job_retried(tmp_path):
    func = functools.partial(_stopping_job, marker_dir=tmp_path, stop_starts=(1,))
    t0 = time.monotonic()
    out = dict((job.start, rec) for job, rec in
               run_pool(_jobs(3), 2, max_retries=1, func=func, stall_timeout=1.0))
    assert sorted(out) == [0, 1, 2] and {r["status"] for r in out.values()} == {"ok"}
    assert time.monotonic() - t0 < 60


def test_always_stalling_job_is_recorded_failed_with_the_cause(tmp_path, caplog):
    func = functools.partial(_stopping_job, marker_dir=tmp_path, stop_starts=(0,), always=True)
    out = dict((job.start, rec) for job, rec in
               run_pool(_jobs(2), 2, max_retries=1, func=func, stall_timeout=1.0))
    assert out[1]["status"] == "ok" and out[0]["status"] == "failed"
    assert out[0]["error"].startswith("WorkerStalled:")
    assert "runner.stall_timeout" in out[0]["error"] and "2 attempts" in out[0]["error"]


def test_a_busy_worker_is_not_a_stalled_one(tmp_path):
    """A long job (here sleeping, beating from its thread) outlives many timeouts."""
    def slow(job):
        time.sleep(2.0)
        return {"job_id": job.job_id, "status": "ok"}

    out = list(run_pool(_jobs(2), 2, max_retries=0, func=slow, stall_timeout=0.5))
    assert [r["status"] for _, r in out] == ["ok", "ok"]


def test_cpu_ticks_of_a_stopped_process_is_none():
    assert isinstance(cpu_ticks(os.getpid()), int)
    assert cpu_ticks(2**22 + 12345) is None
