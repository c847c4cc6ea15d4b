"""Reading results back: every job counted once, every file checked, older versions upgraded.

:func:`read_results` reads one ``results.parquet``, a folder searched recursively, or a list
of files, into one DataFrame of the columns of :data:`~penaltyrun.io.schema.COLUMNS` plus
``status_known``. On the way:

* a file that is not Parquet (truncated, garbage), is not penaltyrun output (the identity
  columns are missing), declares an Arrow extension type (penaltyrun never writes one; a
  pickled ``arrow.py_extension_type`` runs code in pyarrow before 14.0.1, penaltyrun's
  floor; such a file is refused from the footer's metadata before the table is read),
  declares more rows or bytes than a results file may hold (:data:`MAX_FILE_ROWS`,
  :data:`MAX_FILE_BYTES`, also refused from the footer), expands beyond
  :data:`MAX_FILE_BYTES` when its text is decoded, is
  of a schema version newer than this code knows, or holds a column whose values do not
  fit the schema's type (e.g. fractional ``n_evals``) is skipped with one warning naming it
  and the reason;
* the same job (same ``job_id`` and ``config_hash``) found in several files, e.g. a run
  folder beside a copy of it, is kept once, with one warning naming the duplicate files;
* a status other than ok / diverged / failed / timeout is kept but marked: ``status_known`` is False
  for its rows and ``df.attrs["unknown_statuses"]`` maps each such status to its count, so
  a report can say so instead of counting it;
* a run directory with finished job records (``jobs/*.json``) but no ``results.parquet``
  (an interrupted run, or one still running) is read from its records, with one warning
  saying so and naming ``runner.resume=true``;
* a ``holdout_long.parquet`` beside a results file (re-judged held-out data, see
  :mod:`penaltyrun.io.longholdout`) replaces that file's ``holdout`` column;
* reading many files shows a progress bar on a terminal (a log line every few seconds
  elsewhere);
* ``read_results(..., lazy=True)`` leaves the columns of
  :data:`~penaltyrun.io.lazy.LAZY_COLUMNS` (text and lists, the bulk of a large file) in
  the files: each row keeps where it came from, and
  :func:`~penaltyrun.io.lazy.fill_columns` reads them for a group of rows when they are
  needed (:mod:`penaltyrun.io.lazy`), so a report of a million rows never holds them all
  at once.

How a file is checked before and while it is read: :mod:`penaltyrun.io.filecheck`; runs
read from their job records: :mod:`penaltyrun.io.unfinished`.
"""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Iterable
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from penaltyrun.errors import ResultsUnreadableError
from penaltyrun.io import longholdout
from penaltyrun.io.filecheck import (
    KEEP_COLUMNS,
    ROW,
    SOURCE,
    check_footer,
    first_line,
    read_bounded,
    table_frame,
)
from penaltyrun.io.lazy import LAZY_COLUMNS, compact, concat_compact, read_compact
from penaltyrun.io.memory import release_memory
from penaltyrun.io.schema import COLUMNS, RESULTS_FILE, find_results
from penaltyrun.io.unfinished import read_records, unfinished_runs
from penaltyrun.jobrecord import JOB_STATUSES

logger = logging.getLogger(__name__)

#: Column added on reading: False for rows whose status is not one of
#: ok/diverged/failed/timeout.
STATUS_KNOWN = "status_known"
#: Files above which reading shows progress.
PROGRESS_MIN_FILES = 50
#: Seconds between two progress log lines (not on a terminal).
PROGRESS_LOG_S = 5.0


def _read_one(path: Path, columns: tuple[str, ...] | None = None) -> pd.DataFrame:
    """One results file as a frame of exactly :data:`COLUMNS` (older versions upgraded),
    or of ``columns`` (in :data:`COLUMNS` order) when given: only those are read (not the
    stored ``holdout`` column beside a usable re-judged held-out file, which replaces it).

    Raises
    ------
    ValueError
        The file cannot be used (see :func:`check_table`, :func:`conform`).
    OSError, pyarrow.ArrowException
        It cannot be read as Parquet.
    """
    refused = check_footer(path)
    if refused:
        raise ValueError(refused)
    names = COLUMNS if columns is None else columns
    rejudged, unused = longholdout.replacing(path, names)
    read = columns if not unused else tuple(n for n in names if n not in unused)
    return table_frame(read_bounded(path, read), path, columns, rejudged)


def declared_rows(path: Path | Iterable[Path]) -> int:
    """Rows the results files at or under ``path`` declare in their footers (files whose
    footer cannot be read count 0; nothing else is read)."""
    paths = find_results(path, quiet=True) if isinstance(path, (str, Path)) else \
        [Path(p) for p in path]
    total = 0
    for p in paths:
        try:
            total += pq.read_metadata(p).num_rows
        except (OSError, pa.ArrowException, ValueError):
            continue
    return total


class _Progress:
    """Progress over many files: a tqdm bar on a terminal, else a log line every
    :data:`PROGRESS_LOG_S` seconds."""

    def __init__(self, total: int) -> None:
        self.total, self.done = total, 0
        self.bar = None
        self.last = time.monotonic()
        if total < PROGRESS_MIN_FILES:
            self.total = 0
        elif sys.stderr is not None and sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc="reading results", unit="file",
                            file=sys.stderr, leave=False)
        else:
            logger.info("reading %d results files", total)

    def step(self) -> None:
        self.done += 1
        if self.bar is not None:
            self.bar.update(1)
        elif self.total and time.monotonic() - self.last >= PROGRESS_LOG_S:
            self.last = time.monotonic()
            logger.info("read %d of %d results files", self.done, self.total)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def drop_duplicate_jobs(df: pd.DataFrame) -> pd.DataFrame:
    """Keep each (job_id, config_hash) once (the first file in path order); one warning
    naming the files whose rows were left out and the files they duplicate."""
    dup = df.duplicated(subset=["job_id", "config_hash"], keep="first")
    if not dup.any():
        return df
    first = df[~dup].drop_duplicates(subset=["job_id", "config_hash"])
    origin = {(j, c): s for j, c, s in zip(first["job_id"], first["config_hash"],
                                           first[SOURCE])}
    pairs = sorted({(s, origin[(j, c)]) for j, c, s in
                    zip(df.loc[dup, "job_id"], df.loc[dup, "config_hash"],
                        df.loc[dup, SOURCE])})
    shown = "; ".join(f"{a} duplicates {b}" for a, b in pairs[:3])
    more = f"; and {len(pairs) - 3} more file pairs" if len(pairs) > 3 else ""
    logger.warning("left out %d duplicate rows (same job_id and config_hash, counted once): "
                   "%s%s", int(dup.sum()), shown, more)
    return df[~dup]


def _mark_statuses(df: pd.DataFrame) -> pd.DataFrame:
    """Add :data:`STATUS_KNOWN`; warn once about unknown statuses and count them in
    ``df.attrs["unknown_statuses"]``."""
    known = df["status"].isin(JOB_STATUSES)
    df[STATUS_KNOWN] = known.to_numpy(dtype=bool)
    unknown = {str(k): int(v) for k, v in df.loc[~known, "status"].value_counts(
        dropna=False).items() if v}
    if unknown:
        logger.warning("%d rows with a status other than %s (%s): reported as unknown, not "
                       "counted as ok, diverged, failed or timeout", int((~known).sum()),
                       "/".join(JOB_STATUSES),
                       ", ".join(f"{k!r}: {v}" for k, v in sorted(unknown.items())))
    df.attrs["unknown_statuses"] = unknown
    return df


def read_results(path: Path | Iterable[Path], columns: Iterable[str] | None = None,
                 lazy: bool = False, sources: bool = False,
                 checked: Iterable[str] | None = None, dedupe: bool = True) -> pd.DataFrame:
    """All results under ``path`` (file, folder, or several) as one DataFrame, each job once.

    JSON columns stay text; use :func:`~penaltyrun.io.schema.decode_json` to parse them.
    Files that cannot be used are skipped with a warning, duplicates left out, unknown
    statuses marked (see the module docstring).

    Parameters
    ----------
    path : Path or iterable of Path
        A results file, a folder searched recursively, or several files.
    columns : iterable of str, optional
        Read only these columns of :data:`~penaltyrun.io.schema.COLUMNS` (Parquet column
        projection: the others are neither read nor decoded); the columns that identify
        and check a job (:data:`KEEP_COLUMNS`) are always read. Default: every column.
    lazy : bool
        Leave the columns of :data:`LAZY_COLUMNS` in the files: the frame has
        :data:`SOURCE` and :data:`ROW` instead (where each row comes from), and
        :func:`fill_columns` reads them for the rows that need them.
    sources : bool
        Keep :data:`SOURCE` and :data:`ROW` in a frame read whole too (e.g. to name the
        file of rows found unusable later; drop them before the frame is used as one read
        whole).
    checked : iterable of str, optional
        With ``lazy``: the columns left in the files that are checked as each file is
        read (the ones the caller may fill later), as a read of whole files checks the
        columns it reads; a file failing the check is skipped. Default: every column.
    dedupe : bool
        Leave out the rows that repeat a job of an earlier file (:func:`drop_duplicate_jobs`).
        False keeps them, with :data:`SOURCE` and :data:`ROW`, for a caller that first
        drops the rows it cannot use (so that an unusable copy never hides a usable one)
        and then calls :func:`drop_duplicate_jobs` itself.

    Returns
    -------
    DataFrame
        The columns of :data:`~penaltyrun.io.schema.COLUMNS` (or ``columns``) and
        ``status_known`` (bool);
        ``attrs["unknown_statuses"]``: {status: rows} of the statuses not known here,
        ``attrs["skipped_files"]``: {path: reason} of the files left out.

    Raises
    ------
    FileNotFoundError
        If there is no results file, and no run directory with job records, under
        ``path``.
    ResultsUnreadableError
        If there are results files but none of them can be used.
    """
    if columns is not None:
        unknown = sorted(set(columns) - set(COLUMNS))
        if unknown:
            raise ValueError(f"not results columns: {', '.join(unknown)}")
        columns = tuple(n for n in COLUMNS if n in set(columns) | set(KEEP_COLUMNS))
    checked = COLUMNS if checked is None else tuple(checked)
    if lazy:
        columns = tuple(n for n in (columns or COLUMNS) if n not in LAZY_COLUMNS)
    single = isinstance(path, (str, Path))
    paths = find_results(path) if single else [Path(p) for p in path]
    unfinished = unfinished_runs(path) if single else []
    if not paths and not unfinished:
        raise FileNotFoundError(f"no {RESULTS_FILE} (and no job records) found under {path}")
    frames = []
    skipped: dict[str, str] = {}
    for run_dir in unfinished:
        try:
            frames.append(read_records(run_dir, columns))
        except ValueError as exc:
            logger.warning("skipped run directory %s: %s", run_dir, exc)
            skipped[str(run_dir)] = str(exc)
    progress = _Progress(len(paths))
    try:
        for p in paths:
            try:
                frames.append(read_compact(p, columns, checked) if lazy else _read_one(p, columns))
            except (OSError, pa.ArrowException, ValueError, MemoryError,
                    RecursionError) as exc:
                reason = first_line(exc)
                logger.warning("skipped results file %s: %s", p, reason)
                skipped[str(p)] = reason
            progress.step()
    finally:
        progress.close()
    if not frames:
        shown = ", ".join(list(skipped)[:3]) + (" ..." if len(skipped) > 3 else "")
        raise ResultsUnreadableError(f"no readable results under {path}: {len(skipped)} "
                                     f"unreadable file(s) ({shown})")
    if lazy:
        frames = [compact(f) for f in frames]  # job records: compacted here
        df = concat_compact(frames)
    else:
        df = pd.concat(frames, ignore_index=True)
    if dedupe:
        df = drop_duplicate_jobs(df)
    if not lazy and not sources and dedupe:
        df = df.drop(columns=[SOURCE, ROW])
    df = _mark_statuses(df.reset_index(drop=True))
    if lazy:
        release_memory()
    df.attrs["skipped_files"] = skipped
    return df
