"""The one Parquet schema of penaltyrun results: one row per job.

Nested values that differ per problem (matrices, metrics, settings, the resolved config,
the package versions) are stored as JSON text columns, so every problem shares one flat
schema. Reading results back (dedupe, checks, older versions): :mod:`penaltyrun.io.read`.
"""

from __future__ import annotations

import json
import logging
import math
import os
from collections.abc import Iterable
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from penaltyrun import jobrecord
from penaltyrun.errors import EnvironmentProblemError, describe_os_error
from penaltyrun.jobrecord import SCHEMA_VERSION
from penaltyrun.runner import lock
from penaltyrun.runner.records import (
    CORRUPT_DIR,
    load_record,
    open_new,
    quarantine_with_warning,
)

logger = logging.getLogger(__name__)

#: Versions of :data:`SCHEMA` (``SCHEMA_VERSION`` lives with the record's fields,
#: :mod:`penaltyrun.jobrecord`). 3: anytime traces and warm start; 4: ``started_at`` /
#: ``finished_at`` are timestamp columns (UTC) — earlier versions stored ISO text, read back
#: as timestamps; 5: ``packages`` (provenance), and the job id covers the root seed and the
#: held-out setting — earlier files read back with ``packages`` null; 6: closed-loop
#: diagnostics of the best candidate (``closed_loop``, ``cl_*``) — earlier files read back
#: with them null (the report computes them from the stored matrices); 7: first-order
#: columns of the best candidate (``grad_norm``, ``active_bounds``, ``gradient_note``) —
#: earlier files read back with them null; 8: the anytime trace's CPU time
#: (``trace_cpu_s``) — earlier files read back with it null; 9: what exact gradients were
#: charged in ``n_evals`` (``n_gradients``, ``grad_cost``) — earlier files read back with
#: them null; 10: the polish's share of ``n_evals`` (``polish_evals``) — earlier files read
#: back with it null.
SCHEMA_HISTORY = {3: "anytime traces, warm start", 4: "timestamp columns",
                  5: "packages column; job id covers runner.seed and runner.holdout",
                  6: "closed-loop diagnostics columns (closed_loop, cl_*)",
                  7: "first-order columns (grad_norm, active_bounds, gradient_note)",
                  8: "CPU time of the anytime trace (trace_cpu_s)",
                  9: "gradients charged in n_evals (n_gradients, grad_cost)",
                  10: "the polish's share of n_evals (polish_evals)"}
RESULTS_FILE = "results.parquet"
#: Rows per Parquet row group of a results file written here. A row group is the unit a
#: reader decodes: a lazily read report (:func:`penaltyrun.io.lazy.fill_columns`) reads a
#: whole group to get any of its rows, so the group, not the file, bounds its memory.
ROW_GROUP_ROWS = 10_000

#: Arrow type of each kind of :data:`penaltyrun.jobrecord.FIELDS`.
ARROW_TYPES: dict[str, pa.DataType] = {
    jobrecord.TEXT: pa.string(), jobrecord.INT: pa.int64(), jobrecord.NUMBER: pa.float64(),
    jobrecord.BOOL: pa.bool_(), jobrecord.NUMBERS: pa.list_(pa.float64()),
    jobrecord.INTS: pa.list_(pa.int64()), jobrecord.TEXTS: pa.list_(pa.string()),
    jobrecord.JSON: pa.string(), jobrecord.TIME: pa.timestamp("us", tz="UTC"),
}
#: Column name → (arrow type, description), from the record's fields
#: (:data:`penaltyrun.jobrecord.FIELDS`). JSON columns hold text.
COLUMNS: dict[str, tuple[pa.DataType, str]] = {
    name: (ARROW_TYPES[field.kind], field.description)
    for name, field in jobrecord.FIELDS.items() if field.column}
SCHEMA = pa.schema([pa.field(name, typ) for name, (typ, _) in COLUMNS.items()])
JSON_COLUMNS = tuple(name for name in COLUMNS if jobrecord.FIELDS[name].kind == jobrecord.JSON)
TIMESTAMP_COLUMNS = tuple(name for name in COLUMNS
                          if jobrecord.FIELDS[name].kind == jobrecord.TIME)


def to_timestamp(value: Any) -> datetime | None:
    """A record's time (ISO text as job records hold it, or a datetime) as an aware UTC
    datetime; naive times are taken as UTC, unreadable ones become None."""
    if isinstance(value, str):
        try:
            value = datetime.fromisoformat(value.strip().replace("Z", "+00:00"))
        except ValueError:
            logger.warning("unreadable time %r stored as null", value)
            return None
    if not isinstance(value, datetime):
        return None
    try:
        return value.replace(tzinfo=timezone.utc) if value.tzinfo is None else \
            value.astimezone(timezone.utc)
    except OverflowError:  # e.g. 0001-01-01T00:00:00+01:00: before year 1 in UTC
        logger.warning("time %s out of range stored as null", value.isoformat())
        return None


def normalize(record: dict[str, Any], run_id: str = "") -> dict[str, Any]:
    """One record with exactly the schema's columns (JSON columns serialized)."""
    row: dict[str, Any] = {}
    for name in COLUMNS:
        value = record.get(name)
        if name in JSON_COLUMNS and value is not None and not isinstance(value, str):
            value = json.dumps(value, default=str)
        elif name in TIMESTAMP_COLUMNS:
            value = to_timestamp(value)
        row[name] = value
    row["run_id"] = record.get("run_id") or run_id
    row["schema_version"] = SCHEMA_VERSION
    return row


def to_table(records: Iterable[dict[str, Any]], run_id: str = "") -> pa.Table:
    """Arrow table in :data:`SCHEMA` from job records."""
    rows = [normalize(r, run_id) for r in records]
    return pa.Table.from_pylist(rows, schema=SCHEMA)


def collect(run_dir: Path, job_ids: Iterable[str] | None = None) -> Path:
    """Gather ``run_dir/jobs/*.json`` into ``run_dir/results.parquet``; returns its path.

    Every record is checked (:func:`penaltyrun.runner.validate.record_problem`); one that
    fails is moved to ``jobs/corrupt/`` with a warning naming it and the reason (a resume
    runs its job again). Releases this process's lock of ``run_dir``
    (:mod:`penaltyrun.runner.lock`) once the file is written.

    Parameters
    ----------
    run_dir : Path
        Run directory.
    job_ids : iterable of str, optional
        Only these jobs (the run's plan). Records of other jobs in the folder (another
        configuration: other settings, seed or held-out setting) stay on disk but are left
        out of the table, with one warning saying how many.

    Raises
    ------
    EnvironmentProblemError
        The file cannot be written (a full disk, ``results.parquet`` being a directory).
    """
    run_dir = Path(run_dir)
    files = sorted((run_dir / "jobs").glob("*.json"))
    if job_ids is not None:
        wanted = set(job_ids)
        kept = [f for f in files if f.stem in wanted]
        if len(kept) < len(files):
            logger.warning("left out %d job records of another configuration (other "
                           "settings, runner.seed, runner.holdout or an edited problem "
                           "module) found in %s; they stay on disk", len(files) - len(kept),
                           run_dir / "jobs")
        files = kept
    records = []
    for f in files:
        record, reason = load_record(f)
        if record is None:
            quarantine_with_warning(f, reason, what="collect")
            continue
        records.append(record)
    path = run_dir / RESULTS_FILE
    write_table_atomic(to_table(records, run_id=run_dir.name), path)
    logger.info("wrote %d job records to %s", len(records), path)
    lock.release(run_dir)
    return path


def write_table_atomic(table: pa.Table, path: Path) -> Path:
    """Write ``table`` as Parquet to a temporary name beside ``path``, then rename it, so
    a reader never sees a half-written file.

    Raises
    ------
    EnvironmentProblemError
        The write or the rename failed (one line naming ``path``, with the free space on a
        full disk); the temporary file is removed and an earlier ``path`` stays intact.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open_new(tmp) as fh:
            pq.write_table(table, fh, row_group_size=ROW_GROUP_ROWS)
        os.replace(tmp, path)
    except OSError as exc:
        raise EnvironmentProblemError(describe_os_error(exc, path)) from None
    finally:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass
    return path


def find_results(path: Path, quiet: bool = False) -> list[Path]:
    """Result files at ``path``: the file itself, or every results.parquet file below a
    folder (not inside ``jobs/corrupt``; a directory of that name is no result file, with
    one warning unless ``quiet``)."""
    path = Path(path)
    if path.is_file():
        return [path]
    candidates = [path] if path.exists() and not path.is_dir() else \
        [p for p in path.rglob(RESULTS_FILE) if CORRUPT_DIR not in p.parts]
    for p in candidates:
        if not p.is_file() and not quiet:  # a pipe, a device or a folder: never opened
            logger.warning("skipped %s: not a regular file", p)
    return sorted(p for p in candidates if p.is_file())


def read_results(path: Path | Iterable[Path], columns: Iterable[str] | None = None) -> Any:
    """All results under ``path`` (only ``columns`` when given): see
    :func:`penaltyrun.io.read.read_results`."""
    from penaltyrun.io.read import read_results as read

    return read(path, columns)


#: Settings that older records lack, with the behaviour the code had before they existed.
SETTINGS_BEFORE_THEY_EXISTED: dict[str, dict[str, Any]] = {
    # pso_matlab followed MathWorks' algorithm page until these settings were added
    "pso_matlab": {"neighbourhood": "others", "stall_test": "page"},
}


def _upgrade_settings(optimizer: Any, settings_json: Any) -> Any:
    """Optimizer settings JSON with the keys an older record lacks filled in as the code
    then behaved (:data:`SETTINGS_BEFORE_THEY_EXISTED`); anything else unchanged."""
    missing = SETTINGS_BEFORE_THEY_EXISTED.get(optimizer)
    if not missing or not isinstance(settings_json, str) or not settings_json:
        return settings_json
    settings = json.loads(settings_json)
    if all(key in settings for key in missing):
        return settings_json
    return json.dumps({**missing, **settings})


def decode_json(value: str | float | None) -> Any:
    """Parse one JSON column value; a missing value (None, ``""`` or the NaN pandas puts in
    a column that some of the concatenated frames lack) is None.

    Raises
    ------
    ValueError
        Not JSON, or nested too deep for the parser (a ``RecursionError`` turned into a
        ``ValueError``, so callers handle both as damaged data).
    """
    if value is None or value == "" or (isinstance(value, float) and value != value):
        return None
    try:
        return json.loads(value)
    except RecursionError:
        raise ValueError("JSON nested too deep to parse") from None


def strict_json(value: Any) -> Any:
    """``value`` (decoded JSON and numbers) with every non-finite float (NaN, ±∞, which a
    stored metric may hold) replaced by None: JSON has no token for them (Python writes
    ``NaN``, which MATLAB's ``jsondecode`` and strict parsers refuse), so they are written
    as ``null``."""
    if isinstance(value, dict):
        return {k: strict_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [strict_json(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def config_key(config_hash: object) -> str:
    """A job's ``config_hash`` as a key for matching rows of two files (missing: empty,
    whether None or the NaN pandas puts in a column)."""
    return "" if config_hash is None or config_hash != config_hash else str(config_hash)
