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
* ``read_results(..., lazy=True)`` leaves the columns of :data:`LAZY_COLUMNS` (text and
  lists, the bulk of a large file) in the files: each row keeps where it came from, and
  :func:`fill_columns` reads them for a group of rows when they are needed (the rows'
  row groups only, with column projection), so a report of a million rows never holds
  them all at once.
"""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from penaltyrun.errors import ResultsUnreadableError
from penaltyrun.io import longholdout
from penaltyrun.io.schema import (
    COLUMNS,
    RESULTS_FILE,
    SCHEMA_VERSION,
    TIMESTAMP_COLUMNS,
    _upgrade_settings,
    decode_json,
    find_results,
    to_table,
    to_timestamp,
)
from penaltyrun.jobrecord import JOB_STATUSES
from penaltyrun.runner.records import CORRUPT_DIR, JOBS_DIR, load_record

logger = logging.getLogger(__name__)

#: Columns without which a Parquet file is not penaltyrun results.
IDENTITY_COLUMNS = ("job_id", "problem", "case", "param", "optimizer", "status")
#: Column added on reading: False for rows whose status is not one of
#: ok/diverged/failed/timeout.
STATUS_KNOWN = "status_known"
#: JSON columns that name a job's cell (its variant, its parameterization): checked on
#: reading, so a file holding damaged ones is skipped rather than breaking a report.
KEY_JSON_COLUMNS = ("problem_params", "param_options")
#: Columns read whatever the caller asks for: those that identify a job, check its file
#: and count it once.
KEEP_COLUMNS = (*IDENTITY_COLUMNS, "config_hash", "schema_version")
#: Columns of one value per job whose size varies (text, lists): the bulk of a large
#: results file. ``read_results(..., lazy=True)`` leaves them in the files;
#: :func:`fill_columns` reads them for the rows that need them.
LAZY_COLUMNS = ("error", "best_z", "z_names", "matrices", "scalars", "metrics", "holdout",
                "closed_loop", "cl_eig_real", "cl_eig_imag", "active_bounds", "gradient_note",
                "history", "trace_evals", "trace_best", "trace_cpu_s", "config", "packages")
#: Columns of a lazily read frame: the file (or job-record folder) each row comes from,
#: and its position in that file.
SOURCE, ROW = "_source", "_row"
#: Files above which reading shows progress.
PROGRESS_MIN_FILES = 50
#: Seconds between two progress log lines (not on a terminal).
PROGRESS_LOG_S = 5.0


def _first_line(exc: BaseException) -> str:
    text = str(exc)
    return text.splitlines()[0] if text else type(exc).__name__


def check_table(table: pa.Table) -> str | None:
    """Why ``table`` cannot be read as penaltyrun results (None: it can)."""
    missing = [c for c in IDENTITY_COLUMNS if c not in table.column_names]
    if missing:
        return f"not penaltyrun results (no column {', '.join(missing)})"
    empty = [c for c in IDENTITY_COLUMNS if table.column(c).null_count]
    if empty:
        return (f"column {empty[0]} has {table.column(empty[0]).null_count} empty values "
                f"(every job names its {', '.join(IDENTITY_COLUMNS)})")
    if "schema_version" in table.column_names:
        versions = [v for v in table.column("schema_version").to_pylist() if v is not None]
        newer = sorted({v for v in versions if not isinstance(v, int) or v > SCHEMA_VERSION})
        if newer:
            return (f"unknown schema version {newer[0]} (this penaltyrun reads up to "
                    f"{SCHEMA_VERSION}; upgrade penaltyrun)")
    return None


def conform(table: pa.Table) -> pa.Table:
    """``table`` with each schema column cast to the schema's type where it differs.

    Raises
    ------
    ValueError
        A column cannot be cast without loss (e.g. ``n_evals`` with fractional values).
    """
    for name, (typ, _) in COLUMNS.items():
        if name not in table.column_names or name in TIMESTAMP_COLUMNS:
            continue  # missing columns are filled later; old text times are parsed later
        column = table.column(name)
        if column.type == typ or column.null_count == len(column):
            continue
        try:
            cast = column.cast(typ, safe=True)
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError) as exc:
            raise ValueError(f"column {name} holds {column.type} values that are not "
                             f"{typ} ({_first_line(exc)[:80]})") from None
        table = table.set_column(table.column_names.index(name), name, cast)
    return table


#: Marker of an Arrow extension type in a Parquet footer's serialized Arrow schema.
EXTENSION_KEY = b"ARROW:extension:name"
#: Most rows one results file may hold (declared in its footer; checked before reading).
MAX_FILE_ROWS = 10_000_000
#: Most bytes one results file may expand to when read: its declared uncompressed size,
#: and the decoded size of its dictionary-encoded text (4 GiB).
MAX_FILE_BYTES = 4 << 30


def check_footer(path: Path) -> str | None:
    """Why the Parquet file ``path`` is refused before its table is read (None: it is
    not): more rows than :data:`MAX_FILE_ROWS` or more uncompressed bytes than
    :data:`MAX_FILE_BYTES` declared, or an Arrow extension type in the footer's serialized
    ``ARROW:schema`` (searched as bytes, not deserialized)."""
    import base64

    footer = pq.read_metadata(path)
    groups = [footer.row_group(i) for i in range(footer.num_row_groups)]
    rows = max(footer.num_rows, sum(g.num_rows for g in groups))
    if rows > MAX_FILE_ROWS:
        return f"declares {rows} rows (the limit is {MAX_FILE_ROWS} per file): not read"
    size = sum(g.total_byte_size for g in groups)
    if size > MAX_FILE_BYTES:
        return (f"declares {size} bytes uncompressed (the limit is {MAX_FILE_BYTES} per "
                f"file): not read")
    meta = footer.metadata or {}
    raw = meta.get(b"ARROW:schema", b"")
    try:
        raw = base64.b64decode(raw, validate=False)
    except ValueError:
        pass
    if EXTENSION_KEY in raw or any(EXTENSION_KEY in v for v in meta.values()):
        return ("declares an Arrow extension type (penaltyrun never writes one; a pickled "
                "one can run code): not read")
    return None


def _read_one(path: Path, columns: tuple[str, ...] | None = None) -> pd.DataFrame:
    """One results file as a frame of exactly :data:`COLUMNS` (older versions upgraded),
    or of ``columns`` (in :data:`COLUMNS` order) when given: only those are read.

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
    return _frame(_read_bounded(path, columns), path, columns)


def _read_bounded(path: Path, columns: tuple[str, ...] | None = None) -> pa.Table:
    """The table of ``path``, its text columns read dictionary-encoded and decoded only
    when they fit :data:`MAX_FILE_BYTES` (a small file can hold one long text referred to
    by every row: gigabytes once decoded, invisible in the footer). Columns the file
    itself declares dictionary-encoded are measured and decoded the same way.

    Raises
    ------
    ValueError
        The decoded size is over the limit.
    """
    schema = pq.read_schema(path)
    wanted = None if columns is None else [n for n in schema.names if n in columns]
    table = pq.read_table(path, columns=wanted, read_dictionary=_text_columns(schema, wanted))
    return _decoded(table)


def _text_columns(schema: pa.Schema, wanted: list[str] | None) -> list[str]:
    """The text columns of ``schema`` among ``wanted`` (None: all), read
    dictionary-encoded by :func:`_read_bounded`."""
    return [f.name for f in schema if (wanted is None or f.name in wanted)
            and (pa.types.is_string(f.type) or pa.types.is_binary(f.type))]


def _decoded(table: pa.Table, used: int = 0) -> pa.Table:
    """``table`` (text read dictionary-encoded) decoded, when its decoded size (plus
    ``used`` bytes already read from its file) fits :data:`MAX_FILE_BYTES` (see
    :func:`_read_bounded`).

    Raises
    ------
    ValueError
        The decoded size is over the limit.
    """
    if _decoded_size(table) + used > MAX_FILE_BYTES:
        raise ValueError(f"expands to more than {MAX_FILE_BYTES} bytes when read (the "
                         f"limit is {MAX_FILE_BYTES} per file): not read")
    fields = [f.with_type(f.type.value_type) if pa.types.is_dictionary(f.type) else f
              for f in table.schema]
    return table.cast(pa.schema(fields, metadata=table.schema.metadata))


def _decoded_size(table: pa.Table) -> int:
    """Bytes of ``table`` with its dictionary-encoded columns decoded."""
    import pyarrow.compute as pc

    size = 0
    for column in table.columns:
        for chunk in column.chunks:
            if not isinstance(chunk, pa.DictionaryArray) or not len(chunk):
                size += chunk.nbytes
            elif pa.types.is_string(chunk.type.value_type) or \
                    pa.types.is_binary(chunk.type.value_type):
                lengths = pc.fill_null(pc.binary_length(chunk.dictionary), 0)
                size += int(pc.sum(pc.take(lengths, chunk.indices)).as_py() or 0)
            else:  # fixed-width or nested values: each row the dictionary's mean entry
                size += len(chunk) * chunk.dictionary.nbytes // max(1, len(chunk.dictionary))
    return size


def _read_compact(path: Path, columns: tuple[str, ...]) -> pd.DataFrame:
    """:func:`_read_one` of a lazily read file: row group by row group, each group's text
    columns held as categories (:func:`_compact`) before the next is read, so reading
    holds one group's decoded text at a time."""
    refused = check_footer(path)
    if refused:
        raise ValueError(refused)
    schema = pq.read_schema(path)
    wanted = [n for n in schema.names if n in columns]
    parquet = pq.ParquetFile(path, read_dictionary=_text_columns(schema, wanted))
    pieces, used, first = [], 0, 0
    for g in range(parquet.metadata.num_row_groups):
        table = parquet.read_row_group(g, columns=wanted)
        size = _decoded_size(table)
        frame = _frame(_decoded(table, used), path, columns)
        used += size
        frame[ROW] += first
        first += len(frame)
        pieces.append(_compact(frame))
    if not pieces:
        return _compact(_frame(_decoded(parquet.schema_arrow.empty_table().select(wanted)),
                               path, columns))
    return _concat_compact(pieces)


def _frame(table: pa.Table, path: Path, columns: tuple[str, ...] | None = None
           ) -> pd.DataFrame:
    """:func:`_read_one` of a table already read from ``path``."""
    names = [n for n in COLUMNS if columns is None or n in columns]
    problem = check_table(table)
    if problem:
        raise ValueError(problem)
    frame = conform(table).to_pandas()
    for name in names:  # files of older schema versions lack newer columns
        if name not in frame:
            frame[name] = None
    for name in (n for n in TIMESTAMP_COLUMNS if n in names):  # schema <= 3: ISO text
        if not isinstance(frame[name].dtype, pd.DatetimeTZDtype):
            frame[name] = pd.to_datetime(frame[name].map(to_timestamp), utc=True)
    for name in (n for n in KEY_JSON_COLUMNS if n in names):  # each distinct value once
        for value in frame[name].dropna().unique():
            try:
                decode_json(value)
            except (ValueError, TypeError) as exc:
                raise ValueError(f"column {name} holds text that is not usable JSON "
                                 f"({_first_line(exc)[:80]})") from None
    try:
        if "optimizer_settings" in names:  # each distinct (optimizer, settings) once
            pairs = list(zip(frame["optimizer"], frame["optimizer_settings"]))
            upgraded = {pair: _upgrade_settings(*pair) for pair in dict.fromkeys(pairs)}
            frame["optimizer_settings"] = [upgraded[pair] for pair in pairs]
    except (ValueError, TypeError, RecursionError) as exc:  # damaged or hostile JSON
        raise ValueError(f"column optimizer_settings holds text that is not usable JSON "
                         f"({_first_line(exc)[:80]})") from None
    frame = longholdout.apply(frame[names], path)
    frame.attrs = {}
    frame[SOURCE] = str(path)
    frame[ROW] = np.arange(len(frame), dtype=np.int64)
    return frame


def _read_rows(path: Path, rows: np.ndarray, columns: tuple[str, ...]) -> pd.DataFrame:
    """Rows ``rows`` (positions in the file) of the results file ``path``, columns
    ``columns`` (:data:`COLUMNS` order) plus :data:`KEEP_COLUMNS`, checked and upgraded as
    :func:`_read_one` reads a file; index ``0 .. len(rows) − 1``. Only the row groups that
    hold the rows are read, one at a time, and only the rows are kept of each.

    Raises
    ------
    ValueError
        The file changed since it was read (fewer rows), or its rows cannot be used.
    OSError, pyarrow.ArrowException
        It cannot be read as Parquet.
    """
    wanted = tuple(n for n in COLUMNS if n in set(columns) | set(KEEP_COLUMNS))
    schema = pq.read_schema(path)
    present = [n for n in schema.names if n in wanted]
    parquet = pq.ParquetFile(path, read_dictionary=_text_columns(schema, present))
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
    table = _decoded(pa.concat_tables(pieces)) if pieces else \
        _decoded(parquet.schema_arrow.empty_table().select(present))
    with _Quiet(longholdout.logger):
        frame = _frame(table, path, wanted)
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
    from (a frame of :func:`read_results` with ``lazy=True``, or rows of it): the rows'
    row groups only, one at a time; ``df`` itself when it has them all.

    The values are those :func:`read_results` would have read (same checks, upgrades and
    re-judged held-out data), so code that calls this before using a column gives the same
    result on a lazily and an eagerly read frame.

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
            frame = _read_rows(path, sub[ROW].to_numpy(), tuple(missing))
        frame.index = sub.index
        parts.append(frame[missing])
    extra = pd.concat(parts) if len(parts) > 1 else parts[0]
    extra = extra.reindex(df.index)
    return df.assign(**{c: extra[c] for c in missing})


def read_batches(df: pd.DataFrame, max_rows: int) -> Iterator[np.ndarray]:
    """Positions in ``df`` (a frame of :func:`read_results` with ``lazy=True``, or rows of
    it) of its rows in batches that :func:`fill_columns` reads cheaply: the rows of whole
    row groups of one results file, consecutive groups joined until a batch holds at least
    ``max_rows`` rows (a group is decoded whole however few of its rows are asked for, so
    no group is split between two batches); ``max_rows`` at a time from a folder of job
    records or a file whose footer cannot be read (reading them then says why). Files in
    the order their rows first appear in ``df``, rows in file order."""
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


def declared_rows(path: Path | Iterable[Path]) -> int:
    """Rows the results files at or under ``path`` declare in their footers (files whose
    footer cannot be read count 0; nothing else is read)."""
    paths = find_results(path) if isinstance(path, (str, Path)) else [Path(p) for p in path]
    total = 0
    for p in paths:
        try:
            total += pq.read_metadata(p).num_rows
        except (OSError, pa.ArrowException, ValueError):
            continue
    return total


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
    """The finished job records of a run directory without ``results.parquet``, as
    :func:`_read_one` reads a results file; one warning saying how many, and that
    ``runner.resume=true`` finishes the run (unusable records are left out and named,
    never moved: the run may still be going); ``quiet``: no warning (the records are read
    again for :func:`fill_columns`).

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
    return _frame(to_table(records, run_id=run_dir.name), run_dir / JOBS_DIR, columns)


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


def _dedupe(df: pd.DataFrame) -> pd.DataFrame:
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


#: Text columns a lazily read frame holds as categories (sorted, so that grouping and
#: sorting give the order of the text): names, statuses, settings, the source file.
CATEGORY_COLUMNS = ("run_id", "problem", "case", "param", "optimizer", "status",
                    "stop_reason", "optimizer_settings", "problem_params", "param_options",
                    "warm_start", "config_hash", "git_commit", SOURCE)


def _compact(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` with the text columns of :data:`CATEGORY_COLUMNS` as categories: a byte or
    two per row instead of the text."""
    for name in CATEGORY_COLUMNS:
        if name in df and not isinstance(df[name].dtype, pd.CategoricalDtype):
            df[name] = df[name].astype("category")
    return df


def _concat_compact(frames: list[pd.DataFrame]) -> pd.DataFrame:
    """``pd.concat`` of frames of :func:`_compact`, their categories united (sorted) so
    that the columns stay categories."""
    from pandas.api.types import union_categoricals

    for name in CATEGORY_COLUMNS:
        if all(name in f for f in frames):
            united = union_categoricals([f[name] for f in frames], sort_categories=True)
            for f in frames:
                f[name] = f[name].cat.set_categories(united.categories)
    return pd.concat(frames, ignore_index=True)


def release_memory() -> None:
    """Give the memory freed after reading (Arrow's pool, the C heap) back to the system,
    so that what a large report computes next starts from what it holds, not from the
    peak of reading (a no-op where the C library cannot)."""
    import ctypes
    import gc

    gc.collect()
    pa.default_memory_pool().release_unused()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc
        pass


#: Allocation size (bytes) from which the C heap maps memory of its own, given back to the
#: system when freed (glibc's ``M_MMAP_THRESHOLD``; its default grows up to 32 MiB).
MMAP_THRESHOLD = 64 * 1024


def lean_process_memory() -> None:
    """Set this process up to give freed memory back to the system as it goes: Arrow
    allocates from the C heap (its system pool) instead of a pool of its own, and the C
    heap maps blocks of :data:`MMAP_THRESHOLD` bytes or more, which it unmaps when they
    are freed. A report's steps each allocate and free working copies of many rows; with
    the defaults the freed blocks stay held, and the resident memory of a large report
    grows with the steps (``bench/bench_report.py --large N --steps``). For processes the
    command line owns (``penaltyrun-report``): it changes process-wide settings, so the
    library never calls it. A no-op for the C heap where the C library is not glibc."""
    import ctypes

    pa.set_memory_pool(pa.system_memory_pool())
    try:
        ctypes.CDLL("libc.so.6").mallopt(-3, MMAP_THRESHOLD)  # -3: M_MMAP_THRESHOLD
    except (OSError, AttributeError):  # not glibc
        pass


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
                 lazy: bool = False) -> pd.DataFrame:
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
                frames.append(_read_compact(p, columns) if lazy else _read_one(p, columns))
            except (OSError, pa.ArrowException, ValueError, MemoryError,
                    RecursionError) as exc:
                reason = _first_line(exc)
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
        frames = [_compact(f) for f in frames]  # job records: compacted here
        df = _dedupe(_concat_compact(frames))
    else:
        df = _dedupe(pd.concat(frames, ignore_index=True))
    if not lazy:
        df = df.drop(columns=[SOURCE, ROW])
    df = _mark_statuses(df.reset_index(drop=True))
    if lazy:
        release_memory()
    df.attrs["skipped_files"] = skipped
    return df
