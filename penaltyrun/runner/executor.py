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
from penaltyrun.runner.options import resolve_workers
from penaltyrun.runner.plan import Job, order_longest_first
from penaltyrun.runner.pool import run_pool
from penaltyrun.runner.records import JOBS_DIR, pending_jobs, remove_leftovers, write_record
from penaltyrun.runner.spec import RunnerOptions

logger = logging.getLogger(__name__)

#: The default options of :func:`execute`: ``conf/config.yaml``'s, with one worker.
SERIAL = RunnerOptions(workers=1)


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


def execute(jobs: Iterable[Job], run_dir: Path, options: RunnerOptions = SERIAL, *,
            on_record: Callable[[dict[str, Any]], None] | None = None,
            expected_s: Mapping[str, float] | None = None,
            stale: Iterable[Path] = ()) -> list[Path]:
    """Run ``jobs`` and write one record file per finished job.

    Parameters
    ----------
    jobs : iterable of Job
    run_dir : Path
        Run directory; records go to ``run_dir/jobs``.
    options : RunnerOptions
        The ``runner.*`` options; those read here: ``workers`` (parallel jobs, processes;
        1: in this process; ``auto``: one per core), ``backend`` (local or dask),
        ``scheduler`` (dask scheduler address; ``None``: a LocalCluster of ``workers``
        processes), ``resume`` and ``retry_failed`` (skip finished jobs; re-run failed
        ones), ``max_retries`` (times a job whose worker process died is run again),
        ``worker_timeout`` (dask: s without any worker before the run stops),
        ``evaluate_on`` and ``chunks`` (dask: each batch of candidates evaluated as chunks
        on the workers, see :mod:`penaltyrun.runner.dask_swarm`), ``stall_timeout`` (s a
        worker may go without a heartbeat before it is killed and its job retried) and
        ``job_timeout`` (wall-clock s a job may run before its worker is killed and the job
        recorded ``timeout``; local backend). Default :data:`SERIAL`: the defaults of
        ``conf/config.yaml`` with one worker (every job in this process).
    on_record : callable, optional
        Called with each record as it is written (progress reporting).
    expected_s : mapping, optional
        ``job_id`` → expected CPU time (s): jobs are dispatched longest first (see
        :func:`~penaltyrun.runner.plan.order_longest_first`); without it, in the given order.
    stale : iterable of Path
        Files of an earlier run in ``run_dir`` that this run replaces when it ends (its
        ``results.parquet``): removed, once the folder is locked, when jobs are to run, so
        that a run stopped part-way never leaves the earlier run's results looking like
        its own (a folder holds a results file only while its last run is finished).

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
    workers = resolve_workers(options.workers)
    backend, evaluate_on = options.backend, options.evaluate_on
    scheduler, max_retries = options.scheduler, options.max_retries
    job_timeout, stall_timeout = options.job_timeout, float(options.stall_timeout)
    lock.acquire(run_dir)  # held until the results are collected (or the process ends)
    jobs_dir = Path(run_dir, JOBS_DIR)
    jobs_dir.mkdir(parents=True, exist_ok=True)
    if remove_leftovers(jobs_dir):
        logger.info("removed temporary files of an interrupted write in %s", jobs_dir)
    todo = order_longest_first(pending_jobs(jobs, run_dir, options.resume,
                                            options.retry_failed), expected_s)
    if todo:
        for path in stale:
            if Path(path).is_file():
                Path(path).unlink()
                logger.info("removed %s of an earlier run; this run writes its own when it "
                            "ends", path)
    shipped = backend == "dask" and bool(object_paths(todo))
    if shipped and evaluate_on == "dask":
        raise ConfigError("runner.evaluate_on", "dask evaluates the candidates of problems "
                          "named by module only; an in-memory problem runs with "
                          "evaluate_on=local (each job on one dask worker)")
    if evaluate_on == "dask":
        stream = _swarm_stream(todo, workers, scheduler, max_retries,
                               float(options.worker_timeout), options.chunks, stall_timeout)
    elif backend == "dask":
        func = partial(run_job_shipped, blobs=pickled(todo)) if shipped else run_job
        stream = run_dask(todo, workers, scheduler, max_retries, float(options.worker_timeout),
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
