"""Job record files: ``<run_dir>/jobs/<job_id>.json``, one per finished job.

Records are written atomically (temporary file + rename), as UTF-8 whatever the locale, so a
killed run loses at most the jobs in flight; a write that fails (a full disk) leaves no
temporary file behind and ends the run with one line naming the path and the free space.
On resume a record that cannot be taken as its job's result (truncated, garbage, another
job's record, a wrong type, a NaN cost, an unknown schema version: see
:func:`penaltyrun.runner.validate.record_problem`) is named in a warning with the reason,
moved to ``jobs/corrupt/`` and its job is run again. A record is opened only as a regular
file: a FIFO, a symbolic link or a folder of a record's name is never read (nothing blocks,
nothing is followed out of the folder); it is moved aside like a damaged record.
"""

from __future__ import annotations

import json
import logging
import os
import stat
import sys
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any, BinaryIO

from penaltyrun.errors import EnvironmentProblemError, describe_os_error
from penaltyrun.jobrecord import NO_RESULT_STATUSES, SCHEMA_VERSION
from penaltyrun.runner.plan import Job
from penaltyrun.runner.provenance import packages_json
from penaltyrun.runner.usercode import describe_user_code
from penaltyrun.runner.validate import record_problem

logger = logging.getLogger(__name__)

JOBS_DIR = "jobs"
CORRUPT_DIR = "corrupt"
#: Suffix of the temporary files of atomic writes (``.<name>.<pid>.tmp``).
TMP_SUFFIX = ".tmp"


def job_path(run_dir: Path, job: Job) -> Path:
    """File holding the record of ``job``."""
    return Path(run_dir) / JOBS_DIR / f"{job.job_id}.json"


def open_new(path: Path) -> BinaryIO:
    """``path`` opened for writing as a new regular file: whatever is at that name (a
    stale temporary file, or a symbolic link planted there) is removed first, and the file
    is created exclusively without following a link, so a write never lands outside the
    folder. For the temporary files of atomic writes, whose names are predictable.

    Raises
    ------
    OSError
        The name could not be cleared or the file created (e.g. something was put there
        again between the two).
    """
    path = Path(path)
    path.unlink(missing_ok=True)  # removes a link itself, never its target
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0)
    return os.fdopen(os.open(path, flags, 0o644), "wb")


def write_text_atomic(path: Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through a temporary file and a rename.

    Raises
    ------
    EnvironmentProblemError
        The write failed (e.g. a full disk): one line naming ``path`` (and the free space);
        the temporary file is removed and an earlier ``path`` is left as it was.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}{TMP_SUFFIX}")
    try:
        with open_new(tmp) as fh:
            fh.write(text.encode("utf-8"))
        os.replace(tmp, path)
    except OSError as exc:
        raise EnvironmentProblemError(describe_os_error(exc, path)) from None
    finally:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:  # the directory went away: nothing left to clean
            pass
    return path


def write_record(run_dir: Path, job: Job, record: dict[str, Any]) -> Path:
    """Write one job record atomically, with its ``schema_version`` and ``packages``
    (provenance: :func:`penaltyrun.runner.provenance.packages`); returns its path."""
    path = job_path(run_dir, job)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise EnvironmentProblemError(describe_os_error(exc, path.parent, "create")) from None
    record = {**record}
    record.setdefault("schema_version", SCHEMA_VERSION)
    if "packages" not in record:
        record["packages"] = packages_json(record.get("git_commit"))
    return write_text_atomic(path, json.dumps(record, default=str))


def read_regular(path: Path) -> str:
    """The UTF-8 text of ``path``, opened only as a regular file (:func:`read_regular_bytes`).

    Raises
    ------
    OSError
        ``path`` cannot be opened, or is not a regular file (``strerror`` says so).
    ValueError
        The bytes are not UTF-8.
    """
    return read_regular_bytes(path).decode("utf-8")


#: Largest job record read (bytes): a record holds one start's settings, costs and traces,
#: a few megabytes at most; a larger file (a sparse file of gigabytes in a received folder)
#: is not a record and is never read into memory.
MAX_RECORD_BYTES = 256 * 2**20


def read_regular_bytes(path: Path) -> bytes:
    """The bytes of ``path``, opened only as a regular file (never through a symbolic
    link, never blocking on a FIFO) of at most :data:`MAX_RECORD_BYTES`.

    Raises
    ------
    OSError
        ``path`` cannot be opened, is not a regular file or is larger than the limit
        (``strerror`` says so).
    """
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        if Path(path).is_symlink():
            raise OSError(exc.errno, "a symbolic link, not a regular file") from None
        raise
    with os.fdopen(fd, "rb") as fh:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise OSError(0, "not a regular file (a FIFO, device or folder)")
        if info.st_size > MAX_RECORD_BYTES:
            raise OSError(0, f"{info.st_size} bytes, more than a job record holds (the "
                             f"limit is {MAX_RECORD_BYTES})")
        return fh.read(MAX_RECORD_BYTES + 1)


def load_record(path: Path) -> tuple[dict[str, Any] | None, str]:
    """The record in ``path`` and ``""``, or ``None`` and why it cannot be used."""
    path = Path(path)
    try:
        record = json.loads(read_regular(path))
    except OSError as exc:
        return None, exc.strerror or type(exc).__name__
    except (ValueError, RecursionError) as exc:  # JSONDecodeError and UnicodeDecodeError
        # are ValueErrors; JSON nested too deep for the parser is a RecursionError
        return None, f"unreadable ({str(exc).splitlines()[0][:80] if str(exc) else 'garbage'})"
    problem = record_problem(record, path.stem)
    if problem:
        return None, problem
    return record, ""


def read_record(path: Path) -> dict[str, Any] | None:
    """The record in ``path``, or ``None`` if it cannot be taken as its job's result."""
    return load_record(path)[0]


def quarantine(path: Path) -> Path:
    """Move an unusable record to ``jobs/corrupt/`` (time-stamped); returns the new path.

    Raises
    ------
    EnvironmentProblemError
        ``jobs/corrupt`` is a symbolic link or not a folder: a record is never moved
        through a link out of the run directory.
    """
    path = Path(path)
    dest_dir = path.parent / CORRUPT_DIR
    if dest_dir.is_symlink() or (dest_dir.exists() and not dest_dir.is_dir()):
        raise EnvironmentProblemError(f"{dest_dir} is a symbolic link or not a folder, not "
                                      "this run's own: remove it, then run again")
    dest_dir.mkdir(exist_ok=True)
    dest = dest_dir / f"{path.name}.{time.strftime('%Y%m%dT%H%M%S')}.{time.time_ns() % 10**9}"
    os.replace(path, dest)
    return dest


def quarantine_with_warning(path: Path, reason: str, what: str = "resume") -> Path:
    """:func:`quarantine` and one warning naming the file and the reason."""
    dest = quarantine(path)
    logger.warning("%s: job record %s is not usable (%s); moved to %s, the job runs again",
                   what, path, reason, dest)
    return dest


#: Record fields that must be the job's own for the record to count as its result.
IDENTITY_FIELDS = ("problem", "case", "param", "optimizer", "start", "seed",
                   "optimizer_settings", "problem_params", "param_options")


def identity_mismatch(record: dict[str, Any], job: Job) -> str:
    """Why ``record`` (valid, named after ``job``) is not the result of ``job`` ("": it
    is): a field of :data:`IDENTITY_FIELDS` that differs from the one the job would
    record, e.g. a record edited by hand or copied from another configuration and
    renamed."""
    from penaltyrun.runner.job import identity_columns

    def canonical(value: Any) -> str:
        return json.dumps(json.loads(json.dumps(value, default=str)), sort_keys=True)

    expected = identity_columns(job)
    for name in IDENTITY_FIELDS:
        if name in record and canonical(record[name]) != canonical(expected.get(name)):
            return (f"its {name} {canonical(record[name]):.60} is not the job's "
                    f"{canonical(expected.get(name)):.60}")
    return ""


def pending_jobs(jobs: Iterable[Job], run_dir: Path, resume: bool,
                 retry_failed: bool = False) -> list[Job]:
    """Jobs still to run: all of them, or with ``resume`` those without a valid record
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
        record, reason = load_record(path)
        if record is not None:
            reason = identity_mismatch(record, job)
            record = None if reason else record
        if record is None:
            quarantine_with_warning(path, reason)
            todo.append(job)
        elif retry_failed and record["status"] in NO_RESULT_STATUSES:
            todo.append(job)
    logger.info("resume: %d of %d jobs already finished", len(jobs) - len(todo), len(jobs))
    warn_edited_module(jobs, run_dir)
    return todo


def warn_edited_module(jobs: list[Job], run_dir: Path) -> int:
    """Say (one warning) when records in ``run_dir`` ran the same problem with other user
    code or data: the problem module, a local module it imports or a data file a problem
    parameter names (:func:`~penaltyrun.runner.usercode.user_code_hash`) was edited since,
    and the planned jobs, a new configuration
    (:attr:`~penaltyrun.runner.plan.Job.module_hash` is part of the job id), run again.
    Returns how many such records there are."""
    current = {job.module_hash for job in jobs if job.module_hash}
    if not current:
        return 0
    planned = {job.job_id for job in jobs}
    problem = jobs[0].problem
    before: dict[str, int] = {}
    for path in Path(run_dir, JOBS_DIR).glob(f"{problem}-*.json"):
        if path.stem in planned:
            continue
        record = read_record(path)
        old = record.get("module_hash") if record is not None else None
        if record is not None and record["problem"] == problem and old and old not in current:
            before[old] = before.get(old, 0) + 1
    if before:
        from penaltyrun.problems import user_code_params

        job = jobs[0]
        what = describe_user_code(job.problem_module, job.problem_params,
                                  *user_code_params(job.problem, job.problem_module))
        logger.warning("resume: %s was edited since %d finished job(s) in "
                       "%s ran (source hash %s then, %s now): an edited module or file is a "
                       "new configuration, so its jobs run again; the old records stay on "
                       "disk, left out of results.parquet", what, sum(before.values()),
                       Path(run_dir, JOBS_DIR), ", ".join(sorted(before)),
                       ", ".join(sorted(current)))
    return sum(before.values())


def remove_leftovers(folder: Path) -> int:
    """Delete temporary files of atomic writes (``.*.<pid>.tmp``) of processes that are
    gone (killed mid-write); returns how many were removed."""
    removed = 0
    for tmp in Path(folder).glob(f".*{TMP_SUFFIX}"):
        pid = tmp.name.rsplit(".", 2)[-2] if tmp.name.count(".") >= 3 else ""
        if pid.isdigit() and int(pid) != os.getpid() and _pid_alive(int(pid)):
            continue
        try:
            tmp.unlink()
            removed += 1
        except OSError:
            pass
    return removed


def _pid_alive(pid: int) -> bool:
    if not sys.platform.startswith(("linux", "darwin")):
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
