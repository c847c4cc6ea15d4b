"""What a job record must hold to be taken as the result of its job.

A record file ``jobs/<job_id>.json`` is trusted only if it passes :func:`record_problem`:
a JSON object whose ``job_id`` is the file's name, whose ``schema_version`` (when present)
is one this code knows, with every required field of the right type and the numbers the
statistics use finite. Anything else is moved aside and its job runs again
(:func:`penaltyrun.runner.records.pending_jobs`); the Parquet writer leaves it out
(:func:`penaltyrun.io.schema.collect`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from penaltyrun.jobrecord import (
    ALWAYS,
    BOOL,
    FIELDS,
    FINISHED,
    INT,
    INTS,
    JOB_STATUSES,
    NO_RESULT_STATUSES,
    NUMBER,
    NUMBERS,
    OK,
    SCHEMA_VERSION,
    TEXT,
    TEXTS,
)
from penaltyrun.typed import is_int

__all__ = ["JOB_STATUSES", "NO_RESULT_STATUSES", "OPTIONAL", "REQUIRED", "REQUIRED_FINISHED",
           "SCHEMA_VERSION", "record_problem"]

def _int64(value: Any) -> bool:
    """An integer the results file can store (64-bit)."""
    return is_int(value) and -(2 ** 63) <= value < 2 ** 63


def _number(value: Any) -> bool:
    """A number the results file can store: a float, or an integer in 64 bits."""
    return isinstance(value, float) or _int64(value)


#: How each kind of :data:`penaltyrun.jobrecord.FIELDS` is checked; fields of another kind
#: (JSON values, times) are not checked.
_KIND_CHECKS = {
    INT: _int64,
    NUMBER: _number,
    TEXT: lambda v: isinstance(v, str),
    BOOL: lambda v: isinstance(v, bool),
    NUMBERS: lambda v: isinstance(v, list) and all(_number(x) for x in v),
    INTS: lambda v: isinstance(v, list) and all(_int64(x) for x in v),
    TEXTS: lambda v: isinstance(v, list) and all(isinstance(x, str) for x in v),
}
#: Fields every record has (also a ``failed`` or ``timeout`` one), with their kind.
REQUIRED: dict[str, str] = {name: f.kind for name, f in FIELDS.items() if f.required == ALWAYS}
#: Fields an ``ok`` or ``diverged`` record has in addition.
REQUIRED_FINISHED: dict[str, str] = {name: f.kind for name, f in FIELDS.items()
                                     if f.required == FINISHED}
#: Optional fields that are checked, and their kind, when present and not null.
OPTIONAL: dict[str, str] = {name: f.kind for name, f in FIELDS.items()
                            if not f.required and f.kind in _KIND_CHECKS}


def record_problem(record: Any, job_id: str | None = None) -> str | None:
    """Why ``record`` cannot be taken as the record of job ``job_id`` (None: it can).

    Parameters
    ----------
    record : object
        The parsed JSON of a record file.
    job_id : str, optional
        The job the file belongs to (its name without ``.json``); ``None``: not checked.

    Returns
    -------
    str or None
        A short reason, e.g. ``"best_cost is NaN"``, or None for a valid record.
    """
    if not isinstance(record, Mapping):
        return f"not a JSON object but {type(record).__name__}"
    version = record.get("schema_version")
    if version is not None and (not is_int(version) or not 1 <= version <= SCHEMA_VERSION):
        return f"unknown schema_version {version!r} (this penaltyrun knows 1 to " \
               f"{SCHEMA_VERSION})"
    status = record.get("status")
    if status not in JOB_STATUSES:
        return f"status {status!r} is not one of {', '.join(JOB_STATUSES)}"
    required = dict(REQUIRED)
    if status not in NO_RESULT_STATUSES:
        required.update(REQUIRED_FINISHED)
    for name, kind in required.items():
        if record.get(name) is None:
            return f"required field {name} is missing"
        if not _KIND_CHECKS[kind](record[name]):
            return f"{name} must be {kind}, got {record[name]!r:.60}"
    for name, kind in OPTIONAL.items():
        value = record.get(name)
        if value is not None and not _KIND_CHECKS[kind](value):
            return f"{name} must be {kind}, got {value!r:.60}"
    if job_id is not None and record["job_id"] != job_id:
        return f"job_id {record['job_id']!r} is not the file's job {job_id!r}"
    cost = record.get("best_cost")
    if status not in NO_RESULT_STATUSES and math.isnan(cost):
        return "best_cost is NaN"
    if status == OK and not math.isfinite(cost):
        return f"best_cost is {cost} in an ok record (a converged cost is finite)"
    if record["start"] < 0:
        return f"start must be ≥ 0, got {record['start']}"
    return None
