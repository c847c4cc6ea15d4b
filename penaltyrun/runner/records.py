"""Job record files: ``<run_dir>/jobs/<job_id>.json``, one per finished job.

Records are written atomically (temporary file + rename), so a killed run loses at most
the jobs in flight. On resume a record that cannot be read (truncated, garbage, not a
record) is named in a warning, moved to ``jobs/corrupt/`` and its job is run again.
"""

from __future__ import annotations

import json
import logging
import os
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from penaltyrun.runner.job import JOB_STATUSES
from penaltyrun.runner.plan import Job

logger = logging.getLogger(__name__)

JOBS_DIR = "jobs"
CORRUPT_DIR = "corrupt"


def job_path(run_dir: Path, job: Job) -> Path:
    """File holding the record of ``job``."""
    return Path(run_dir) / JOBS_DIR / f"{job.job_id}.json"


def write_record(run_dir: Path, job: Job, record: dict[str, Any]) -> Path:
    """Write one job record atomically; returns its path."""
    path = job_path(run_dir, job)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(record, default=str))
    os.replace(tmp, path)
    return path


def read_record(path: Path) -> dict[str, Any] | None:
    """The record in ``path``, or ``None`` if it is unreadable or not a job record."""
    try:
        record = json.loads(Path(path).read_text())
    except (OSError, ValueError):  # JSONDecodeError and UnicodeDecodeError are ValueErrors
        return None
    if not isinstance(record, dict) or record.get("status") not in JOB_STATUSES:
        return None
    return record


def quarantine(path: Path) -> Path:
    """Move an unreadable record to ``jobs/corrupt/`` (time-stamped); returns the new path."""
    path = Path(path)
    dest_dir = path.parent / CORRUPT_DIR
    dest_dir.mkdir(exist_ok=True)
    dest = dest_dir / f"{path.name}.{time.strftime('%Y%m%dT%H%M%S')}.{time.time_ns() % 10**9}"
    os.replace(path, dest)
    return dest


def pending_jobs(jobs: Iterable[Job], run_dir: Path, resume: bool,
                 retry_failed: bool = False) -> list[Job]:
    """Jobs still to run: all of them, or with ``resume`` those without a readable record
    (and with ``retry_failed`` also those recorded ``failed``)."""
    jobs = list(jobs)
    if not resume:
        return jobs
    todo = []
    for job in jobs:
        path = job_path(run_dir, job)
        if not path.exists():
            todo.append(job)
            continue
        record = read_record(path)
        if record is None:
            dest = quarantine(path)
            logger.warning("resume: job record %s is unreadable (truncated or not a record); "
                           "moved to %s, the job runs again", path, dest)
            todo.append(job)
        elif retry_failed and record["status"] == "failed":
            todo.append(job)
    logger.info("resume: %d of %d jobs already finished", len(jobs) - len(todo), len(jobs))
    return todo
