"""A job whose code misbehaves costs that job only: past ``job_timeout`` its worker is
killed and the job recorded ``timeout`` (also while the worker's heartbeat thread runs);
KeyboardInterrupt, SystemExit, ``os._exit`` and a segmentation fault are recorded ``failed``
with one line, at once (no retry), and the other jobs finish."""

import functools
import logging
import os
import signal
import sys
import time
from pathlib import Path

import pytest

from penaltyrun.runner import plan_jobs
from penaltyrun.runner.pool import ended_itself, run_pool
from penaltyrun.runner.validate import record_problem


def _jobs(n):
    return plan_jobs("zermelo", "default", "diagonal", "pso", n_starts=n, root_seed=1,
                     meta={"run_id": "t"})


def _misbehaving(job, how: str, marker_dir: Path):
    """Job function: start 0 misbehaves as ``how`` says (every attempt, counted in a file
    per attempt), the other starts return an ok record."""
    if job.start == 0:
        (marker_dir / f"attempt-{time.monotonic_ns()}").write_text(str(os.getpid()))
        if how == "sleep":
            time.sleep(3600)
        elif how == "spin":
            while True:
                pass
        elif how == "interrupt":
            raise KeyboardInterrupt
        elif how == "sysexit":
            sys.exit(3)
        elif how == "osexit":
            os._exit(3)
        elif how == "segv":
            os.kill(os.getpid(), signal.SIGSEGV)
        elif how in ("subprocess", "fork", "setsid"):  # a child outliving the job, a hang
            import subprocess

            child = os.fork() if how == "fork" else subprocess.Popen(
                ["sleep", "3600"], start_new_session=how == "setsid").pid
            if child == 0:
                time.sleep(3600)
                os._exit(0)
            (marker_dir / f"child-{child}").write_text("")
            time.sleep(3600)
        elif how == "daemon":  # double fork: the grandchild, in a session of its own,
            read, write = os.pipe()  # is orphaned when its parent exits
            if os.fork() == 0:
                os.setsid()
                if os.fork() == 0:
                    os.write(write, str(os.getpid()).encode().ljust(16))
                    time.sleep(3600)
                    os._exit(0)
                os._exit(0)
            grandchild = int(os.read(read, 16).decode())
            (marker_dir / f"child-{grandchild}").write_text("")
            time.sleep(3600)
    return {"job_id": job.job_id, "problem": job.problem, "case": job.case,
            "param": job.param, "optimizer": job.optimizer, "start": job.start,
            "seed": job.seed, "status": "ok", "best_cost": 1.0}


def _run(how, tmp_path, **kw):
    func = functools.partial(_misbehaving, how=how, marker_dir=tmp_path)
    t0 = time.monotonic()
    out = {job.start: rec for job, rec in run_pool(_jobs(3), 2, func=func, **kw)}
    return out, time.monotonic() - t0, len(list(tmp_path.glob("attempt-*")))


@pytest.mark.parametrize("how", ["sleep", "spin"])
def test_a_job_past_job_timeout_is_killed_and_recorded_timeout(tmp_path, how, caplog):
    with caplog.at_level(logging.ERROR, logger="penaltyrun.runner.pool"):
        out, elapsed, attempts = _run(how, tmp_path, job_timeout=1.0, stall_timeout=600,
                                      max_retries=1)
    assert [out[i]["status"] for i in range(3)] == ["timeout", "ok", "ok"]
    assert out[0]["error"].startswith("JobTimeout: ") and "runner.job_timeout=1 s" in \
        out[0]["error"]
    assert out[0]["wall_time_s"] >= 1.0 and out[0]["run_id"] == "t"
    assert record_problem(out[0], out[0]["job_id"]) is None  # a valid record
    assert attempts == 1  # not run again
    assert elapsed < 30  # nothing hangs (the limit is 1 s; slack for a loaded machine)
    lines = [r for r in caplog.records if out[0]["job_id"] in r.getMessage()]
    assert len(lines) == 1 and "recorded timeout" in lines[0].getMessage()


def test_a_sleeping_job_is_no_stalled_worker_only_job_timeout_stops_it(tmp_path):
    """The heartbeat thread of a sleeping job keeps answering: for five stall timeouts the
    worker is not killed as stalled (which would retry the job); job_timeout stops it."""
    out, _, attempts = _run("sleep", tmp_path, job_timeout=2.5, stall_timeout=0.5,
                            max_retries=1)
    assert out[0]["status"] == "timeout" and attempts == 1


@pytest.mark.parametrize("how, text", [
    ("interrupt", "KeyboardInterrupt: raised by the job's code"),
    ("sysexit", "SystemExit: the job's code called sys.exit(3)"),
    ("osexit", "worker process exited with code 3"),
    ("segv", "worker process died of SIGSEGV"),
])
def test_a_job_ending_its_code_or_its_worker_is_failed_at_once(tmp_path, how, text, caplog,
                                                               capfd):
    with caplog.at_level(logging.ERROR):
        out, elapsed, attempts = _run(how, tmp_path, max_retries=2)
    assert [out[i]["status"] for i in range(3)] == ["failed", "ok", "ok"]
    assert text in out[0]["error"] and "\n" not in out[0]["error"]
    assert record_problem(out[0], out[0]["job_id"]) is None
    assert attempts == 1  # it would end the same way again: no retry
    # one line: the worker logs an exception of the job's code (in its own process, out of
    # caplog's sight; the command-line tests count it), the main process a worker's end
    lines = [r.getMessage() for r in caplog.records if out[0]["job_id"] in r.getMessage()]
    assert len(lines) == (1 if how in ("osexit", "segv") else 0), lines
    assert "Traceback" not in capfd.readouterr().err or how == "segv"  # faulthandler's dump


def test_which_worker_ends_are_its_own():
    assert ended_itself(0) and ended_itself(3) and ended_itself(-signal.SIGSEGV)
    assert ended_itself(-signal.SIGABRT)
    assert not ended_itself(-signal.SIGKILL) and not ended_itself(-signal.SIGTERM)
    assert not ended_itself(None)


@pytest.mark.parametrize("how", ["subprocess", "fork", "setsid", "daemon"])
def test_what_a_timed_out_job_started_ends_with_its_worker(tmp_path, how):
    """F7: a job that starts a subprocess (or forks) and then hangs: recorded timeout, and
    its child does not outlive the run (the worker's process group is killed), nor does a
    child in a session of its own or a daemon's orphaned grandchild (Linux: the worker is
    their subreaper and stops and kills every process below it)."""
    out, _, _ = _run(how, tmp_path, job_timeout=1.0, stall_timeout=600, max_retries=1)
    assert out[0]["status"] == "timeout"
    pids = [int(p.name.split("-")[1]) for p in tmp_path.glob("child-*")]
    assert len(pids) == 1
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and Path(f"/proc/{pids[0]}").exists() and \
            Path(f"/proc/{pids[0]}/stat").read_text().split(")")[-1].split()[0] != "Z":
        time.sleep(0.1)
    alive = Path(f"/proc/{pids[0]}").exists() and \
        Path(f"/proc/{pids[0]}/stat").read_text().split(")")[-1].split()[0] != "Z"
    if alive:
        os.kill(pids[0], signal.SIGKILL)
    assert not alive
