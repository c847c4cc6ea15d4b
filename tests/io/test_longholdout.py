"""A re-judged held-out file beside a results file replaces the stored held-out data."""

from __future__ import annotations

import json
import logging

import pandas as pd
import pyarrow.parquet as pq
import pytest

from penaltyrun.errors import ResultsUnreadableError
from penaltyrun.io.longholdout import LONG_FILE
from penaltyrun.io.schema import read_results, to_table


def _records() -> list[dict]:
    return [{"job_id": f"j{k}", "problem": "zermelo", "case": "default", "param": "diagonal",
             "optimizer": "pso", "start": k, "seed": k, "status": "ok", "best_cost": 1.0 + k,
             "best_converged": True, "holdout": {"cost": [1.0], "converged": [False]}}
            for k in range(3)]


def test_long_file_is_read_in_preference_and_left_out_jobs_carry_none(tmp_path):
    path = tmp_path / "results.parquet"
    pq.write_table(to_table(_records(), run_id="r"), path)
    stored = read_results(path)
    assert stored["holdout"].notna().all()
    new = json.dumps({"cost": [2.0], "converged": [True], "horizon": 10.0})
    pd.DataFrame({"job_id": ["j0", "j2"], "config_hash": list(stored["config_hash"].iloc[[0, 2]]),
                  "holdout": [new, new], "status": ["ok", "ok"],
                  "wall_time_s": [0.1, 0.1]}).to_parquet(tmp_path / LONG_FILE)
    df = read_results(path).set_index("job_id")
    assert json.loads(df.loc["j0", "holdout"])["horizon"] == 10.0
    assert json.loads(df.loc["j2", "holdout"])["horizon"] == 10.0
    assert pd.isna(df.loc["j1", "holdout"])
    assert (df["best_cost"].to_numpy() == [1.0, 2.0, 3.0]).all()


@pytest.mark.parametrize("holdout, words", [
    ("{nope", "not usable JSON"),
    ("[" * 100_000 + "]" * 100_000, "nested too deep"),
    (json.dumps({"cost": "cheap", "converged": [1, 2]}), "held-out costs that are not")])
def test_b8_a_damaged_long_file_is_skipped_and_the_stored_held_out_data_reported(
        tmp_path, caplog, holdout, words):
    path = tmp_path / "results.parquet"
    pq.write_table(to_table(_records(), run_id="r"), path)
    stored = read_results(path)
    pd.DataFrame({"job_id": ["j0"], "config_hash": [stored["config_hash"].iloc[0]],
                  "holdout": [holdout], "status": ["ok"],
                  "wall_time_s": [0.1]}).to_parquet(tmp_path / LONG_FILE)
    with caplog.at_level(logging.WARNING):
        df = read_results(path)
    assert df["holdout"].tolist() == stored["holdout"].tolist()
    lines = [r.getMessage() for r in caplog.records if LONG_FILE in r.getMessage()]
    assert len(lines) == 1 and "skipped re-judged held-out file" in lines[0]
    assert words in lines[0]


@pytest.mark.parametrize("lazy", [False, True])
def test_beside_a_usable_long_file_the_stored_held_out_column_is_neither_read_nor_checked(
        tmp_path, caplog, lazy):
    """The stored held-out data are replaced, so a damaged stored column (converged flags
    given as text) costs nothing there; without the re-judged file the same results file
    is skipped with one warning."""
    from penaltyrun.io.lazy import fill_columns
    from penaltyrun.io.read import read_results as read_whole_or_lazy

    records = _records()
    for record in records:
        record["holdout"] = {"cost": [1.0], "converged": ["yes"]}
    path = tmp_path / "results.parquet"
    pq.write_table(to_table(records, run_id="r"), path)
    with caplog.at_level(logging.WARNING):
        with pytest.raises(ResultsUnreadableError):
            read_whole_or_lazy(path, lazy=lazy)
    assert any("skipped" in r.getMessage() for r in caplog.records)
    hashes = pq.read_table(path, columns=["config_hash"]).column(0).to_pylist()
    new = json.dumps({"cost": [2.0], "converged": [True], "horizon": 10.0})
    pd.DataFrame({"job_id": ["j0", "j1", "j2"], "config_hash": hashes,
                  "holdout": [new] * 3, "status": ["ok"] * 3,
                  "wall_time_s": [0.1] * 3}).to_parquet(tmp_path / LONG_FILE)
    df = read_whole_or_lazy(path, lazy=lazy, sources=lazy)
    if lazy:
        assert "holdout" not in df
        df = fill_columns(df, ["holdout"])
    assert [json.loads(h)["horizon"] for h in df["holdout"]] == [10.0] * 3
    assert df["best_cost"].tolist() == [1.0, 2.0, 3.0]
