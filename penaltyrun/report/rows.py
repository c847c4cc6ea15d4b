"""The columns a report reads, and the per-row columns it reads only where it needs them.

A report of a large results set reads its files lazily (:func:`penaltyrun.io.read.
read_results` with ``lazy=True``): the frame holds the small columns of every job, and the
text and list columns (matrices, traces, held-out data, ...) stay in the files until a
section asks for them, for the rows it needs — one cell's traces, one best start's
matrices — through :func:`with_columns` and :func:`full_row`. On a frame read whole both
return what they are given, so each section computes the same on either.
"""

from __future__ import annotations

from collections.abc import Hashable, Iterable, Iterator

import numpy as np
import pandas as pd

from penaltyrun.io.filecheck import ROW, SOURCE
from penaltyrun.io.lazy import LAZY_COLUMNS, fill_columns, read_batches
from penaltyrun.io.schema import COLUMNS

#: Columns the report never uses: not read (the per-iteration cost history, the resolved
#: config text and the package versions are the bulk of a large results file).
UNUSED_COLUMNS = ("history", "config", "packages")
#: Columns the report reads.
REPORT_COLUMNS = tuple(n for n in COLUMNS if n not in UNUSED_COLUMNS)
#: Small columns the report reads only for single rows (a best start's, a hook's jobs):
#: a lazily read frame leaves them in the files too.
SINGLE_ROW_COLUMNS = ("seed", "best_status", "t_final", "cl_min_damping", "cl_gain_norm",
                      "cl_gain_cond", "n_iters", "package_version", "started_at",
                      "finished_at")
#: The report's columns that a lazily read frame leaves in the files.
ROW_COLUMNS = tuple(n for n in REPORT_COLUMNS
                    if n in LAZY_COLUMNS or n in SINGLE_ROW_COLUMNS)
#: The report's columns of a lazily read frame.
FRAME_COLUMNS = tuple(n for n in REPORT_COLUMNS if n not in ROW_COLUMNS)
#: The anytime trace of a start.
TRACE_COLUMNS = ("trace_evals", "trace_best")


def lazy(df: pd.DataFrame) -> bool:
    """Whether ``df`` was read lazily (its rows say where they come from)."""
    return SOURCE in df.columns and ROW in df.columns


def has(df: pd.DataFrame, column: str) -> bool:
    """Whether ``column`` is in ``df`` or can be read for its rows (:func:`with_columns`)."""
    return column in df.columns or (lazy(df) and column in ROW_COLUMNS)


def with_columns(df: pd.DataFrame, columns: Iterable[str] = ROW_COLUMNS) -> pd.DataFrame:
    """``df`` with the report columns ``columns`` read for its rows where it lacks them
    (a lazily read frame); ``df`` itself otherwise."""
    if not lazy(df):
        return df
    return fill_columns(df, [c for c in columns if c in ROW_COLUMNS])


#: Rows whose per-row columns a lazily read frame reads at a time (:func:`batches`; whole
#: row groups of a file joined until a batch holds at least this many).
BATCH_ROWS = 10_000


def batches(df: pd.DataFrame, columns: Iterable[str]) -> Iterator[pd.DataFrame]:
    """Rows of ``df`` in batches with the report columns ``columns`` read for their rows
    (:func:`with_columns`): a loop over them holds one batch's text and lists at a time,
    not the whole frame's. A lazily read frame's batches are rows of whole row groups of
    one file (:func:`penaltyrun.io.lazy.read_batches`: each group read once), in file
    order, so callers align by index label, not position; a frame read whole is one batch.
    """
    if not lazy(df):
        yield df
        return
    columns = tuple(columns)
    for where in read_batches(df, BATCH_ROWS):
        yield with_columns(df.take(where), columns)


def present(df: pd.DataFrame, column: str) -> pd.Series:
    """Whether each row of ``df`` holds a value of the report column ``column`` (boolean,
    ``df``'s index), read a batch of rows at a time (:func:`batches`)."""
    parts = [part[column].notna() for part in batches(narrow(df, (column,)), (column,))]
    if not parts:
        return pd.Series(False, index=df.index, dtype=bool)
    return pd.concat(parts).reindex(df.index) if len(parts) > 1 else parts[0]


def narrow(df: pd.DataFrame, columns: Iterable[str]) -> pd.DataFrame:
    """``df`` with only the columns ``columns`` that it has (and where its rows come
    from): what a section selects rows of, so that selecting them copies no more."""
    keep = [c for c in dict.fromkeys([*columns, SOURCE, ROW]) if c in df.columns]
    return df[keep]


def full_row(df: pd.DataFrame, label: Hashable) -> pd.Series:
    """The row ``label`` of ``df`` with every report column (:func:`with_columns`)."""
    if not lazy(df):
        return df.loc[label]
    return with_columns(df.loc[[label]]).iloc[0]


def groups(df: pd.DataFrame, keys: list[str]) -> Iterator[tuple[tuple, pd.DataFrame]]:
    """``(key, rows)`` of each group of ``df`` by ``keys``, in the order and with the rows
    of ``df.groupby(keys, sort=True)`` (rows with a missing key left out), one group at a
    time.

    Iterating a pandas groupby first copies the whole frame sorted by group and holds the
    copy until the loop ends; a report's case sections take most of its time and, of a
    large results set, that copy would be as large as the frame itself. Here only the
    group numbers (8 bytes a row) are held besides the group being worked on.
    """
    grouped = df.groupby(keys, sort=True, observed=True)
    codes = grouped.ngroup().fillna(-1).to_numpy(np.int64)
    order = np.argsort(codes, kind="stable")
    bounds = np.searchsorted(codes[order], np.arange(grouped.ngroups + 1))
    for k in range(grouped.ngroups):
        rows = df.take(order[bounds[k]:bounds[k + 1]])
        yield tuple(rows[c].iloc[0] for c in keys), rows


__all__ = ["BATCH_ROWS", "FRAME_COLUMNS", "REPORT_COLUMNS", "ROW_COLUMNS", "SINGLE_ROW_COLUMNS",
           "TRACE_COLUMNS", "UNUSED_COLUMNS", "batches", "full_row", "groups", "has", "lazy",
           "narrow", "present", "with_columns"]
