"""Swarm-level Dask distribution (``runner.evaluate_on=dask``): every optimizer iteration's
batch of candidates is split into chunks evaluated on Dask workers, gathered in order.

The optimizer loops (one thread per concurrent start) run in this process; the workers only
evaluate. So a worker lost mid-iteration costs only its chunk, which the scheduler runs again
on another worker (up to ``allowed-failures``, :func:`~.dask_backend.open_client`), and the
start goes on with bitwise the same costs. Each start's problem settings reach every worker
once, through a worker plugin (:class:`SpecPlugin`, also applied to workers that join later);
a worker builds the problem at its first chunk and keeps it for the run
(:func:`penaltyrun.runner.swarm.cached`).

Concurrent starts are threads of this process. pyswarms and cma draw from numpy's *global*
random state, so a :class:`Baton` lets one start's Python run at a time, with its own copy
of that state, and is passed on while the start waits for its chunks: each start draws
exactly the numbers of a serial run (evaluations run on the workers meanwhile).

Job-level and swarm-level parallelism combine (:func:`shares`): with T worker threads and J
jobs, ``min(J, T)`` starts run at once and, under ``runner.chunks: auto``, each batch is split
into T // (starts running now) chunks, so the cluster stays full and the last starts of a run
get all of it; fewer when a chunk would cost less than :data:`OVERHEAD_FACTOR` times the
measured per-batch overhead (a calibration from the start's batches so far).
"""

from __future__ import annotations

import concurrent.futures as cf
import logging
import threading
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from typing import Any

import distributed
import numpy as np

from penaltyrun.errors import RunAbortedError
from penaltyrun.jobrecord import FAILED
from penaltyrun.problems.base import BatchEvaluation
from penaltyrun.runner import swarm
from penaltyrun.runner.dask_backend import (
    POLL_S,
    WorkerWatchdog,
    close_quietly,
    lost_scheduler_error,
    open_client,
    scheduler_lost,
)
from penaltyrun.runner.job import run_job
from penaltyrun.runner.plan import Job

logger = logging.getLogger(__name__)

#: auto chunks: a chunk should cost at least this many times the per-batch overhead.
OVERHEAD_FACTOR = 10.0
#: Floor of the measured per-batch overhead (s), so one fast batch does not mislead.
MIN_OVERHEAD_S = 1e-3
#: auto chunks: seconds between two looks at the cluster's thread count.
REFRESH_S = 10.0


def shares(n_jobs: int, threads: int, chunks: int | str) -> tuple[int, int]:
    """Concurrent starts and chunks per batch for ``n_jobs`` on ``threads`` worker threads.

    Parameters
    ----------
    n_jobs : int
        Jobs to run (≥ 1).
    threads : int
        Worker threads of the cluster (≥ 1).
    chunks : int or "auto"
        ``runner.chunks``. auto: ``min(n_jobs, threads)`` starts at once, each batch in
        ``threads // starts`` chunks. An integer c: ``threads // c`` starts (at least one).

    Returns
    -------
    (int, int)
        Concurrent starts, chunks per batch (an upper bound under auto, see
        :class:`DaskBatch`).
    """
    threads, n_jobs = max(1, int(threads)), max(1, int(n_jobs))
    if chunks == "auto":
        starts = min(n_jobs, threads)
        return starts, max(1, threads // starts)
    return max(1, min(n_jobs, threads // int(chunks))), int(chunks)


class Baton:
    """One thread at a time runs a start's Python, each with its own global numpy state.

    A start's thread holds the baton (:meth:`held`) except while it waits for the workers
    (:meth:`passed`); ``np.random``'s global state is saved when the baton is passed and
    restored when it comes back, so interleaved starts never draw each other's numbers.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()

    @contextmanager
    def held(self) -> Iterator[None]:
        """Hold the baton for the whole block (a start's thread)."""
        with self._lock:
            yield

    @contextmanager
    def passed(self) -> Iterator[None]:
        """Let other starts run during the block (a wait); the caller must hold the baton."""
        state = np.random.get_state()  # noqa: NPY002  (the state pyswarms and cma draw from)
        self._lock.release()
        try:
            yield
        finally:
            self._lock.acquire()
            np.random.set_state(state)  # noqa: NPY002


class SpecPlugin(distributed.WorkerPlugin):
    """Registers one :class:`~penaltyrun.runner.swarm.ProblemSpec` on each worker.

    Parameters
    ----------
    spec : ProblemSpec
    """

    def __init__(self, spec: swarm.ProblemSpec) -> None:
        self.spec = spec

    def setup(self, worker: Any) -> None:
        """Register the spec in the worker process."""
        swarm.register(self.spec)

    def teardown(self, worker: Any) -> None:
        """Drop the spec and its cached problem."""
        swarm.forget(self.spec.key)


class DaskBatch:
    """Batched objective Z (B, dim) → (B,) evaluated as chunks on Dask workers.

    Parameters
    ----------
    evaluation : DaskEvaluation
        Its client submits the chunks, its :meth:`~DaskEvaluation.gather` collects them and
        its :meth:`~DaskEvaluation.chunk_cap` bounds their number.
    key : str
        Key of a registered problem spec.

    Attributes
    ----------
    cpu_per_eval : float or None
        Mean CPU seconds per candidate on the workers (calibration).
    overhead_s : float or None
        Mean wall seconds of a batch beyond its longest chunk (round trip, serialization,
        queueing).
    n_batches : int
    wall_s, cpu_s, critical_cpu_s : float
        Totals over the batches: wall time, CPU time of every chunk, CPU time of the longest
        chunk of each batch (the critical path on idle cores).
    """

    def __init__(self, evaluation: Any, key: str) -> None:
        self.evaluation, self.key = evaluation, key
        self.cpu_per_eval: float | None = None
        self.overhead_s: float | None = None
        self.n_batches = 0
        self.wall_s = self.cpu_s = self.critical_cpu_s = 0.0

    def n_chunks(self, n: int) -> int:
        """Chunks for a batch of ``n`` candidates: the evaluation's cap; under auto fewer
        when a chunk would cost less than :data:`OVERHEAD_FACTOR` × the overhead."""
        c = min(n, self.evaluation.chunk_cap())
        if self.evaluation.auto and self.cpu_per_eval is not None \
                and self.overhead_s is not None:
            floor_s = OVERHEAD_FACTOR * max(self.overhead_s, MIN_OVERHEAD_S)
            c = min(c, max(1, int(n * self.cpu_per_eval / floor_s)))
        return max(1, c)

    def __call__(self, Z: np.ndarray) -> np.ndarray:
        """Costs (B,) of the candidates Z (B, dim): contiguous chunks submitted at once,
        gathered in order (bitwise the costs of the whole batch evaluated locally)."""
        Z = np.atleast_2d(np.asarray(Z, float))
        t0 = time.perf_counter()
        parts = np.array_split(Z, self.n_chunks(Z.shape[0]))
        client = self.evaluation.client
        futures = [client.submit(swarm.evaluate_chunk, self.key, part, pure=False)
                   for part in parts]
        results = self.evaluation.gather(futures)
        wall = time.perf_counter() - t0
        cpu = np.array([r[1] for r in results])
        self.calibrate(Z.shape[0], float(cpu.sum()), float(cpu.max()), wall)
        parts = [r[0] for r in results]
        if isinstance(parts[0], BatchEvaluation):  # a problem's objective form
            return BatchEvaluation(*(np.concatenate([getattr(p, f) for p in parts])
                                     for f in ("cost", "converged", "status", "objective")))
        return np.concatenate(parts)

    def calibrate(self, n: int, cpu_s: float, max_cpu_s: float, wall_s: float) -> None:
        """Fold one batch of ``n`` candidates into the means and totals."""
        k = self.n_batches
        per, over = cpu_s / max(n, 1), max(0.0, wall_s - max_cpu_s)
        self.cpu_per_eval = per if k == 0 else (k * self.cpu_per_eval + per) / (k + 1)
        self.overhead_s = over if k == 0 else (k * self.overhead_s + over) / (k + 1)
        self.n_batches = k + 1
        self.wall_s += wall_s
        self.cpu_s += cpu_s
        self.critical_cpu_s += max_cpu_s


class DaskEvaluation:
    """Evaluation of every job's candidates on a Dask cluster (see the module docstring).

    Parameters
    ----------
    client : distributed.Client
    chunks : int or "auto"
        ``runner.chunks``: a fixed number of chunks per batch, or auto (the cluster's
        threads shared by the starts running now, see :meth:`chunk_cap`).
    threads : int
        Worker threads of the cluster now (refreshed every :data:`REFRESH_S` s).
    """

    def __init__(self, client: Any, chunks: int | str, threads: int) -> None:
        self.client, self.chunks, self.threads = client, chunks, max(1, int(threads))
        self.auto = chunks == "auto"
        self.stop = threading.Event()
        self.baton = Baton()
        self.active = 0  # starts running now
        self._threads_at = time.monotonic()
        self._plugins: dict[str, str] = {}
        self._lock = threading.Lock()

    def chunk_cap(self) -> int:
        """Most chunks per batch: ``runner.chunks``, or under auto the cluster's threads
        divided among the starts running now (so the last starts of a run get the whole
        cluster)."""
        if not self.auto:
            return int(self.chunks)
        if time.monotonic() - self._threads_at > REFRESH_S:
            self._threads_at = time.monotonic()
            self.threads = max(1, worker_threads(self.client) or self.threads)
        return max(1, self.threads // max(1, self.active))

    def register(self, spec: swarm.ProblemSpec) -> str:
        """Send ``spec`` to every worker (once per run); return its key."""
        with self._lock:
            if spec.key not in self._plugins:
                name = f"penaltyrun-problem-{spec.key}"
                self.client.register_plugin(SpecPlugin(spec), name=name)
                self._plugins[spec.key] = name
        return spec.key

    def objective(self, job: Job, prob: Any, layout: Any, param: str) -> DaskBatch:
        """Batched objective of ``job`` under ``param``, evaluated on the workers."""
        key = self.register(swarm.ProblemSpec.of(job, param))
        return DaskBatch(self, key)

    def best(self, job: Job, prob: Any, mats: Mapping[str, np.ndarray],
             scalars: Mapping[str, float]) -> tuple[dict[str, Any], Any]:
        """Detailed (and held-out) evaluation of the job's best candidate, on a worker."""
        key = self.register(swarm.ProblemSpec.of(job))
        fut = self.client.submit(swarm.evaluate_best_chunk, key, dict(mats), dict(scalars),
                                 job.holdout, pure=False)
        return self.gather([fut])[0]

    def gather(self, futures: list[Any]) -> list[Any]:
        """Results of ``futures`` in order, waiting with the baton passed, in short steps so
        that :attr:`stop` ends the wait.

        Raises
        ------
        RunAbortedError
            If :attr:`stop` is set first.
        Exception
            The error of a chunk that failed (e.g. ``KilledWorker``).
        """
        pending = futures
        with self.baton.passed():
            while pending:
                if self.stop.is_set():
                    for fut in futures:
                        fut.cancel()
                    raise RunAbortedError("run stopped while a batch was being evaluated")
                try:
                    distributed.wait(pending, timeout=POLL_S)
                except (TimeoutError, distributed.TimeoutError):
                    pass
                pending = [f for f in pending if not f.done()]
        return self.client.gather(futures)

    def run_job(self, job: Job) -> dict[str, Any]:
        """:func:`~penaltyrun.runner.job.run_job` of ``job`` with the baton held."""
        with self.baton.held():
            self.active += 1
            try:
                return run_job(job, self)
            finally:
                self.active -= 1

    def close(self) -> None:
        """Stop pending batches and remove the plugins (workers drop their problems)."""
        self.stop.set()
        for name in self._plugins.values():
            try:
                self.client.unregister_worker_plugin(name)
            except Exception as exc:  # scheduler gone: nothing left to clean
                logger.debug("could not unregister %s: %s", name, exc)
        self._plugins.clear()


def worker_threads(client: Any) -> int:
    """Worker threads the scheduler knows now (0 when it cannot be reached)."""
    try:
        workers = client.scheduler_info().get("workers", {})
    except Exception:  # scheduler unreachable: the caller keeps its last count
        return 0
    return sum(int(w.get("nthreads", 1)) for w in workers.values())


def cluster_threads(client: Any, timeout_s: float) -> int:
    """Worker threads of the cluster, waiting up to ``timeout_s`` for a first worker.

    Raises
    ------
    RunAbortedError
        If no worker joins within ``timeout_s`` seconds.
    """
    try:
        client.wait_for_workers(1, timeout=timeout_s)
    except (TimeoutError, distributed.TimeoutError):
        raise RunAbortedError(f"no dask worker for {timeout_s:g} s (runner.worker_timeout); "
                              "start workers and rerun") from None
    return max(1, worker_threads(client))


def run_swarm(jobs: list[Job], workers: int, scheduler: str | None, max_retries: int = 1,
              worker_timeout: float = 60.0, chunks: int | str = "auto",
              stall_timeout: float | None = None) -> Iterator[tuple[Job, dict[str, Any]]]:
    """Run ``jobs`` with their batches on Dask workers; yield ``(job, record)`` as each ends.

    Parameters
    ----------
    jobs : list of Job
    workers : int
        Worker processes of the LocalCluster (when ``scheduler`` is None).
    scheduler : str or None
        Address of a running scheduler.
    max_retries : int
        LocalCluster only: times a chunk may kill its worker before it fails.
    worker_timeout : float
        Seconds without any worker after which the run stops (s).
    chunks : int or "auto"
        ``runner.chunks`` (see :func:`shares`).
    stall_timeout : float, optional
        LocalCluster: seconds without a heartbeat before a worker is removed (s).

    Raises
    ------
    RunAbortedError
        If the scheduler cannot be reached or is lost (the starts finished before it was
        lost have been yielded; the others are not recorded), or the cluster has no worker
        for ``worker_timeout`` seconds.
    """
    client, cluster = open_client(workers, scheduler, max_retries, stall_timeout)
    evaluation = None
    pool = None
    try:
        threads = cluster_threads(client, worker_timeout)
        starts, per = shares(len(jobs), threads, chunks)
        logger.info("swarm-level dask: %d worker threads, %d starts at once, batches in up to "
                    "%d chunks%s", threads, starts, per, " (auto)" if chunks == "auto" else "")
        evaluation = DaskEvaluation(client, chunks, threads)
        pool = cf.ThreadPoolExecutor(max_workers=starts, thread_name_prefix="penaltyrun-start")
        futures = {pool.submit(evaluation.run_job, job): job for job in jobs}
        pending = set(futures)
        watchdog = WorkerWatchdog(client, worker_timeout)
        while pending:
            done, pending = cf.wait(pending, timeout=POLL_S, return_when=cf.FIRST_COMPLETED)
            lost = 0
            for fut in done:  # the starts finished before a loss are kept
                record = fut.result()
                if record.get("status") == FAILED and scheduler_lost(client):
                    lost += 1
                    continue
                yield futures[fut], record
            if lost:
                raise lost_scheduler_error(client, len(pending) + lost)
            watchdog.check(bool(done), len(pending))
    finally:
        if evaluation is not None:
            evaluation.stop.set()
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
        if evaluation is not None:
            evaluation.close()
        close_quietly(client)
        if cluster is not None:
            cluster.close()
