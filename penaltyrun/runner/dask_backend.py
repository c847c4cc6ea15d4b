"""The dask.distributed backend: one task per job on a LocalCluster or a remote scheduler.

dask already re-runs the task of a worker that died on another worker; a task that kills
``runner.max_retries + 1`` workers ends with ``KilledWorker`` and is recorded ``failed``
(for a LocalCluster; a remote scheduler applies its own ``allowed-failures``). A run whose
cluster has had no worker for ``worker_timeout`` seconds stops with
:class:`~penaltyrun.errors.RunAbortedError` instead of waiting for ever, and so does a run
whose scheduler is lost (killed, unreachable): its cancelled tasks are not recorded, the
finished jobs stay for ``runner.resume=true``. A LocalCluster's scheduler removes a worker
that has not answered for ``runner.stall_timeout`` seconds (dask's ``worker-ttl``) and runs
its tasks again elsewhere.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator
from typing import Any

from penaltyrun.errors import ConfigError, RunAbortedError
from penaltyrun.runner.job import run_job
from penaltyrun.runner.plan import Job
from penaltyrun.runner.pool import failure_record

logger = logging.getLogger(__name__)

#: Seconds between two checks of the cluster's workers while waiting for results.
POLL_S = 1.0
#: Seconds to wait for the connection to a remote scheduler.
CONNECT_TIMEOUT_S = 10.0
_DASK_LOGGERS = ("distributed", "dask", "bokeh", "tornado")


class OneLineDaskLogs(logging.Filter):
    """Drop the tracebacks of dask's own log records (e.g. every failed reconnection to a
    lost scheduler): their message stays, one line each."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.name.split(".", 1)[0] in _DASK_LOGGERS:
            record.exc_info, record.exc_text, record.stack_info = None, None, None
        return True


def quiet_dask_logs() -> None:
    """dask's own logs at WARNING and without tracebacks, unless penaltyrun runs verbose
    (``hydra.verbose``)."""
    if logging.getLogger("penaltyrun").isEnabledFor(logging.DEBUG):
        return
    for name in _DASK_LOGGERS:
        logging.getLogger(name).setLevel(logging.WARNING)
    names = ["", *(n for n in list(logging.root.manager.loggerDict)
                   if n.split(".", 1)[0] in _DASK_LOGGERS)]
    handlers = [h for name in names for h in logging.getLogger(name).handlers]
    for handler in handlers:
        if not any(isinstance(f, OneLineDaskLogs) for f in handler.filters):
            handler.addFilter(OneLineDaskLogs())


def import_distributed() -> Any:
    """The ``distributed`` module, or a ConfigError saying how to install it."""
    try:
        import distributed
    except ImportError:
        raise ConfigError("runner.backend", "dask backend needs `pip install "
                          "'penaltyrun[dask]'` (dask.distributed is not installed)",
                          allowed=("local", "dask")) from None
    return distributed


#: Seconds the scheduler has to answer the probe of :func:`scheduler_lost`.
PROBE_TIMEOUT_S = 5.0


def scheduler_lost(client: Any) -> bool:
    """Whether the client has lost its scheduler (closed, reconnecting or not answering).

    The scheduler is asked for its identity directly: ``Client.scheduler_info`` swallows a
    broken connection and returns its cached answer, so a scheduler killed a moment ago
    would still look alive and the tasks it cancelled would be recorded as failed jobs.
    """
    if getattr(client, "status", "running") != "running":
        return True
    try:
        client.sync(client.scheduler.identity, callback_timeout=PROBE_TIMEOUT_S)
    except Exception:  # any failure to reach the scheduler
        return True
    return False


def lost_scheduler_error(client: Any, jobs_left: int) -> RunAbortedError:
    """The one line of a run whose scheduler went away."""
    where = getattr(getattr(client, "scheduler", None), "address", None) or "the scheduler"
    return RunAbortedError(f"lost the dask scheduler ({where}) with {jobs_left} jobs left; "
                           "finished jobs are kept: restart the scheduler and rerun with "
                           "runner.resume=true")


def _result_or_failure(client: Any, job: Job, fut: Any, jobs_left: int) -> dict[str, Any]:
    """The record of a finished task; a task that raised (e.g. ``KilledWorker``) is a
    failed job, not a crashed run.

    Raises
    ------
    RunAbortedError
        The task was cancelled because the scheduler is gone.
    """
    if fut.status == "cancelled" or (fut.status != "finished" and scheduler_lost(client)):
        raise lost_scheduler_error(client, jobs_left)
    try:
        return fut.result()
    except Exception as exc:
        if scheduler_lost(client):
            raise lost_scheduler_error(client, jobs_left) from None
        return failure_record(job, f"worker: {exc!r}")


def n_workers(client: Any) -> int:
    """Workers the scheduler knows now (0 when it cannot be reached)."""
    try:
        return len(client.scheduler_info().get("workers", {}))
    except Exception:  # scheduler unreachable: counts as no worker
        return 0


class WorkerWatchdog:
    """Stop a run that has had no dask worker for ``timeout`` seconds.

    Parameters
    ----------
    client : distributed.Client
        The run's client.
    timeout : float
        Seconds without any worker (and without progress) before giving up (s).
    """

    def __init__(self, client: Any, timeout: float) -> None:
        self.client = client
        self.timeout = float(timeout)
        self.lost_since: float | None = None

    def check(self, progressed: bool, jobs_left: int) -> None:
        """Call once per poll; ``progressed``: a job finished since the last call.

        Raises
        ------
        RunAbortedError
            No worker and no progress for ``timeout`` seconds.
        """
        if progressed or n_workers(self.client) > 0:
            self.lost_since = None
            return
        self.lost_since = self.lost_since or time.monotonic()
        if time.monotonic() - self.lost_since > self.timeout:
            raise RunAbortedError(
                f"no dask worker for {self.timeout:g} s (runner.worker_timeout) with "
                f"{jobs_left} jobs left; start workers and rerun with runner.resume=true "
                f"(finished jobs are kept)")


def open_client(workers: int, scheduler: str | None, max_retries: int = 1,
                stall_timeout: float | None = None) -> tuple[Any, Any]:
    """A client of the scheduler at ``scheduler``, or of a new LocalCluster.

    Parameters
    ----------
    workers : int
        Worker processes (one thread each) of the LocalCluster (when ``scheduler`` is None).
    scheduler : str or None
        Address of a running scheduler, e.g. ``tcp://127.0.0.1:8786``.
    max_retries : int
        LocalCluster only: times a task may kill its worker before it fails.
    stall_timeout : float, optional
        LocalCluster only: seconds without a heartbeat after which the scheduler removes a
        worker (``distributed.scheduler.worker-ttl``); a remote scheduler keeps its own.

    Returns
    -------
    (Client, LocalCluster or None)
        Close both when done (the cluster is None for a remote scheduler).

    Raises
    ------
    RunAbortedError
        If the scheduler cannot be reached.
    """
    distributed = import_distributed()
    import dask

    quiet_dask_logs()
    try:
        if scheduler:
            return distributed.Client(scheduler, timeout=CONNECT_TIMEOUT_S), None
        settings: dict[str, Any] = {"distributed.scheduler.allowed-failures": int(max_retries)}
        if stall_timeout is not None:
            settings["distributed.scheduler.worker-ttl"] = f"{float(stall_timeout):g}s"
        with dask.config.set(settings):
            cluster = distributed.LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=True,
                dashboard_address=None, silence_logs=logging.WARNING)
        return distributed.Client(cluster), cluster
    except OSError as exc:
        raise RunAbortedError(f"runner.scheduler: cannot connect to {scheduler}: {exc}") \
            from None


def run_dask(jobs: list[Job], workers: int, scheduler: str | None, max_retries: int = 1,
             worker_timeout: float = 60.0, stall_timeout: float | None = None,
             func: Callable[[Job], dict[str, Any]] = run_job
             ) -> Iterator[tuple[Job, dict[str, Any]]]:
    """Run ``jobs`` as dask tasks; yield ``(job, record)`` as each finishes.

    Parameters
    ----------
    jobs : list of Job
        Submitted in this order, the first with the highest priority (longest first).
    workers : int
        Worker processes of the LocalCluster (when ``scheduler`` is None).
    scheduler : str or None
        Address of a running scheduler, e.g. ``tcp://127.0.0.1:8786``.
    max_retries : int
        LocalCluster only: times a task may kill its worker before it fails.
    worker_timeout : float
        Seconds without any worker after which the run stops (s).
    stall_timeout : float, optional
        LocalCluster: seconds without a heartbeat before a worker is removed (s).
    func : callable
        Job function run on the workers (default :func:`~penaltyrun.runner.job.run_job`;
        it must pickle and must not raise).

    Raises
    ------
    RunAbortedError
        If the scheduler cannot be reached or is lost, or the cluster has no worker for
        ``worker_timeout`` seconds.
    """
    distributed = import_distributed()
    client, cluster = open_client(workers, scheduler, max_retries, stall_timeout)
    futures: dict[Any, Job] = {}
    try:
        futures = {client.submit(func, job, pure=False, key=f"penaltyrun-{job.job_id}",
                                 priority=len(jobs) - i): job  # in the given order
                   for i, job in enumerate(jobs)}
        pending = set(futures)
        watchdog = WorkerWatchdog(client, worker_timeout)
        while pending:
            try:
                done, pending = distributed.wait(pending, timeout=POLL_S,
                                                 return_when="FIRST_COMPLETED")
            except (TimeoutError, distributed.TimeoutError):
                done = set()
            except Exception:  # the connection broke under the wait
                if scheduler_lost(client):
                    raise lost_scheduler_error(client, len(pending)) from None
                raise
            for fut in done:
                yield futures[fut], _result_or_failure(client, futures[fut], fut,
                                                       len(pending) + len(done))
            watchdog.check(bool(done), len(pending))
    finally:
        close_quietly(client, futures)
        if cluster is not None:
            cluster.close()


def close_quietly(client: Any, futures: Any = ()) -> None:
    """Cancel ``futures`` and close ``client``; a scheduler that is gone is no error here."""
    try:
        for fut in futures:
            fut.cancel()
    except Exception as exc:  # scheduler gone: nothing to cancel
        logger.debug("cancel failed: %s", exc)
    try:
        client.close(timeout=5)
    except Exception as exc:  # scheduler gone
        logger.debug("client close failed: %s", exc)
