"""Runs without a results file: an interrupted run (or one still running) read from its
finished job records."""

from __future__ import annotations

import logging
from pathlib import Path

import pandas as pd

from penaltyrun.io.filecheck import table_frame
from penaltyrun.io.schema import RESULTS_FILE, to_table
from penaltyrun.runner.records import CORRUPT_DIR, JOBS_DIR, load_record

logger = logging.getLogger(__name__)


def unfinished_runs(path: Path) -> list[Path]:
    """Run directories at or below ``path`` that hold job records (``jobs/*.json``) but no
    ``results.parquet``: a run that was interrupted (or is still running)."""
    path = Path(path)
    if not path.is_dir():
        return []
    runs = {p.parent.parent for p in path.rglob(f"{JOBS_DIR}/*.json")
            if CORRUPT_DIR not in p.parts and p.is_file()}
    return sorted(r for r in runs if not (r / RESULTS_FILE).exists())


def read_records(run_dir: Path, columns: tuple[str, ...] | None = None,
                 quiet: bool = False) -> pd.DataFrame:
    """The finished job records of a run directory without ``results.parquet``, checked as
    :func:`~penaltyrun.io.read.read_results` checks a results file; one warning saying how many,
    and that ``runner.resume=true`` finishes the run (unusable records are left out and named,
    never moved: the run may still be going); ``quiet``: no warning (the records are read again
    for :func:`~penaltyrun.io.lazy.fill_columns`).

    Raises
    ------
    ValueError
        No record in ``run_dir/jobs`` can be used.
    """
    run_dir = Path(run_dir)
    records, bad = [], []
    for f in sorted((run_dir / JOBS_DIR).glob("*.json")):
        record, reason = load_record(f)
        if record is None:
            bad.append(f"{f.name} ({reason})")
        else:
            records.append(record)
    if bad and not quiet:
        logger.warning("left out %d unusable job records of %s: %s", len(bad), run_dir,
                       "; ".join(bad[:3]) + (" ..." if len(bad) > 3 else ""))
    if not records:
        raise ValueError(f"no usable job record in {run_dir / JOBS_DIR}")
    if not quiet:
        logger.warning("%s has no %s (the run was interrupted, or is still running): "
                       "reporting its %d finished job records; to finish it, rerun the same "
                       "command with runner.resume=true", run_dir, RESULTS_FILE, len(records))
    return table_frame(to_table(records, run_id=run_dir.name), run_dir / JOBS_DIR, columns)
