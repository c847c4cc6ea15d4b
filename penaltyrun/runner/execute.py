"""Execute planned jobs on a local process pool or a dask.distributed cluster.

Every finished job is written at once to ``<run_dir>/jobs/<job_id>.json`` (atomically:
temporary file + rename), so a killed run loses at most the jobs in flight, and
``resume=True`` skips the jobs whose file exists.
"""

from __future__ import annotations

import json
import logging
import os
import time
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Any

from penaltyrun.errors import ConfigError, RunInterruptedError
from penaltyrun.runner.job import run_job
from penaltyrun.runner.plan import Job

logger = logging.getLogger(__name__)

BACKENDS = ("local", "dask")
JOBS_DIR = "jobs"


def job_path(run_dir: Path, job: Job) -> Path:
    """File holding the record of ``job``."""
    return Path(run_dir) / JOBS_DIR / f"{job.job_id}.json"


def write_record(run_dir: Path, job: Job, record: dict[str, Any]) -> Path:
    """Write one job record atomically; returns its path."""
    path = job_path(run_dir, job)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(record, default=str))
    os.replace(tmp, path)
    return path


def pending_jobs(jobs: Iterable[Job], run_dir: Path, resume: bool,
                 retry_failed: bool = False) -> list[Job]:
    """Jobs still to run: all of them, or with ``resume`` those without a record."""
    jobs = list(jobs)
    if not resume:
        return jobs
    todo = []
    for job in jobs:
        path = job_path(run_dir, job)
        if not path.exists():
            todo.append(job)
        elif retry_failed and json.loads(path.read_text()).get("status") == "failed":
            todo.append(job)
    logger.info("resume: %d of %d jobs already finished", len(jobs) - len(todo), len(jobs))
    return todo


def _local(jobs: list[Job], workers: int) -> Iterator[tuple[Job, dict[str, Any]]]:
    if workers == 1:
        for job in jobs:
            yield job, run_job(job)
        return
    pool = ProcessPoolExecutor(max_workers=workers)
    try:
        futures = {pool.submit(run_job, job): job for job in jobs}
        remaining = set(futures)
        while remaining:
            done, remaining = wait(remaining, return_when=FIRST_COMPLETED)
            for fut in done:
                yield futures[fut], _result_or_failure(futures[fut], fut)
    except BaseException:  # Ctrl-C or an abandoned stream: do not wait for jobs in flight
        _stop_pool(pool)
        raise
    pool.shutdown()


def _stop_pool(pool: ProcessPoolExecutor) -> None:
    """Cancel queued jobs and end the workers now (their jobs in flight are not recorded)."""
    terminate = getattr(pool, "terminate_workers", None)  # Python >= 3.14
    if terminate is not None:
        terminate()
        return
    workers = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in workers:
        proc.terminate()


def _result_or_failure(job: Job, fut: Any) -> dict[str, Any]:
    """A worker that died (e.g. killed) is recorded as a failed job, not a crashed run."""
    try:
        return fut.result()
    except Exception as exc:
        return {"job_id": job.job_id, "problem": job.problem, "case": job.case,
                "param": job.param, "optimizer": job.optimizer, "start": job.start,
                "seed": job.seed, "status": "failed", "error": f"worker: {exc!r}",
                **job.meta}


def _dask(jobs: list[Job], workers: int, scheduler: str | None
          ) -> Iterator[tuple[Job, dict[str, Any]]]:
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise ConfigError("runner.backend", "dask backend needs `pip install "
                          "'penaltyrun[dask]'` (dask.distributed is not installed)",
                          allowed=BACKENDS) from None
    cluster = None
    if scheduler:
        client = Client(scheduler)
    else:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None)
        client = Client(cluster)
    try:
        futures = {client.submit(run_job, job, pure=False, key=f"penaltyrun-{job.job_id}"):
                   job for job in jobs}
        for fut in as_completed(futures):
            yield futures[fut], _result_or_failure(futures[fut], fut)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def check_settings(workers: Any, backend: Any) -> None:
    """Validate ``runner.workers`` and ``runner.backend``.

    Raises
    ------
    ConfigError
        Naming the key (and the allowed backends).
    """
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
        raise ConfigError("runner.workers", f"must be a positive integer, got {workers!r}")
    if backend not in BACKENDS:
        raise ConfigError("runner.backend", f"unknown backend {backend!r}", allowed=BACKENDS)


def execute(jobs: Iterable[Job], run_dir: Path, workers: int = 1, backend: str = "local",
            scheduler: str | None = None, resume: bool = False, retry_failed: bool = False,
            on_record: Callable[[dict[str, Any]], None] | None = None) -> list[Path]:
    """Run ``jobs`` and write one record file per finished job.

    Parameters
    ----------
    jobs : iterable of Job
    run_dir : Path
        Run directory; records go to ``run_dir/jobs``.
    workers : int
        Parallel jobs (processes), ≥ 1.
    backend : {"local", "dask"}
    scheduler : str, optional
        dask scheduler address (``None``: a LocalCluster of ``workers`` processes).
    resume, retry_failed : bool
        Skip finished jobs (and re-run failed ones with ``retry_failed``).
    on_record : callable, optional
        Called with each record as it is written (progress reporting).

    Returns
    -------
    list of Path
        Record files written in this call.

    Raises
    ------
    RunInterruptedError
        On Ctrl-C (SIGINT): queued jobs are cancelled, workers stopped, and every record
        written so far stays on disk for ``resume``.
    """
    check_settings(workers, backend)
    todo = pending_jobs(jobs, run_dir, resume, retry_failed)
    Path(run_dir, JOBS_DIR).mkdir(parents=True, exist_ok=True)
    stream = _local(todo, workers) if backend == "local" else _dask(todo, workers, scheduler)
    written = []
    t0 = time.perf_counter()
    try:
        for i, (job, record) in enumerate(stream, start=1):
            written.append(write_record(run_dir, job, record))
            elapsed = time.perf_counter() - t0
            eta = elapsed / i * (len(todo) - i)
            cost = record.get("best_cost")
            logger.info("[%d/%d] %s: %s%s (%.1f s; elapsed %.0f s, ETA %.0f s)", i, len(todo),
                        job.job_id, record.get("status"),
                        f", cost {cost:.6g}" if isinstance(cost, float) else "",
                        record.get("wall_time_s", float("nan")), elapsed, eta)
            if on_record is not None:
                on_record(record)
    except KeyboardInterrupt:
        raise RunInterruptedError(str(run_dir), len(written), len(todo)) from None
    finally:
        stream.close()
    return written
