"""A process pool that survives the death of a worker.

``concurrent.futures.ProcessPoolExecutor`` breaks as a whole when one worker dies (the
out-of-memory killer, a segfault in a compiled kernel, ``kill -9``): every job in flight and
every queued job then fails with ``BrokenProcessPool``. Here each worker runs one job at a
time over its own pipe, so the main process knows which job a dead worker was running:
only that job is affected, the worker is replaced, and the job is run again up to
``max_retries`` times before it is recorded ``failed`` with the cause. A job is run again
only when its worker was killed from outside (SIGKILL of the out-of-memory killer or of a
user, SIGTERM): a worker that ended itself (``os._exit``, ``exit()`` in a C library, a
segmentation fault or another crash signal of its own code) would end the same way again,
jobs being deterministic, so its job is recorded ``failed`` at once. ``KeyboardInterrupt``
and ``SystemExit`` raised by a job's code end that job only (see
:mod:`penaltyrun.runner.interrupts`).

A job running longer than ``job_timeout`` seconds (``runner.job_timeout``, wall clock) has
its worker killed and replaced, and is recorded ``timeout`` (not retried: it would most
likely run as long again); this holds for a job that sleeps or loops forever while its
worker's heartbeat thread keeps answering.

A worker that stops answering (``kill -STOP``, a deadlock) is found too: each worker sends a
heartbeat over its pipe every few seconds from a thread of its own, and the main process
reads its CPU time (``/proc``, Linux). A worker with neither a heartbeat nor CPU progress
for ``stall_timeout`` seconds is killed and its job retried like a dead worker's (a long
compiled kernel holds Python's GIL and so delays heartbeats, but its CPU time advances).

Workers never outlive the main process: on Linux the kernel sends them SIGKILL when it
dies (``prctl(PR_SET_PDEATHSIG)``), and on every platform a watchdog thread in each worker
exits it within :data:`WATCHDOG_S` seconds of noticing a new parent process id.

A forked worker starts as a copy of the main process, signal handlers included. The
signals of :data:`FORK_BLOCKED` are therefore blocked around the fork and unblocked in the
worker once it has its own handlers: a SIGTERM sent to a worker that has just been forked
(the pool replaces and stops workers at any moment) ends it instead of running the main
process's handler in it.
"""

from __future__ import annotations

import contextlib
import ctypes
import faulthandler
import importlib
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

from penaltyrun.jobrecord import FAILED, TIMEOUT
from penaltyrun.runner import interrupts, proctree
from penaltyrun.runner.job import identity_columns
from penaltyrun.runner.plan import Job

logger = logging.getLogger(__name__)

#: Seconds between two parent checks of a worker's watchdog thread.
WATCHDOG_S = 1.0
#: Longest interval between two heartbeats of a worker (s); shorter for small timeouts.
BEAT_S = 5.0
#: Default of ``runner.stall_timeout`` (s).
STALL_TIMEOUT_S = 600.0
_PR_SET_PDEATHSIG = 1
#: Signals blocked while a worker is forked: until the worker has its own handlers, the
#: parent's (e.g. the command line's SIGTERM → KeyboardInterrupt) would run in the child
#: and could raise in the child before multiprocessing's guard that ends it, so that the
#: child went on running the parent's code (a second runner, a second pytest).
FORK_BLOCKED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
#: Signals a process raises on itself when its own code crashes: a job whose worker died of
#: one of them is not run again (it would crash again).
CRASH_SIGNALS = tuple(getattr(signal, name) for name in
                      ("SIGSEGV", "SIGBUS", "SIGFPE", "SIGILL", "SIGABRT", "SIGSYS", "SIGTRAP")
                      if hasattr(signal, name))

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


def _start_heartbeat(conn: Connection, lock: threading.Lock, interval_s: float) -> None:
    """Daemon thread of a worker sending ``("beat", None)`` every ``interval_s`` seconds."""
    def beat() -> None:
        while True:
            time.sleep(interval_s)
            try:
                with lock:
                    conn.send(("beat", None))
            except (OSError, ValueError):  # pipe closed: the worker is ending
                return

    threading.Thread(target=beat, name="penaltyrun-heartbeat", daemon=True).start()


def _worker_main(conn: Connection, parent_pid: int, func: JobFunc,
                 beat_s: float = BEAT_S) -> None:
    """Loop of one worker: receive a job, send back ``("record", record)``; ``None`` ends
    the loop. A thread sends heartbeats meanwhile."""
    own_fault_handler()
    try:  # its own process group: what a job's code starts ends with the worker (stop)
        os.setpgid(0, 0)
    except OSError:
        pass
    proctree.become_subreaper()  # and what leaves the group is still found below it
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C: the main process stops us
    interrupts.mark_worker()  # so a KeyboardInterrupt here comes from a job's code
    for signum in (signal.SIGTERM, signal.SIGHUP):  # not the main process's handlers
        signal.signal(signum, signal.SIG_DFL)
    if hasattr(signal, "pthread_sigmask"):  # blocked by the parent around the fork
        signal.pthread_sigmask(signal.SIG_UNBLOCK, FORK_BLOCKED)
    die_with_parent(parent_pid)
    lock = threading.Lock()
    _start_heartbeat(conn, lock, beat_s)
    while True:
        try:
            job = conn.recv()
        except (EOFError, OSError):
            return
        if job is None:
            return
        try:
            record = func(job)
        except BaseException as exc:  # a job's code must not end the worker
            text = (interrupts.describe_exit_exception(exc)
                    if isinstance(exc, (KeyboardInterrupt, SystemExit))
                    else f"{type(exc).__name__}: {exc}")
            logger.error("job %s failed: %s", job.job_id, text)
            record = failure_record(job, text)
        with lock:
            conn.send(("record", record))


def cpu_ticks(pid: int) -> int | None:
    """User + system CPU time of process ``pid`` in clock ticks (Linux ``/proc``), or
    ``None`` where it cannot be read; a stopped process (state ``T``) gives ``None`` too,
    so that it counts as making no progress."""
    fields = proctree.stat_fields(pid)
    if fields is None or fields[0] in ("T", "t"):
        return None
    return int(fields[11]) + int(fields[12])


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
    return (f"worker process exited with code {exitcode} (os._exit or exit() in the job's "
            "code?)")


def ended_itself(exitcode: int | None) -> bool:
    """Whether a worker's exit code says its own code ended it: an exit status (``os._exit``,
    ``exit()``) or a crash signal (:data:`CRASH_SIGNALS`), not a kill from outside."""
    return exitcode is not None and (exitcode >= 0 or -exitcode in CRASH_SIGNALS)


def failure_record(job: Job, error: str, status: str = FAILED) -> dict[str, Any]:
    """Record of a job that could not produce one itself (its worker died, or was killed
    at ``runner.job_timeout``: ``status="timeout"``)."""
    return {**identity_columns(job), "status": status, "error": error}


@contextlib.contextmanager
def signals_blocked(signums: tuple[int, ...]) -> Iterator[None]:
    """Block ``signums`` in the calling thread for the block's duration (no-op where the
    platform has no ``pthread_sigmask``); signals that arrive meanwhile are delivered when
    the old mask is restored. A child forked inside the block starts with them blocked."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, signums)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


class _Worker:
    """One worker process, the job it is running (``None`` when idle) and when it was last
    seen alive (a heartbeat, a record or CPU progress)."""

    def __init__(self, ctx: Any, func: JobFunc, beat_s: float = BEAT_S) -> None:
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker_main, args=(child, os.getpid(), func, beat_s),
                                daemon=True, name="penaltyrun-worker")
        with signals_blocked(FORK_BLOCKED):
            self.proc.start()
        child.close()
        self.job: Job | None = None
        self.seen = self.started = time.monotonic()
        self.ticks = cpu_ticks(self.proc.pid)

    def assign(self, job: Job) -> None:
        """Send ``job`` to the worker."""
        self.job = job
        self.seen = self.started = time.monotonic()
        self.conn.send(job)

    def silent_for(self) -> float:
        """Seconds since the worker was last seen alive (CPU progress counts)."""
        ticks = cpu_ticks(self.proc.pid)
        if ticks is not None and ticks != self.ticks:
            self.ticks = ticks
            self.seen = time.monotonic()
        return time.monotonic() - self.seen

    def stop(self, kill: bool = False) -> None:
        """End the worker: SIGTERM (SIGKILL with ``kill``, e.g. a stopped process), then
        SIGKILL if it is still there after 5 s; then every process left in its process
        group (what a job's code started: a subprocess, a fork) is killed too, and on
        Linux every process below it, also one in a session of its own or orphaned
        (:mod:`penaltyrun.runner.proctree`), stopped first so that none forks meanwhile."""
        below = proctree.freeze_descendants(self.proc.pid)
        if self.proc.is_alive():
            self.proc.kill() if kill else self.proc.terminate()
        self.proc.join(timeout=5)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join(timeout=5)
        _kill_group(self.proc.pid)
        proctree.kill(below)
        self.conn.close()


def _kill_group(pid: int | None) -> None:
    """SIGKILL the process group ``pid`` leads (a worker's, :func:`_worker_main`), if it
    still has members; never another group (a worker that had not yet made its own)."""
    if not pid or pid == os.getpgid(0):
        return
    try:
        os.killpg(pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


def import_shared(jobs: list[Job]) -> list[str]:
    """Import the modules the optimizers of ``jobs`` import when they first run
    (``shared_imports`` of :data:`penaltyrun.optim.OPTIMIZERS`; ``pyswarms``: 0.3 s CPU) in
    this process, before the workers are forked, so that every forked worker shares them
    instead of importing them again. ``module:function`` names the optimizer's own loader
    (pyswarms must be imported through it: its import-time logging set-up would write
    ``report.log``).

    Returns
    -------
    list of str
        The modules imported now or before; one that cannot be imported is left to the
        job, which then records the error as before.
    """
    from penaltyrun.optim import OPTIMIZERS

    done = []
    for name in sorted({job.optimizer for job in jobs}):
        entry = OPTIMIZERS.get(name)
        for module in entry.shared_imports if entry is not None else ():
            name, _, loader = module.partition(":")
            try:
                loaded = importlib.import_module(name)
                if loader:
                    getattr(loaded, loader)()
            except ImportError as exc:
                logger.debug("not imported before the fork: %s (%s)", module, exc)
                continue
            done.append(module)
    return done


def run_pool(jobs: list[Job], workers: int, max_retries: int = 1,
             func: JobFunc | None = None, stall_timeout: float = STALL_TIMEOUT_S,
             job_timeout: float | None = None) -> Iterator[tuple[Job, dict[str, Any]]]:
    """Run ``jobs`` on ``workers`` processes; yield ``(job, record)`` as each finishes.

    Parameters
    ----------
    jobs : list of Job
    workers : int
        Worker processes, ≥ 1.
    max_retries : int
        Times a job whose worker was killed from outside or stalled is run again before it
        is recorded ``failed`` (a worker that ended itself: no retry).
    func : callable, optional
        Job function (default :func:`penaltyrun.runner.job.run_job`); it must not raise.
    stall_timeout : float
        Seconds without a heartbeat or CPU progress after which a worker is killed (s).
    job_timeout : float, optional
        Wall-clock seconds a job may run before its worker is killed and the job recorded
        ``timeout`` (s); ``None``: no limit.

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
    import_shared(jobs)
    ctx = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else mp.get_context()
    beat_s = max(0.05, min(BEAT_S, stall_timeout / 4))
    queue = deque(jobs)
    attempts: dict[str, int] = {}
    pool: list[_Worker] = []

    def lost(i: int, cause: str, kill: bool = False, retry: bool = True
             ) -> Iterator[tuple[Job, dict[str, Any]]]:
        """Replace worker ``i`` whose job ended without a record; retry or record it."""
        w = pool[i]
        job = w.job
        w.stop(kill)
        pool[i] = _Worker(ctx, func, beat_s)
        attempts[job.job_id] = attempts.get(job.job_id, 0) + 1
        if not retry:
            logger.error("job %s: %s; recorded failed (not run again: it would end the same "
                         "way)", job.job_id, cause)
            yield job, failure_record(job, f"WorkerDied: {cause} while running the job; not "
                                           "run again (it would end the same way)")
            return
        if attempts[job.job_id] <= max_retries:
            logger.warning("job %s: %s; pool rebuilt, running it again (retry %d of %d)",
                           job.job_id, cause, attempts[job.job_id], max_retries)
            queue.appendleft(job)
            return
        logger.error("job %s: %s on each of %d attempts; recorded failed", job.job_id,
                     cause, attempts[job.job_id])
        kind = "WorkerStalled" if "no heartbeat" in cause else "WorkerDied"
        yield job, failure_record(job, f"{kind}: {cause} on each of {attempts[job.job_id]} "
                                       f"attempts (runner.max_retries={max_retries})")

    def timed_out(i: int) -> Iterator[tuple[Job, dict[str, Any]]]:
        """Kill worker ``i`` whose job ran past ``job_timeout``; record the job ``timeout``."""
        w = pool[i]
        job, elapsed = w.job, time.monotonic() - w.started
        cause = (f"JobTimeout: the job ran longer than runner.job_timeout={job_timeout:g} s; "
                 f"its worker process (pid {w.proc.pid}) was killed")
        logger.error("job %s: %s; recorded timeout", job.job_id, cause[len("JobTimeout: "):])
        w.stop(kill=True)
        pool[i] = _Worker(ctx, func, beat_s)
        yield job, {**failure_record(job, cause, status=TIMEOUT), "wall_time_s": elapsed}

    def wait_s(busy: list[_Worker]) -> float:
        """Seconds to wait for messages: a heartbeat interval, less up to the next
        deadline of ``job_timeout``."""
        if job_timeout is None or not busy:
            return beat_s
        left = min(w.started + job_timeout for w in busy) - time.monotonic()
        return min(beat_s, max(0.01, left))

    try:
        pool = [_Worker(ctx, func, beat_s) for _ in range(min(workers, len(queue)))]
        while queue or any(w.job is not None for w in pool):
            for w in pool:
                if w.job is None and queue:
                    w.assign(queue.popleft())
            busy = [w for w in pool if w.job is not None]
            ready = wait([w.conn for w in busy] + [w.proc.sentinel for w in busy],
                         timeout=wait_s(busy))
            for i, w in enumerate(pool):
                if w.job is None:
                    _receive(w)  # an idle worker's heartbeats must not fill its pipe
                    continue
                if w.conn in ready:
                    record = _receive(w)
                    if record is not None:
                        job, w.job = w.job, None
                        yield job, record
                        continue
                if w.proc.sentinel in ready or not w.proc.is_alive():
                    w.proc.join(timeout=5)
                    yield from lost(i, describe_exit(w.proc.exitcode),
                                    retry=not ended_itself(w.proc.exitcode))
                elif job_timeout is not None and time.monotonic() - w.started > job_timeout:
                    yield from timed_out(i)
                elif w.silent_for() > stall_timeout:
                    yield from lost(i, f"worker process (pid {w.proc.pid}) gave no heartbeat "
                                       f"and used no CPU for {stall_timeout:g} s "
                                       "(runner.stall_timeout); killed", kill=True)
    finally:
        for w in pool:
            w.stop()


def _receive(w: _Worker) -> dict[str, Any] | None:
    """Read the worker's messages: heartbeats mark it alive; returns its record if one came
    (``None``: only heartbeats, or the pipe broke)."""
    record = None
    try:
        while w.conn.poll():
            kind, payload = w.conn.recv()
            w.seen = time.monotonic()
            if kind == "record":
                record = payload
                break
    except (EOFError, OSError):
        return None
    return record
