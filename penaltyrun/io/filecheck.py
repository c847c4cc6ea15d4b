"""What a results file must be before and while it is read, and its table as a frame.

A file is refused from its footer alone (:func:`check_footer`: declared rows and bytes, an
Arrow extension type), read with its text dictionary-encoded and decoded only within a byte
limit (:func:`read_bounded`), and its table checked (:func:`check_table`), cast to the
schema (:func:`conform`) and made a frame (:func:`table_frame`). Every refusal is a
``ValueError`` whose message says why; :mod:`penaltyrun.io.read` turns it into one warning
naming the file.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from penaltyrun.io import longholdout
from penaltyrun.io.schema import (
    COLUMNS,
    SCHEMA_VERSION,
    TIMESTAMP_COLUMNS,
    _upgrade_settings,
    decode_json,
    to_timestamp,
)
from penaltyrun.jobrecord import FIELDS, NUMBERS, OK
from penaltyrun.typed import is_number

#: Columns without which a Parquet file is not penaltyrun results.
IDENTITY_COLUMNS = ("job_id", "problem", "case", "param", "optimizer", "start", "status")
#: Columns read whatever the caller asks for: those that identify a job, check its file
#: and count it once.
KEEP_COLUMNS = (*IDENTITY_COLUMNS, "config_hash", "schema_version")
#: Columns of a lazily read frame: the file (or job-record folder) each row comes from,
#: and its position in that file.
SOURCE, ROW = "_source", "_row"


def first_line(exc: BaseException) -> str:
    """The first line of ``exc``'s message (its type's name if it has none)."""
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
                             f"{typ} ({first_line(exc)[:80]})") from None
        table = table.set_column(table.column_names.index(name), name, cast)
    return table


def check_columns(table: pa.Table) -> str | None:
    """Why some columns of a results table, read apart from its identity columns (the
    per-row columns a lazy read leaves in the file), cannot be reported (None: they can):
    a type that does not cast to the schema's (:func:`conform`) or a value
    :func:`check_content` refuses."""
    try:
        frame = conform(table).to_pandas()
    except ValueError as exc:
        return first_line(exc)
    return check_content(frame)


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


def read_bounded(path: Path, columns: tuple[str, ...] | None = None) -> pa.Table:
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
    table = pq.read_table(path, columns=wanted, read_dictionary=text_columns(schema, wanted))
    return decoded(table)


def text_columns(schema: pa.Schema, wanted: list[str] | None) -> list[str]:
    """The text columns of ``schema`` among ``wanted`` (None: all), read
    dictionary-encoded by :func:`read_bounded`."""
    return [f.name for f in schema if (wanted is None or f.name in wanted)
            and (pa.types.is_string(f.type) or pa.types.is_binary(f.type))]


def decoded(table: pa.Table, used: int = 0) -> pa.Table:
    """``table`` (text read dictionary-encoded) decoded, when its decoded size (plus
    ``used`` bytes already read from its file) fits :data:`MAX_FILE_BYTES` (see
    :func:`read_bounded`).

    Raises
    ------
    ValueError
        The decoded size is over the limit.
    """
    if decoded_size(table) + used > MAX_FILE_BYTES:
        raise ValueError(f"expands to more than {MAX_FILE_BYTES} bytes when read (the "
                         f"limit is {MAX_FILE_BYTES} per file): not read")
    fields = [f.with_type(f.type.value_type) if pa.types.is_dictionary(f.type) else f
              for f in table.schema]
    return table.cast(pa.schema(fields, metadata=table.schema.metadata))


def decoded_size(table: pa.Table) -> int:
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


def table_frame(table: pa.Table, path: Path, columns: tuple[str, ...] | None = None,
                rejudged: pd.DataFrame | str | None = longholdout.BESIDE) -> pd.DataFrame:
    """A table read from the results file (or job-record folder) ``path`` as a frame of the
    schema's columns (or of ``columns``): checked, upgraded from older schema versions, its
    re-judged held-out data applied (``rejudged``: see :func:`penaltyrun.io.longholdout.apply`),
    and each row's :data:`SOURCE` and :data:`ROW`.

    Raises
    ------
    ValueError
        The table cannot be used (see :func:`check_table`, :func:`conform`,
        :func:`check_content`)."""
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
    try:
        if "optimizer_settings" in names:  # each distinct (optimizer, settings) once
            pairs = list(zip(frame["optimizer"], frame["optimizer_settings"]))
            upgraded = {pair: _upgrade_settings(*pair) for pair in dict.fromkeys(pairs)}
            frame["optimizer_settings"] = [upgraded[pair] for pair in pairs]
    except (ValueError, TypeError, RecursionError) as exc:  # damaged or hostile JSON
        raise ValueError(f"column optimizer_settings holds text that is not usable JSON "
                         f"({first_line(exc)[:80]})") from None
    problem = check_content(frame)
    if problem:
        raise ValueError(problem)
    frame = longholdout.apply(frame[names], path, rejudged)
    frame.attrs = {}
    frame[SOURCE] = str(path)
    frame[ROW] = np.arange(len(frame), dtype=np.int64)
    return frame


#: Entries of the held-out JSON that are one value, not one per scenario.
HOLDOUT_SCALARS = ("horizon", "training_horizon", "training")
#: Numeric columns (a number or a list of numbers a row) whose entries no run records: a
#: cost of −∞ (no cost is), a negative time (s; NaN: not recorded).
IMPOSSIBLE_VALUES = {
    **dict.fromkeys(("best_cost", "history", "trace_best"), (np.isneginf, "-inf (no cost is)")),
    **dict.fromkeys(("t_final", "wall_time_s", "trace_cpu_s"),
                    (lambda v: v < 0, "negative times"))}
#: JSON columns whose every value is an object ({name: value}) when present.
OBJECT_COLUMNS = ("matrices", "scalars", "metrics", "holdout", "closed_loop",
                  "optimizer_settings", "problem_params", "param_options", "warm_start")


def check_content(frame: pd.DataFrame) -> str | None:
    """Why the values of ``frame`` (a results table as read) cannot be reported (None: they
    can): a value of :data:`IMPOSSIBLE_VALUES` (a cost of −∞, a negative time), a job of
    status ``ok`` without a finite ``best_cost``, a held-out cost of −∞, a JSON column of
    :data:`OBJECT_COLUMNS` whose value is not an object or is nested too deep to parse, a
    matrix that is not a rectangular array of numbers, or held-out lists of different
    lengths. Each distinct value is decoded once; columns absent from ``frame`` (a lazily
    read frame's) are not checked here but when their rows are read."""
    for name, (impossible, what) in IMPOSSIBLE_VALUES.items():
        if name in frame and any(impossible(v).any() for v in _numbers(frame[name])):
            return f"column {name} holds {what}"
    if "status" in frame and "best_cost" in frame:
        cost = pd.to_numeric(frame["best_cost"], errors="coerce").to_numpy(float)
        if ((frame["status"] == OK).to_numpy() & ~np.isfinite(cost)).any():
            return "a job of status ok has no finite best_cost (an ok job records its cost)"
    for name in (n for n in OBJECT_COLUMNS if n in frame):
        for value in frame[name].dropna().unique():
            why = json_object_problem(name, value)
            if why:
                return why
    return None


def _numbers(column: pd.Series) -> list[np.ndarray]:
    """The values of a numeric column of the schema as float arrays: the whole column for a
    number a row (anything else taken as NaN), one array a row for a list of numbers
    (:data:`penaltyrun.jobrecord.NUMBERS`)."""
    if FIELDS[str(column.name)].kind != NUMBERS:
        return [pd.to_numeric(column, errors="coerce").to_numpy(float)]
    return [np.asarray(v, float) for v in column.dropna()]


def json_object_problem(name: str, text: object) -> str | None:
    """Why the JSON text ``text`` of column ``name`` (one of :data:`OBJECT_COLUMNS`) cannot
    be reported (None: it can), see :func:`check_content`."""
    try:
        decoded = decode_json(text)
    except (ValueError, TypeError) as exc:
        return f"column {name} holds text that is not usable JSON ({first_line(exc)[:80]})"
    why = _object_problem(name, decoded)
    return f"column {name} holds {why}" if why else None


def _object_problem(name: str, value: object) -> str | None:
    """Why the decoded value of JSON column ``name`` is unusable (None: it is usable)."""
    if value is None:
        return None
    if not isinstance(value, dict):
        return f"a JSON {type(value).__name__} where an object is expected"
    if name == "matrices":
        for key, matrix in value.items():
            if not _rectangular(matrix):
                return f"matrix {str(key)[:40]!r}, which is not a rectangular array of numbers"
    if name == "holdout":
        lengths = {len(v) for v in value.values() if isinstance(v, list)}
        if len(lengths) > 1:
            return "held-out lists of different lengths"
        cost = value.get("cost", [])
        if not isinstance(cost, list) or not all(_number(c) for c in cost):
            return "held-out costs that are not a list of numbers"
        if any(c is not None and float(c) == -np.inf for c in cost):
            return "held-out costs of -inf (no cost is)"
        if any(not isinstance(v, list) for k, v in value.items() if k not in HOLDOUT_SCALARS):
            return "held-out data whose per-scenario entries are not all lists"
    if name == "scalars" and not all(_number(v, missing=False) for v in value.values()):
        return "scalars that are not all numbers"
    for key, kind in TYPED_ENTRIES.get(name, {}).items():
        if key in value and not _of_kind(value[key], kind):
            words = "an object of the kinds it holds" if isinstance(kind, dict) \
                else KIND_WORDS[kind]
            return f"a {name} entry {key!r} that is not {words}"
    return None


#: Kinds of the entries of :data:`TYPED_ENTRIES`: one number (JSON number or null), text
#: or a true/false, a list of them (one per held-out scenario), or an object whose own
#: entries are typed (a dict of entry → kind).
NUMBER, TEXT, FLAG = "number", "text", "flag"
KIND_WORDS = {NUMBER: "a number", TEXT: "text", FLAG: "true or false",
              (NUMBER,): "a list of numbers", (TEXT,): "a list of texts",
              (FLAG,): "a list of true/false"}
#: The nominal (training) scenario the held-out data of some problems carry.
TRAINING_ENTRY = {"converged": FLAG, "cost": NUMBER}
#: Entries of the JSON columns ``metrics`` and ``holdout`` that the report reads, with the
#: kind each holds where present (any entry may be null): a file whose entry holds another
#: kind is refused, so that text is never counted as a converged scenario or read as an
#: energy. Other entries are the problem's own and are not read by the report.
TYPED_ENTRIES = {
    "metrics": {"cost": NUMBER, "energy": NUMBER, "arrival_time": NUMBER, "rho": NUMBER,
                "optimum": NUMBER, "criterion": TEXT, "method": TEXT},
    "holdout": {"converged": (FLAG,), "converged_by_deadline": (FLAG,),
                "arrival_time": (NUMBER,), "kind": (TEXT,), "scenario": (TEXT,),
                "status": (TEXT,), "horizon": NUMBER, "training_horizon": NUMBER,
                "training": TRAINING_ENTRY}}


def _of_kind(value: object, kind: str | tuple[str] | dict[str, str]) -> bool:
    """Whether ``value`` (decoded JSON) is of ``kind`` (see :data:`TYPED_ENTRIES`)."""
    if isinstance(kind, dict):
        return value is None or (isinstance(value, dict) and all(
            _of_kind(value[k], sub) for k, sub in kind.items() if k in value))
    if isinstance(kind, tuple):
        return isinstance(value, list) and all(_of_kind(v, kind[0]) for v in value)
    if value is None:  # missing: allowed for every kind
        return True
    if kind == NUMBER:
        return _number(value)
    return isinstance(value, str) if kind == TEXT else isinstance(value, bool)


def _number(value: object, missing: bool = True) -> bool:
    """A JSON number that fits a float (or, with ``missing``, null); not a boolean."""
    if value is None:
        return missing
    if not is_number(value):
        return False
    try:
        float(value)
    except OverflowError:  # an integer beyond the floats' range
        return False
    return True


def _rectangular(matrix: object) -> bool:
    """Whether ``matrix`` is a non-empty list of equally long, non-empty lists of numbers."""
    if not isinstance(matrix, list) or not matrix or not all(isinstance(r, list) for r in matrix):
        return False
    width = len(matrix[0])
    return width > 0 and all(len(r) == width and all(_number(v, missing=False) for v in r)
                             for r in matrix)

