"""In-memory problems on workers that do not share this process's memory (dask).

A job names an in-memory problem (a :func:`~penaltyrun.problems.user_cost.from_cost`
problem) by the module path ``object:<name>`` (:func:`penaltyrun.problems.hold`). Forked
workers of the local pool inherit the held object; dask workers get it pickled with
cloudpickle, once per task, and unpickle it before the job runs.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from penaltyrun import problems
from penaltyrun.errors import ConfigError
from penaltyrun.runner.job import run_job
from penaltyrun.runner.plan import Job


def object_paths(jobs: Iterable[Job]) -> list[str]:
    """Module paths of the in-memory problems ``jobs`` use (sorted, without repeats)."""
    return sorted({job.problem_module for job in jobs
                   if job.problem_module.startswith(problems.OBJECT_PREFIX)})


def pickled(jobs: Iterable[Job]) -> dict[str, bytes]:
    """The in-memory problems of ``jobs``, pickled with cloudpickle, by module path.

    Raises
    ------
    ConfigError
        A problem that cloudpickle cannot pickle (e.g. its cost holds an open file or a
        lock): one line saying how to run it instead.
    """
    import cloudpickle

    blobs = {}
    for path in object_paths(jobs):
        obj = problems.held_object(path)
        try:
            blobs[path] = cloudpickle.dumps(obj)
        except Exception as exc:  # cloudpickle raises many types (TypeError, PicklingError)
            raise ConfigError("runner.backend", f"the in-memory problem {obj.name!r} cannot "
                              f"be sent to dask workers: cloudpickle failed "
                              f"({type(exc).__name__}: {exc}); run it on the local process "
                              "pool (backend local) or make its cost picklable") from None
    return blobs


def run_job_shipped(job: Job, blobs: Mapping[str, bytes]) -> dict[str, Any]:
    """:func:`~penaltyrun.runner.job.run_job` on a dask worker, after installing the
    pickled in-memory problems ``blobs`` (from :func:`pickled`) in the worker process."""
    import cloudpickle

    for path, blob in blobs.items():
        problems.install(path, cloudpickle.loads(blob))
    return run_job(job)
