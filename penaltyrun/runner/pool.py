"""A process pool that survives the death of a worker.

``concurrent.futures.ProcessPoolExecutor`` breaks as a whole when one worker dies (the
out-of-memory killer, a segfault in a compiled kernel, ``kill -9``): every job in flight and
every queued job then fails with ``BrokenProcessPool``. Here each worker runs one job at a
time over its own pipe, so the main process knows which job a dead worker was running:
only that job is affected, the worker is replaced, and the job is run again up to
``max_retries`` times before it is recorded ``failed`` with the cause.

Workers never outlive the main process: on Linux the kernel sends them SIGKILL when it
dies (``prctl(PR_SET_PDEATHSIG)``), and on every platform a watchdog thread in each worker
exits it within :data:`WATCHDOG_S` seconds of noticing a new parent process id.
"""

from __future__ import annotations

import ctypes
import faulthandler
import logging
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from multiprocessing.connection import Connection, wait
from typing import Any

from penaltyrun.runner.plan import Job

logger = logging.getLogger(__name__)

#: Seconds between two parent checks of a worker's watchdog thread.
WATCHDOG_S = 1.0
_PR_SET_PDEATHSIG = 1

JobFunc = Callable[[Job], dict[str, Any]]


def die_with_parent(parent_pid: int, interval_s: float = WATCHDOG_S) -> None:
    """Make the calling (worker) process end when process ``parent_pid`` ends.

    Linux: the kernel sends SIGKILL at the parent's death (``PR_SET_PDEATHSIG``). Everywhere:
    a daemon thread checks ``os.getppid()`` every ``interval_s`` seconds and exits the
    process when the parent has changed (the orphan was adopted by another process).
    """
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):  # no prctl: the watchdog thread still works
            pass

    def watch() -> None:
        while True:
            if os.getppid() != parent_pid:
                os._exit(1)
            time.sleep(interval_s)

    threading.Thread(target=watch, name="penaltyrun-parent-watchdog", daemon=True).start()


def own_fault_handler() -> None:
    """Point a fault handler inherited from the parent at this (worker) process's stderr.

    A forked worker inherits the parent's ``faulthandler`` target, a file descriptor the
    parent chose (pytest's is a saved copy of the terminal): a worker's crash dump would be
    written there, into the parent's output, instead of to the worker's own stderr.
    """
    if not faulthandler.is_enabled():
        return
    try:
        faulthandler.enable(file=sys.stderr)
    except (AttributeError, ValueError, OSError):  # a stderr without a file descriptor
        faulthandler.disable()


def _worker_main(conn: Connection, parent_pid: int, func: JobFunc) -> None:
    """Loop of one worker: receive a job, send back its record; ``None`` ends the loop."""
    own_fault_handler()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C: the main process stops us
    for signum in (signal.SIGTERM, signal.SIGHUP):  # not the main process's handlers
        signal.signal(signum, signal.SIG_DFL)
    die_with_parent(parent_pid)
    while True:
        try:
            job = conn.recv()
        except (EOFError, OSError):
            return
        if job is None:
            return
        conn.send(func(job))


def describe_exit(exitcode: int | None) -> str:
    """Readable cause of a worker's end from its exit code (negative: killed by a signal)."""
    if exitcode is None:
        return "worker process vanished"
    if exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = f"signal {-exitcode}"
        hint = " (killed: out of memory or kill -9?)" if -exitcode == signal.SIGKILL else \
            " (segmentation fault in a compiled kernel?)" if -exitcode == signal.SIGSEGV else ""
        return f"worker process died of {name}{hint}"
    return f"worker process exited with code {exitcode}"


def failure_record(job: Job, error: str) -> dict[str, Any]:
    """Record of a job that could not produce one itself (its worker died)."""
    return {"job_id": job.job_id, "problem": job.problem, "case": job.case,
            "param": job.param, "optimizer": job.optimizer, "start": job.start,
            "seed": job.seed, "status": "failed", "error": error, **job.meta}


class _Worker:
    """One worker process and the job it is running (``None`` when idle)."""

    def __init__(self, ctx: Any, func: JobFunc) -> None:
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker_main, args=(child, os.getpid(), func),
                                daemon=True, name="penaltyrun-worker")
        self.proc.start()
        child.close()
        self.job: Job | None = None

    def stop(self) -> None:
        if self.proc.is_alive():
            self.proc.terminate()
        self.proc.join(timeout=5)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join(timeout=5)
        self.conn.close()


def run_pool(jobs: list[Job], workers: int, max_retries: int = 1,
             func: JobFunc | None = None) -> Iterator[tuple[Job, dict[str, Any]]]:
    """Run ``jobs`` on ``workers`` processes; yield ``(job, record)`` as each finishes.

    Parameters
    ----------
    jobs : list of Job
    workers : int
        Worker processes, ≥ 1.
    max_retries : int
        Times a job whose worker died is run again before it is recorded ``failed``.
    func : callable, optional
        Job function (default :func:`penaltyrun.runner.job.run_job`); it must not raise.

    Yields
    ------
    (Job, dict)
        Each job exactly once with its record. Closing the generator (or an exception such
        as KeyboardInterrupt in the consumer) ends every worker at once; jobs in flight are
        not recorded.
    """
    if func is None:
        from penaltyrun.runner.job import run_job

        func = run_job
    ctx = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else mp.get_context()
    queue = deque(jobs)
    deaths: dict[str, int] = {}
    pool: list[_Worker] = []
    try:
        pool = [_Worker(ctx, func) for _ in range(min(workers, len(queue)))]
        while queue or any(w.job is not None for w in pool):
            for w in pool:
                if w.job is None and queue:
                    w.job = queue.popleft()
                    w.conn.send(w.job)
            busy = [w for w in pool if w.job is not None]
            ready = wait([w.conn for w in busy] + [w.proc.sentinel for w in busy])
            for i, w in enumerate(pool):
                if w.job is None:
                    continue
                if w.conn in ready:
                    try:
                        record = w.conn.recv()
                    except (EOFError, OSError):
                        record = None
                    if record is not None:
                        job, w.job = w.job, None
                        yield job, record
                        continue
                if w.proc.sentinel in ready or not w.proc.is_alive():
                    w.proc.join(timeout=5)
                    job, cause = w.job, describe_exit(w.proc.exitcode)
                    w.stop()
                    pool[i] = _Worker(ctx, func)
                    deaths[job.job_id] = deaths.get(job.job_id, 0) + 1
                    if deaths[job.job_id] <= max_retries:
                        logger.warning("job %s: %s; pool rebuilt, running it again "
                                       "(retry %d of %d)", job.job_id, cause,
                                       deaths[job.job_id], max_retries)
                        queue.appendleft(job)
                    else:
                        logger.error("job %s: %s on each of %d attempts; recorded failed",
                                     job.job_id, cause, deaths[job.job_id])
                        yield job, failure_record(
                            job, f"WorkerDied: {cause} on each of {deaths[job.job_id]} "
                                 f"attempts (runner.max_retries={max_retries})")
    finally:
        for w in pool:
            w.stop()
