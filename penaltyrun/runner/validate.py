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

#: Job-level statuses: ``ok`` (best candidate converged), ``diverged`` (the optimizer's
#: best candidate did not meet the terminal condition), ``failed`` (the job raised, or its
#: worker process died), ``timeout`` (the job ran longer than ``runner.job_timeout`` and
#: its worker process was killed).
JOB_STATUSES = ("ok", "diverged", "failed", "timeout")
#: Statuses of a job that produced no result (no best cost): a resumed run with
#: ``runner.retry_failed=true`` runs these again, and no statistic counts their costs.
NO_RESULT_STATUSES = ("failed", "timeout")
#: Version of the record / results schema this code writes (see :mod:`penaltyrun.io.schema`
#: for the history). Records of a newer version are refused: their meaning is unknown here.
SCHEMA_VERSION = 6

_INT = "an integer"
_NUMBER = "a number"
_TEXT = "text"

#: Fields every record has (also a ``failed`` or ``timeout`` one), with their kind.
REQUIRED: dict[str, str] = {
    "job_id": _TEXT, "problem": _TEXT, "case": _TEXT, "param": _TEXT, "optimizer": _TEXT,
    "start": _INT, "seed": _INT, "status": _TEXT,
}
#: Fields an ``ok`` or ``diverged`` record has in addition.
REQUIRED_FINISHED: dict[str, str] = {"best_cost": _NUMBER}
#: Optional fields and their kind when present and not null.
OPTIONAL: dict[str, str] = {
    "error": _TEXT, "best_status": _TEXT, "stop_reason": _TEXT, "run_id": _TEXT,
    "config_hash": _TEXT, "config": _TEXT, "module_hash": _TEXT, "package_version": _TEXT,
    "git_commit": _TEXT,
    "n_evals": _INT, "n_iters": _INT, "n_nonfinite": _INT, "max_evals": _INT,
    "schema_version": _INT, "t_final": _NUMBER, "wall_time_s": _NUMBER,
    "best_converged": "true or false", "best_z": "a list of numbers",
    "history": "a list of numbers", "trace_best": "a list of numbers",
    "trace_evals": "a list of integers", "z_names": "a list of text",
    "cl_eig_real": "a list of numbers", "cl_eig_imag": "a list of numbers",
    "cl_slowest_real": _NUMBER, "cl_min_damping": _NUMBER, "cl_gain_norm": _NUMBER,
    "cl_gain_cond": _NUMBER,
}


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


_KIND_CHECKS = {
    _INT: _is_int,
    _NUMBER: _is_number,
    _TEXT: lambda v: isinstance(v, str),
    "true or false": lambda v: isinstance(v, bool),
    "a list of numbers": lambda v: isinstance(v, list) and all(_is_number(x) for x in v),
    "a list of integers": lambda v: isinstance(v, list) and all(_is_int(x) for x in v),
    "a list of text": lambda v: isinstance(v, list) and all(isinstance(x, str) for x in v),
}


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
    if version is not None and (not _is_int(version) or not 1 <= version <= SCHEMA_VERSION):
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
    if status == "ok" and not math.isfinite(cost):
        return f"best_cost is {cost} in an ok record (a converged cost is finite)"
    if record["start"] < 0:
        return f"start must be ≥ 0, got {record['start']}"
    return None
