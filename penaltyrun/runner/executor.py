"""Execute planned jobs on a local process pool or a dask.distributed cluster.

Every finished job is written at once to ``<run_dir>/jobs/<job_id>.json`` (atomically:
temporary file + rename), so a killed run loses at most the jobs in flight, and
``resume=True`` skips the jobs whose record exists (see :mod:`penaltyrun.runner.records`).
A worker that dies or stalls fails only the job it was running, which is run again up to
``max_retries`` times, and a job running past ``job_timeout`` is killed and recorded
``timeout`` (see :mod:`penaltyrun.runner.pool`). With ``job_timeout`` even one worker is a
process of its own (a job running in this process could not be stopped). Before the first
job the run directory is locked for this process (:mod:`penaltyrun.runner.lock`): a second
run into it is refused.
"""

from __future__ import annotations

import logging
import signal
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from functools import partial
from pathlib import Path
from typing import Any

from penaltyrun.errors import ConfigError, RunInterruptedError
from penaltyrun.runner import interrupts, lock
from penaltyrun.runner.dask_backend import import_distributed, run_dask
from penaltyrun.runner.eta import DispatchEta
from penaltyrun.runner.job import run_job
from penaltyrun.runner.objects import object_paths, pickled, run_job_shipped
from penaltyrun.runner.options import (
    BACKENDS,
    RUNNER_OPTIONS,
    check_job_timeout,
    check_value,
    resolve_workers,
)
from penaltyrun.runner.plan import Job, order_longest_first
from penaltyrun.runner.pool import STALL_TIMEOUT_S, run_pool
from penaltyrun.runner.records import JOBS_DIR, pending_jobs, remove_leftovers, write_record

logger = logging.getLogger(__name__)


def _serial(jobs: list[Job]) -> Iterator[tuple[Job, dict[str, Any]]]:
    for job in jobs:
        yield job, run_job(job)


def _swarm_stream(todo: list[Job], workers: int, scheduler: str | None, max_retries: int,
                  worker_timeout: float, chunks: int | str, stall_timeout: float
                  ) -> Iterator[tuple[Job, dict[str, Any]]]:
    """:func:`~penaltyrun.runner.dask_swarm.run_swarm` (imported here: it needs dask)."""
    import_distributed()
    from penaltyrun.runner.dask_swarm import run_swarm

    return run_swarm(todo, workers, scheduler, max_retries, worker_timeout, chunks,
                     stall_timeout)


def dispatch_slots(workers: int, n_todo: int, backend: str = "local",
                   scheduler: str | None = None, evaluate_on: str = "local") -> int | None:
    """Jobs that run at once: ``workers`` (1 in turn), ``None`` when unknown here (a remote
    dask scheduler, or candidates evaluated across the cluster)."""
    if evaluate_on == "dask" or (backend == "dask" and scheduler):
        return None
    return 1 if workers == 1 or n_todo <= 1 else int(workers)


def check_settings(workers: Any, backend: Any, evaluate_on: Any = "local",
                   chunks: Any = "auto", job_timeout: Any = None) -> None:
    """Validate ``runner.workers`` (an integer ≥ 1 or ``auto``), ``runner.backend``,
    ``runner.evaluate_on``, ``runner.chunks`` and ``runner.job_timeout``.

    Raises
    ------
    ConfigError
        Naming the key (and the allowed backends).
    """
    resolve_workers(workers)
    if backend not in BACKENDS:
        raise ConfigError("runner.backend", f"unknown backend {backend!r}", allowed=BACKENDS)
    for key, value in (("evaluate_on", evaluate_on), ("chunks", chunks)):
        check_value(key, RUNNER_OPTIONS[key][0], value, RUNNER_OPTIONS[key][1])
    if evaluate_on == "dask" and backend != "dask":
        raise ConfigError("runner.evaluate_on", "dask needs runner.backend=dask")
    check_job_timeout(job_timeout, backend)


def execute(jobs: Iterable[Job], run_dir: Path, workers: int | str = 1,
            backend: str = "local", scheduler: str | None = None, resume: bool = False,
            retry_failed: bool = False, on_record: Callable[[dict[str, Any]], None] | None = None,
            max_retries: int = 1, worker_timeout: float = 60.0,
            expected_s: Mapping[str, float] | None = None, evaluate_on: str = "local",
            chunks: int | str = "auto", stall_timeout: float = STALL_TIMEOUT_S,
            job_timeout: float | None = None) -> list[Path]:
    """Run ``jobs`` and write one record file per finished job.

    Parameters
    ----------
    jobs : iterable of Job
    run_dir : Path
        Run directory; records go to ``run_dir/jobs``.
    workers : int or "auto"
        Parallel jobs (processes), ≥ 1 (1: in this process); ``auto``: one per core.
    backend : {"local", "dask"}
    scheduler : str, optional
        dask scheduler address (``None``: a LocalCluster of ``workers`` processes).
    resume, retry_failed : bool
        Skip finished jobs (and re-run failed ones with ``retry_failed``).
    on_record : callable, optional
        Called with each record as it is written (progress reporting).
    max_retries : int
        Times a job whose worker process died is run again before it is recorded failed.
    worker_timeout : float
        dask: seconds without any worker before the run stops (s).
    expected_s : mapping, optional
        ``job_id`` → expected CPU time (s): jobs are dispatched longest first (see
        :func:`~penaltyrun.runner.plan.order_longest_first`); without it, in the given order.
    evaluate_on : {"local", "dask"}
        dask (with ``backend="dask"``): each batch of candidates is evaluated as chunks on
        the dask workers, several starts at once (see :mod:`penaltyrun.runner.dask_swarm`).
    chunks : int or "auto"
        Chunks per batch with ``evaluate_on="dask"``.
    stall_timeout : float
        Seconds a worker may go without a heartbeat (local pool) or without answering the
        scheduler (dask LocalCluster) before it is killed and its job retried (s).
    job_timeout : float, optional
        Wall-clock seconds a job may run before its worker process is killed and the job
        recorded ``timeout`` (s; local backend); ``None``: no limit.

    Returns
    -------
    list of Path
        Record files written in this call.

    Raises
    ------
    RunInterruptedError
        On Ctrl-C (SIGINT), SIGTERM or SIGHUP: queued jobs are cancelled, workers stopped,
        and every record written so far stays on disk for ``resume``.
    RunAbortedError
        dask: the scheduler is unreachable or lost, or the cluster lost its last worker.
    ConfigError
        Another process runs in ``run_dir`` (see :mod:`penaltyrun.runner.lock`).
    EnvironmentProblemError
        A record could not be written (e.g. a full disk); records written before stay.
    """
    check_settings(workers, backend, evaluate_on, chunks, job_timeout)
    workers = resolve_workers(workers)
    lock.acquire(run_dir)  # held until the results are collected (or the process ends)
    jobs_dir = Path(run_dir, JOBS_DIR)
    jobs_dir.mkdir(parents=True, exist_ok=True)
    if remove_leftovers(jobs_dir):
        logger.info("removed temporary files of an interrupted write in %s", jobs_dir)
    todo = order_longest_first(pending_jobs(jobs, run_dir, resume, retry_failed), expected_s)
    shipped = backend == "dask" and bool(object_paths(todo))
    if shipped and evaluate_on == "dask":
        raise ConfigError("runner.evaluate_on", "dask evaluates the candidates of problems "
                          "named by module only; an in-memory problem runs with "
                          "evaluate_on=local (each job on one dask worker)")
    if evaluate_on == "dask":
        stream = _swarm_stream(todo, workers, scheduler, max_retries, worker_timeout, chunks,
                               stall_timeout)
    elif backend == "dask":
        func = partial(run_job_shipped, blobs=pickled(todo)) if shipped else run_job
        stream = run_dask(todo, workers, scheduler, max_retries, worker_timeout,
                          stall_timeout, func)
    elif job_timeout is None and (workers == 1 or len(todo) <= 1):
        stream = _serial(todo)
    else:
        stream = run_pool(todo, min(workers, max(1, len(todo))), max_retries,
                          stall_timeout=stall_timeout, job_timeout=job_timeout)
    written = []
    eta = DispatchEta(len(todo), dispatch_slots(workers, len(todo), backend, scheduler,
                                                evaluate_on))
    t0 = time.perf_counter()
    try:
        with interrupts.sigint_marked():  # a KeyboardInterrupt of a job's code ends the job
            for i, (job, record) in enumerate(stream, start=1):
                written.append(write_record(run_dir, job, record))
                elapsed = time.perf_counter() - t0
                left = eta.finished(elapsed, record.get("wall_time_s"))
                cost = record.get("best_cost")
                logger.info("[%d/%d] %s: %s%s (%.1f s; elapsed %.0f s, ETA %.0f s)", i,
                            len(todo), job.job_id, record.get("status"),
                            f", cost {cost:.6g}" if isinstance(cost, float) else "",
                            record.get("wall_time_s", float("nan")), elapsed, left)
                if on_record is not None:
                    on_record(record)
    except KeyboardInterrupt as exc:
        signum = getattr(exc, "signum", int(signal.SIGINT))
        raise RunInterruptedError(str(run_dir), len(written), len(todo), signum) from None
    finally:
        stream.close()
    return written
