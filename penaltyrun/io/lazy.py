"""Lazily read results: the small columns of every job in memory, the text and list columns
(:data:`LAZY_COLUMNS`) left in the files until a group of rows needs them.

:func:`~penaltyrun.io.read.read_results` with ``lazy=True`` reads each file row group by
row group (:func:`read_compact`), its text columns held as categories; each row keeps the
file it came from (:data:`~penaltyrun.io.filecheck.SOURCE`) and its position there
(:data:`~penaltyrun.io.filecheck.ROW`). :func:`fill_columns` reads the other columns for
the rows that need them (their row groups only, with column projection), and
:func:`read_batches` groups rows so that each row group is decoded once.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from penaltyrun.errors import ResultsUnreadableError
from penaltyrun.io import longholdout
from penaltyrun.io.filecheck import (
    KEEP_COLUMNS,
    ROW,
    SOURCE,
    check_columns,
    check_footer,
    decoded,
    decoded_size,
    table_frame,
    text_columns,
)
from penaltyrun.io.schema import COLUMNS
from penaltyrun.io.unfinished import read_records
from penaltyrun.runner.records import JOBS_DIR

#: Columns of one value per job whose size varies (text, lists): the bulk of a large
#: results file. ``read_results(..., lazy=True)`` leaves them in the files;
#: :func:`fill_columns` reads them for the rows that need them.
LAZY_COLUMNS = ("error", "best_z", "z_names", "matrices", "scalars", "metrics", "holdout",
                "closed_loop", "cl_eig_real", "cl_eig_imag", "active_bounds", "gradient_note",
                "history", "trace_evals", "trace_best", "trace_cpu_s", "config", "packages")


def read_compact(path: Path, columns: tuple[str, ...],
                 checked: Iterable[str] = COLUMNS) -> pd.DataFrame:
    """A results file read lazily: row group by row group, each group's text
    columns held as categories (:func:`compact`) before the next is read, so reading
    holds one group's decoded text at a time.

    The columns of ``checked`` left in the file (those the caller may read later) are
    checked as they would be when read whole (one row group at a time, then dropped), so
    a file with damaged rows is refused here, where the reader skips it with one warning,
    not in the middle of a report that needs them. Beside a usable re-judged held-out file
    (:mod:`penaltyrun.io.longholdout`) the stored ``holdout`` column, which it replaces, is
    neither read nor checked.

    Raises
    ------
    ValueError
        The file is refused (its footer, size, a column or a value).
    """
    refused = check_footer(path)
    if refused:
        raise ValueError(refused)
    schema = pq.read_schema(path)
    rejudged, unused = longholdout.replacing(path, {*columns, *checked})
    wanted = [n for n in schema.names if n in columns and n not in unused]
    checkable = set(checked) & set(COLUMNS)
    left = [n for n in schema.names if n in checkable and n not in wanted and n not in unused]
    parquet = pq.ParquetFile(path, read_dictionary=text_columns(schema, wanted))
    left_file = pq.ParquetFile(path, read_dictionary=text_columns(schema, left))
    pieces, used, first = [], 0, 0
    for g in range(parquet.metadata.num_row_groups):
        if left:
            rest = left_file.read_row_group(g, columns=left)
            problem = check_columns(decoded(rest, used))
            if problem:
                raise ValueError(problem)
            used += decoded_size(rest)
            del rest
        table = parquet.read_row_group(g, columns=wanted)
        size = decoded_size(table)
        frame = table_frame(decoded(table, used), path, columns, rejudged)
        used += size
        frame[ROW] += first
        first += len(frame)
        pieces.append(compact(frame))
    if not pieces:
        return compact(table_frame(decoded(parquet.schema_arrow.empty_table().select(wanted)),
                               path, columns, rejudged))
    return concat_compact(pieces)


def read_rows(path: Path, rows: np.ndarray, columns: tuple[str, ...]) -> pd.DataFrame:
    """Rows ``rows`` (positions in the file) of the results file ``path``, columns
    ``columns`` (:data:`COLUMNS` order) plus :data:`KEEP_COLUMNS`, checked and upgraded as
    a results file is read; index ``0 .. len(rows) − 1``. Only the row groups that
    hold the rows are read, one at a time, and only the rows are kept of each.

    Raises
    ------
    ValueError
        The file changed since it was read (fewer rows).
    ResultsUnreadableError
        Its rows cannot be used (:func:`~penaltyrun.io.filecheck.check_content`): one line
        naming the file.
    OSError, pyarrow.ArrowException
        It cannot be read as Parquet.
    """
    wanted = tuple(n for n in COLUMNS if n in set(columns) | set(KEEP_COLUMNS))
    schema = pq.read_schema(path)
    rejudged, unused = longholdout.replacing(path, wanted)
    present = [n for n in schema.names if n in wanted and n not in unused]
    parquet = pq.ParquetFile(path, read_dictionary=text_columns(schema, present))
    meta = parquet.metadata
    bounds = np.cumsum([0] + [meta.row_group(i).num_rows for i in range(meta.num_row_groups)])
    rows = np.asarray(rows, np.int64)
    if rows.size and (rows.min() < 0 or rows.max() >= bounds[-1]):
        raise ValueError(f"{path} has fewer rows than when it was read: read the results "
                         "again")
    group = np.searchsorted(bounds, rows, side="right") - 1
    pieces, order = [], []
    for g in np.unique(group):
        mine = np.flatnonzero(group == g)
        table = parquet.read_row_group(int(g), columns=present)
        pieces.append(table.take(pa.array(rows[mine] - bounds[g])))
        order.append(mine)
    table = decoded(pa.concat_tables(pieces)) if pieces else \
        decoded(parquet.schema_arrow.empty_table().select(present))
    with _Quiet(longholdout.logger):
        try:
            frame = table_frame(table, path, wanted, rejudged)
        except ValueError as exc:  # checked when read (read_compact): changed since
            raise ResultsUnreadableError(
                f"{path}: {exc}; its rows were checked when the results were read, so the "
                "file changed since: report again") from None
    if order:  # back to the order of ``rows``
        frame = frame.iloc[np.argsort(np.concatenate(order), kind="stable")]
    return frame.reset_index(drop=True)


class _Quiet:
    """Within the block, ``logger`` says only warnings (its info lines were said when the
    rows were first read)."""

    def __init__(self, log: logging.Logger) -> None:
        self.log, self.level = log, log.level

    def __enter__(self) -> None:
        self.log.setLevel(max(self.level, logging.WARNING))

    def __exit__(self, *exc: object) -> None:
        self.log.setLevel(self.level)


def fill_columns(df: pd.DataFrame, columns: Iterable[str]) -> pd.DataFrame:
    """``df`` with the columns ``columns`` that it lacks read from the files its rows came
    from (a frame of :func:`~penaltyrun.io.read.read_results` with ``lazy=True``, or rows
    of it): the rows' row groups only, one at a time; ``df`` itself when it has them all.

    The values are those :func:`~penaltyrun.io.read.read_results` would have read (same checks,
    upgrades and re-judged held-out data), so code that calls this before using a column gives
    the same result on a lazily and an eagerly read frame.

    Raises
    ------
    KeyError
        A column is missing and ``df`` does not say where its rows come from, or a name is
        not a results column.
    ValueError
        A file changed since it was read.
    """
    missing = [c for c in columns if c not in df.columns]
    if not missing:
        return df
    unknown = sorted(set(missing) - set(COLUMNS))
    if unknown:
        raise KeyError(f"not results columns: {', '.join(unknown)}")
    if SOURCE not in df or ROW not in df:
        raise KeyError(f"columns {', '.join(missing)} were not read, and the rows do not "
                       "say which file they come from")
    if df.empty:
        return df.assign(**{c: pd.Series(index=df.index, dtype=object) for c in missing})
    parts = []
    for source, where in df.groupby(SOURCE, sort=False).indices.items():
        sub = df.iloc[where]
        path = Path(source)
        if path.name == JOBS_DIR and path.is_dir():  # an unfinished run: its job records
            keep = tuple(n for n in COLUMNS if n in set(missing) | set(KEEP_COLUMNS))
            frame = read_records(path.parent, keep, quiet=True)
            frame = frame.drop_duplicates("job_id").set_index("job_id") \
                .reindex(sub["job_id"]).reset_index(drop=True)
        else:
            frame = read_rows(path, sub[ROW].to_numpy(), tuple(missing))
        frame.index = sub.index
        parts.append(frame[missing])
    extra = pd.concat(parts) if len(parts) > 1 else parts[0]
    extra = extra.reindex(df.index)
    return df.assign(**{c: extra[c] for c in missing})


def read_batches(df: pd.DataFrame, max_rows: int) -> Iterator[np.ndarray]:
    """Positions in ``df`` (a frame of :func:`~penaltyrun.io.read.read_results` with
    ``lazy=True``, or rows of it) of its rows in batches that :func:`fill_columns` reads
    cheaply: the rows of whole row groups of one results file, consecutive groups joined until
    a batch holds at least ``max_rows`` rows (a group is decoded whole however few of its rows
    are asked for, so no group is split between two batches); ``max_rows`` at a time from a
    folder of job records or a file whose footer cannot be read (reading them then says why).
    Files in the order their rows first appear in ``df``, rows in file order."""
    for source, where in df.groupby(SOURCE, sort=False).indices.items():
        rows = df[ROW].to_numpy()[where]
        order = np.argsort(rows, kind="stable")
        where, rows = where[order], rows[order]
        path = Path(source)
        meta = None
        if not (path.name == JOBS_DIR and path.is_dir()):
            try:
                meta = pq.read_metadata(path)
            except (OSError, pa.ArrowException):
                meta = None
        if meta is None:
            for begin in range(0, len(where), max_rows):
                yield where[begin:begin + max_rows]
            continue
        bounds = np.cumsum([0] + [meta.row_group(i).num_rows
                                  for i in range(meta.num_row_groups)])
        group = np.searchsorted(bounds, rows, side="right") - 1
        begin = 0
        for end in [*np.flatnonzero(np.diff(group)) + 1, len(where)]:
            if end - begin >= max_rows or end == len(where):
                yield where[begin:end]
                begin = end


#: Text columns a lazily read frame holds as categories (sorted, so that grouping and
#: sorting give the order of the text): names, statuses, settings, the source file.
CATEGORY_COLUMNS = ("run_id", "problem", "case", "param", "optimizer", "status",
                    "stop_reason", "optimizer_settings", "problem_params", "param_options",
                    "warm_start", "config_hash", "git_commit", SOURCE)


def compact(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` with the text columns of :data:`CATEGORY_COLUMNS` as categories: a byte or
    two per row instead of the text."""
    for name in CATEGORY_COLUMNS:
        if name in df and not isinstance(df[name].dtype, pd.CategoricalDtype):
            df[name] = df[name].astype("category")
    return df


def concat_compact(frames: list[pd.DataFrame]) -> pd.DataFrame:
    """``pd.concat`` of frames of :func:`compact`, their categories united (sorted) so
    that the columns stay categories."""
    from pandas.api.types import union_categoricals

    for name in CATEGORY_COLUMNS:
        if all(name in f for f in frames):
            united = union_categoricals([f[name] for f in frames], sort_categories=True)
            for f in frames:
                f[name] = f[name].cat.set_categories(united.categories)
    return pd.concat(frames, ignore_index=True)
