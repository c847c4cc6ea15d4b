"""Report row helpers: :func:`penaltyrun.report.rows.groups` iterates like a pandas
groupby without holding a sorted copy of the frame; a lazily read frame's per-row columns
are read in batches with the values a frame read whole holds."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun.report import rows
from penaltyrun.report.rows import groups

KEYS = ["problem", "case", "variant"]


def _frame(codes: list[tuple[int, int, int]], categorical: bool) -> pd.DataFrame:
    names = (["b", "a", None], ["x", "y"], ["", "v=1", "v=2"])
    df = pd.DataFrame({key: [names[i][c[i]] for c in codes] for i, key in enumerate(KEYS)})
    df["value"] = np.arange(len(df), dtype=float)
    if categorical:  # categories out of lexical order: groupby sorts by category order
        df["problem"] = pd.Categorical(df["problem"], categories=["b", "a"])
    return df


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 2), st.integers(0, 1), st.integers(0, 2)),
                max_size=40), st.booleans())
def test_groups_equal_a_sorted_pandas_groupby(codes, categorical):
    """Same keys in the same order, same rows in the same order (a missing key is left
    out, as pandas does), for object and categorical key columns."""
    df = _frame(codes, categorical)
    expected = [(key, g) for key, g in df.groupby(KEYS, sort=True, observed=True)]
    got = list(groups(df, KEYS))
    assert [key for key, _ in got] == [key for key, _ in expected]
    for (_, a), (_, b) in zip(got, expected):
        pd.testing.assert_frame_equal(a, b)


def test_groups_of_an_empty_frame_yield_nothing():
    assert list(groups(_frame([], False), KEYS)) == []


GOLDEN_INPUT = Path(__file__).parent / "golden" / "two_studies" / "input"


def _read_both() -> tuple[pd.DataFrame, pd.DataFrame]:
    from penaltyrun.io.read import read_results
    from penaltyrun.report.rows import FRAME_COLUMNS, REPORT_COLUMNS

    return (read_results(GOLDEN_INPUT, REPORT_COLUMNS),
            read_results(GOLDEN_INPUT, FRAME_COLUMNS, lazy=True))


def test_batches_of_a_lazy_frame_are_its_files_row_groups(tmp_path):
    """One batch per row group of each file, each group's rows in file order with the
    columns read; together every row with the values of a frame read whole; a frame read
    whole is one batch."""
    from penaltyrun.io.filecheck import ROW, SOURCE

    whole, lazy = _read_both()
    parts = list(rows.batches(lazy, ("holdout", "matrices")))
    joined = pd.concat(parts)
    assert sorted(joined.index) == sorted(lazy.index)
    assert joined["matrices"].reindex(whole.index).tolist() == whole["matrices"].tolist()
    for part in parts:
        assert part[SOURCE].nunique() == 1 and part[ROW].is_monotonic_increasing
    assert [len(p) for p in rows.batches(whole, ("holdout",))] == [len(whole)]


def test_a_file_of_several_row_groups_is_read_a_group_at_a_time(tmp_path, monkeypatch):
    """Rows asked for in any order: batches of whole row groups (no group split between
    two, so each is read once), in file order, joined until a batch holds BATCH_ROWS
    rows; each row with its own values."""
    import pyarrow.parquet as pq

    from penaltyrun.io.read import ROW, read_results
    from penaltyrun.report.rows import FRAME_COLUMNS

    sys.path.insert(0, str(Path(__file__).parent))
    from large_results import write_large_results

    src = write_large_results(tmp_path / "r", 30)
    table = pq.read_table(src)
    pq.write_table(table, src, row_group_size=7)  # groups of 7, 7, 7, 7, 2 rows
    lazy = read_results(src, FRAME_COLUMNS, lazy=True).sample(frac=1, random_state=0)
    lazy = lazy.iloc[3:]
    expected = table.column("matrices").to_pylist()
    for batch_rows in (1, 12):
        monkeypatch.setattr(rows, "BATCH_ROWS", batch_rows)
        parts = list(rows.batches(lazy, ("matrices",)))
        groups = [sorted(set(p[ROW] // 7)) for p in parts]
        flat = [g for gs in groups for g in gs]
        assert flat == sorted({int(r) // 7 for r in lazy[ROW]})  # each once, file order
        assert all(len(p) >= batch_rows for p in parts[:-1])
        if batch_rows == 1:
            assert all(len(g) == 1 for g in groups)
        joined = pd.concat(parts)
        assert sorted(joined.index) == sorted(lazy.index)
        assert all(m == expected[r] for m, r in zip(joined["matrices"], joined[ROW]))


def test_present_reads_in_batches_what_a_whole_frame_holds():
    whole, lazy = _read_both()
    assert whole["holdout"].notna().any() and whole["holdout"].isna().any()
    assert rows.present(lazy, "holdout").tolist() == whole["holdout"].notna().tolist()
    assert rows.present(lazy.iloc[:0], "holdout").empty


def test_the_best_held_out_start_is_the_same_read_lazily_in_batches():
    """holdout.best_start ranks converged starts first, then by cost, and reads the
    held-out data batch by batch until a start has them: the start of a frame read whole."""
    from penaltyrun.report import holdout

    whole, lazy = _read_both()
    keys = ["problem", "case", "param", "optimizer"]
    picked = 0
    for key, g in whole.groupby(keys, sort=True):
        a = holdout.best_start(g)
        b = holdout.best_start(lazy.loc[g.index])
        assert (a is None) == (b is None), key
        if a is not None:
            assert a["job_id"] == b["job_id"] and a["holdout"] == b["holdout"], key
            picked += 1
    assert picked >= 4
