"""Columns added by a schema version: their type, and that files written before them read
back with the columns empty (schema 8: the anytime trace's CPU seconds; schema 9: what exact
gradients were charged)."""

from __future__ import annotations

import json

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from penaltyrun.io.schema import (
    COLUMNS,
    RESULTS_FILE,
    SCHEMA,
    SCHEMA_HISTORY,
    SCHEMA_VERSION,
    collect,
    normalize,
    read_results,
)
from penaltyrun.runner.records import write_text_atomic

#: version → (the columns it added with their Arrow type, values a record gives them)
ADDED = {
    8: ({"trace_cpu_s": pa.list_(pa.float64())}, {"trace_cpu_s": [0.01, 0.25, 0.5]}),
    9: ({"n_gradients": pa.int64(), "grad_cost": pa.float64()},
        {"n_gradients": 8, "grad_cost": 2.5}),
}


def record(start: int, **extra) -> dict:
    return {"job_id": f"lqr-default-givens-lbfgs-abc-s{start:03d}", "problem": "lqr",
            "case": "default", "param": "givens", "optimizer": "lbfgs", "start": start,
            "seed": start, "status": "ok", "best_cost": 2.0, "n_evals": 30,
            "config_hash": "h1", "trace_evals": [1, 12, 30], "trace_best": [9.0, 3.0, 2.0],
            **extra}


def _empty(value) -> bool:
    """A missing value as pandas reads it: None (list columns) or NaN / NA (scalars)."""
    return value is None or (pd.api.types.is_scalar(value) and pd.isna(value))


@pytest.mark.parametrize("version", sorted(ADDED))
def test_the_added_columns_belong_to_their_schema_version(version):
    types, _ = ADDED[version]
    assert SCHEMA_VERSION >= version
    for name, kind in types.items():
        assert name in SCHEMA_HISTORY[version] and COLUMNS[name][0] == kind


def test_what_the_columns_mean():
    assert "time.process_time" in COLUMNS["trace_cpu_s"][1]
    assert "grad_cost × n_gradients" in COLUMNS["n_evals"][1]


@pytest.mark.parametrize("version", sorted(ADDED))
def test_the_columns_round_trip_and_older_files_read_back_without_them(tmp_path, version):
    types, values = ADDED[version]
    (tmp_path / "new" / "jobs").mkdir(parents=True)
    rec = record(0, **values)
    write_text_atomic(tmp_path / "new" / "jobs" / f"{rec['job_id']}.json", json.dumps(rec))
    collect(tmp_path / "new")
    old = pa.Table.from_pylist([normalize(record(1), "old")], schema=SCHEMA)
    old = old.drop_columns(list(types))
    old = old.set_column(old.schema.get_field_index("schema_version"), "schema_version",
                         pa.array([version - 1]))
    (tmp_path / "old").mkdir()
    pq.write_table(old, tmp_path / "old" / RESULTS_FILE)
    df = read_results(tmp_path).sort_values("start")
    for name, value in values.items():
        got = df[name].iloc[0]
        assert (list(got) if isinstance(value, list) else got) == value
        assert _empty(df[name].iloc[1])
    assert df["schema_version"].tolist() == [SCHEMA_VERSION, version - 1]
