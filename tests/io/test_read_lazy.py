"""Lazy reading: the text and list columns stay in the files, and are read for a group of
rows with exactly the values an eager read gives (row groups, duplicates, re-judged
held-out data and unfinished runs included)."""

import json

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from penaltyrun.io import lazy, read
from penaltyrun.io.filecheck import ROW, SOURCE
from penaltyrun.io.lazy import LAZY_COLUMNS, fill_columns
from penaltyrun.io.read import declared_rows
from penaltyrun.io.schema import RESULTS_FILE, SCHEMA, normalize
from penaltyrun.runner.records import write_text_atomic


def record(start, **overrides):
    rec = {"job_id": f"zermelo-default-full-pso-abc-s{start:03d}", "problem": "zermelo",
           "case": "default", "param": "full", "optimizer": "pso", "start": start,
           "seed": start, "status": "ok", "best_cost": 1.0 + start, "n_evals": 10,
           "config_hash": "h1", "matrices": {"K": [[1.0 + start, 0.0], [0.0, 2.0]]},
           "trace_evals": list(range(1, start % 4 + 2)),
           "trace_best": [5.0 - k for k in range(start % 4 + 1)],
           "error": None if start % 5 else f"boom {start}",
           "holdout": {"cost": [float(start)]},
           "optimizer_settings": {"n_particles": 20}}
    rec.update(overrides)
    return rec


def write_file(path, records, group_rows):
    """``records`` as a results file of row groups of ``group_rows`` rows."""
    path.mkdir(parents=True, exist_ok=True)
    table = pa.Table.from_pylist([normalize(r, path.name) for r in records], schema=SCHEMA)
    pq.write_table(table, path / RESULTS_FILE, row_group_size=group_rows)
    return path / RESULTS_FILE


def same(a, b):
    """Equal values, list columns and NaN included."""
    def key(v):
        if isinstance(v, float) and np.isnan(v):
            return "nan"
        return json.dumps(np.asarray(v).tolist() if hasattr(v, "__len__") and
                          not isinstance(v, str) else v, default=str)
    return [key(v) for v in a] == [key(v) for v in b]


@pytest.fixture
def folder(tmp_path):
    """Two results files (the second of several row groups, one job also in the first)
    and an unfinished run (job records only)."""
    write_file(tmp_path / "a", [record(i) for i in range(5)], 2)
    write_file(tmp_path / "b", [record(i, config_hash="h2") for i in range(23)]
               + [record(0)], 4)
    jobs = tmp_path / "c" / "jobs"
    jobs.mkdir(parents=True)
    for i in range(3):
        r = record(i, config_hash="h3")
        write_text_atomic(jobs / f"{r['job_id']}.json", json.dumps(r))
    return tmp_path


def test_lazy_frame_leaves_the_per_row_columns_in_the_files(folder):
    eager = read.read_results(folder)
    lazy = read.read_results(folder, lazy=True)
    assert len(lazy) == len(eager) == 5 + 23 + 3  # the duplicate job counted once
    assert not set(LAZY_COLUMNS) & set(lazy.columns)
    assert {SOURCE, ROW} <= set(lazy.columns) and not {SOURCE, ROW} & set(eager.columns)
    assert lazy["job_id"].tolist() == eager["job_id"].tolist()
    assert declared_rows(folder) == 5 + 24


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_filled_columns_equal_an_eager_read(folder, seed):
    eager = read.read_results(folder)
    lazy = read.read_results(folder, lazy=True)
    rows = np.random.default_rng(seed).permutation(len(lazy))[:17]  # any order, any file
    filled = fill_columns(lazy.iloc[rows], ["matrices", "trace_evals", "trace_best",
                                            "error", "holdout"])
    assert filled.index.tolist() == lazy.index[rows].tolist()
    for column in ("matrices", "trace_evals", "trace_best", "error", "holdout"):
        assert same(filled[column], eager[column].iloc[rows]), column


def test_fill_columns_keeps_a_frame_that_has_them_and_refuses_one_that_cannot(folder):
    eager = read.read_results(folder)
    assert fill_columns(eager, ["matrices"]) is eager
    with pytest.raises(KeyError, match="do not say which file"):
        fill_columns(eager.drop(columns="matrices"), ["matrices"])
    with pytest.raises(KeyError, match="not results columns"):
        fill_columns(read.read_results(folder, lazy=True), ["nonsense"])
    empty = fill_columns(read.read_results(folder, lazy=True).iloc[:0], ["matrices"])
    assert "matrices" in empty and empty.empty


def test_re_judged_held_out_data_replace_the_stored_ones_when_filled(folder):
    long = pa.table({"job_id": [record(1)["job_id"]], "config_hash": ["h1"],
                     "holdout": [json.dumps({"cost": [99.0]})]})
    pq.write_table(long, folder / "a" / "holdout_long.parquet")
    eager = read.read_results(folder)
    lazy = read.read_results(folder, lazy=True)
    filled = fill_columns(lazy, ["holdout"])
    assert same(filled["holdout"], eager["holdout"])
    assert '"cost": [99.0]' in "".join(filled["holdout"].dropna())


def test_a_file_that_lost_rows_since_it_was_read_is_an_error(folder):
    lazy = read.read_results(folder / "b", lazy=True)
    write_file(folder / "b", [record(0)], 4)
    with pytest.raises(ValueError, match="fewer rows"):
        fill_columns(lazy, ["matrices"])


def test_a_file_with_damaged_rows_is_skipped_by_a_lazy_read_with_one_warning(tmp_path,
                                                                              caplog):
    """A lazy read leaves the matrices in the file but checks them as it reads the file
    (a row group at a time): the damaged file is skipped with one warning naming it and
    the rest of the folder is read, as a read of whole files does."""
    import logging

    damaged = write_file(tmp_path / "d", [record(i) for i in range(5)]
                         + [record(5, matrices={"K": [[1.0, 2.0], [3.0]]})], 2)
    write_file(tmp_path / "e", [record(i, config_hash="h2") for i in range(4)], 2)
    with caplog.at_level(logging.WARNING):
        lazy = read.read_results(tmp_path, lazy=True)
    warned = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warned) == 1 and str(damaged) in warned[0]
    assert "column matrices holds matrix 'K'" in warned[0]
    assert len(lazy) == 4 and set(lazy["config_hash"]) == {"h2"}
    assert lazy.attrs["skipped_files"] == {str(damaged): warned[0].split(": ", 1)[1]}
    eager = read.read_results(tmp_path)
    assert len(eager) == 4


def test_damaged_rows_written_after_a_lazy_read_are_one_error_naming_the_file(tmp_path):
    """A file replaced by damaged rows after the lazy read is found when its rows are
    read, and said in one line naming the file (no traceback)."""
    from penaltyrun.errors import ResultsUnreadableError

    path = write_file(tmp_path / "d", [record(i) for i in range(6)], 2)
    lazy = read.read_results(tmp_path / "d", lazy=True)
    write_file(tmp_path / "d", [record(i) for i in range(5)]
               + [record(5, matrices={"K": [[1.0, 2.0], [3.0]]})], 2)
    with pytest.raises(ResultsUnreadableError, match=f"{path}: column matrices holds"):
        fill_columns(lazy, ["matrices"])


def test_results_files_are_written_in_row_groups_a_lazy_reader_reads_one_at_a_time(
        tmp_path, monkeypatch):
    """write_table_atomic cuts a results file into row groups of ROW_GROUP_ROWS rows; a
    lazily read frame's batches are whole groups, and reading them gives every value."""
    from penaltyrun.io import schema

    monkeypatch.setattr(schema, "ROW_GROUP_ROWS", 3)
    records = [record(s) for s in range(8)]
    table = pa.Table.from_pylist([normalize(r, "run") for r in records], schema=SCHEMA)
    path = schema.write_table_atomic(table, tmp_path / RESULTS_FILE)
    meta = pq.read_metadata(path)
    assert [meta.row_group(i).num_rows for i in range(meta.num_row_groups)] == [3, 3, 2]
    frame = read.read_results(path, ("job_id", "status", "best_cost"), lazy=True)
    shuffled = frame.iloc[[7, 0, 4, 2, 5]]
    batches = list(lazy.read_batches(shuffled, 1))
    assert [sorted(shuffled[ROW].to_numpy()[b]) for b in batches] == [[0, 2], [4, 5], [7]]
    joined = list(lazy.read_batches(shuffled, 3))  # whole groups, until 3 rows or more
    assert [sorted(shuffled[ROW].to_numpy()[b]) for b in joined] == [[0, 2, 4, 5], [7]]
    filled = fill_columns(shuffled.iloc[batches[1]], ("matrices",))
    assert [json.loads(m)["K"][0][0] for m in filled["matrices"]] == [5.0, 6.0]


def test_a_lazy_read_checks_the_columns_a_read_whole_of_the_same_columns_checks(tmp_path):
    """Damage in a column the caller never reads (``history`` here) refuses the file in
    neither read when the caller names its columns, and in both by default."""
    write_file(tmp_path / "d", [record(i) for i in range(3)]
               + [record(3, history=[1.0, float("-inf")])], 2)
    used = [c for c in read.COLUMNS if c != "history"]
    assert len(read.read_results(tmp_path, used)) == 4
    assert len(read.read_results(tmp_path, lazy=True, checked=used)) == 4
    from penaltyrun.errors import ResultsUnreadableError

    for kwargs in ({}, {"lazy": True}):
        with pytest.raises(ResultsUnreadableError, match="no readable results"):
            read.read_results(tmp_path, **kwargs)
