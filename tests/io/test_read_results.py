"""Reading results back: each job once, foreign and newer files skipped, unknown statuses
marked, every record with its package versions."""

import json
import logging
import shutil

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from penaltyrun.io import read
from penaltyrun.io.schema import (
    COLUMNS,
    RESULTS_FILE,
    SCHEMA,
    SCHEMA_VERSION,
    collect,
    normalize,
    read_results,
)
from penaltyrun.runner.records import write_text_atomic


def record(start=0, **overrides):
    rec = {"job_id": f"zermelo-default-full-pso-abc-s{start:03d}", "problem": "zermelo",
           "case": "default", "param": "full", "optimizer": "pso", "start": start,
           "seed": start, "status": "ok", "best_cost": 1.0 + start, "n_evals": 10,
           "config_hash": "h1"}
    rec.update(overrides)
    return rec


def write_run(run, records):
    (run / "jobs").mkdir(parents=True)
    for r in records:
        write_text_atomic(run / "jobs" / f"{r['job_id']}.json", json.dumps(r))
    return collect(run)


def test_a_copy_of_a_run_is_counted_once(tmp_path, caplog):
    write_run(tmp_path / "run", [record(0), record(1)])
    shutil.copytree(tmp_path / "run", tmp_path / "backup")
    write_run(tmp_path / "other", [record(0, config_hash="h2")])  # another config: kept
    df = read_results(tmp_path)
    assert len(df) == 3
    assert sorted(df["config_hash"]) == ["h1", "h1", "h2"]
    assert "left out 2 duplicate rows" in caplog.text
    assert str(tmp_path / "run" / RESULTS_FILE) in caplog.text  # the file kept is named
    assert str(tmp_path / "backup" / RESULTS_FILE) in caplog.text


def test_foreign_and_newer_files_are_skipped_with_a_warning(tmp_path, caplog):
    write_run(tmp_path / "good", [record(0)])
    (tmp_path / "foreign").mkdir()
    pq.write_table(pa.table({"x": [1, 2]}), tmp_path / "foreign" / RESULTS_FILE)
    rows = [normalize(record(1), "new")]
    rows[0]["schema_version"] = SCHEMA_VERSION + 1
    (tmp_path / "newer").mkdir()
    pq.write_table(pa.Table.from_pylist(rows, schema=SCHEMA), tmp_path / "newer" / RESULTS_FILE)
    (tmp_path / "dir" / RESULTS_FILE).mkdir(parents=True)  # a directory of that name
    df = read_results(tmp_path)
    assert list(df["start"]) == [0]
    assert "not penaltyrun results" in caplog.text and "foreign" in caplog.text
    assert f"unknown schema version {SCHEMA_VERSION + 1}" in caplog.text
    assert set(df.attrs["skipped_files"]) == {str(tmp_path / "foreign" / RESULTS_FILE),
                                              str(tmp_path / "newer" / RESULTS_FILE)}


def test_column_types_are_checked(tmp_path, caplog):
    def write(name, n_evals):
        rows = [normalize(record(i), name) for i in range(len(n_evals))]
        schema = pa.schema([pa.field(n, pa.float64() if n == "n_evals" else SCHEMA.field(n).type)
                            for n in COLUMNS])
        for row, n in zip(rows, n_evals):
            row["n_evals"] = n
        (tmp_path / name).mkdir()
        pq.write_table(pa.Table.from_pylist(rows, schema=schema), tmp_path / name / RESULTS_FILE)

    write("integral", [10.0, 20.0])
    write("fractional", [10.5])
    df = read_results(tmp_path)
    assert df["n_evals"].tolist() == [10, 20] and df["n_evals"].dtype == "int64"
    assert "column n_evals" in caplog.text and "fractional" in caplog.text


def test_unknown_statuses_are_marked_not_counted(tmp_path, caplog):
    rows = [normalize(record(0), "r"), normalize(record(1, status="skipped"), "r")]
    (tmp_path / "r").mkdir()
    pq.write_table(pa.Table.from_pylist(rows, schema=SCHEMA), tmp_path / "r" / RESULTS_FILE)
    df = read_results(tmp_path)
    assert df["status_known"].tolist() == [True, False]
    assert df.attrs["unknown_statuses"] == {"skipped": 1}
    assert "'skipped': 1" in caplog.text


def test_records_carry_their_package_versions_and_old_files_still_read(tmp_path):
    from penaltyrun.runner import plan_jobs
    from penaltyrun.runner.records import write_record

    job = plan_jobs("zermelo", "default", "full", "pso", n_starts=1, root_seed=3)[0]
    write_record(tmp_path / "new", job, {**record(0, job_id=job.job_id), "git_commit": "abc"})
    collect(tmp_path / "new")
    old = pa.Table.from_pylist([normalize(record(1), "old")], schema=SCHEMA)
    old = old.drop_columns(["packages"]).set_column(
        list(COLUMNS).index("schema_version") - 1, "schema_version", pa.array([4]))
    (tmp_path / "old").mkdir()
    pq.write_table(old, tmp_path / "old" / RESULTS_FILE)
    df = read_results(tmp_path).sort_values("start")
    packages = json.loads(df["packages"].iloc[0])
    assert {"python", "numpy", "scipy", "numba", "pyswarms", "pandas", "pyarrow",
            "penaltyrun"} <= set(packages)
    assert packages["git_commit"] == "abc"
    assert pd.isna(df["packages"].iloc[1]) and df["schema_version"].tolist() == \
        [SCHEMA_VERSION, 4]


def test_many_files_show_progress(tmp_path, caplog, monkeypatch):
    monkeypatch.setattr(read, "PROGRESS_MIN_FILES", 3)
    monkeypatch.setattr(read, "PROGRESS_LOG_S", 0.0)
    for i in range(4):
        write_run(tmp_path / f"r{i}", [record(i)])
    with caplog.at_level(logging.INFO, logger="penaltyrun.io.read"):
        assert len(read_results(tmp_path)) == 4
    assert "reading 4 results files" in caplog.text and "read 4 of 4" in caplog.text


def test_collect_quarantines_invalid_records(tmp_path, caplog):
    run = tmp_path / "run"
    bad = record(1, best_cost="abc")
    df = read_results(write_run(run, [record(0), bad, record(2, best_cost=float("nan"))]))
    assert df["start"].tolist() == [0]
    assert "best_cost must be a number" in caplog.text and "best_cost is NaN" in caplog.text
    assert len(list((run / "jobs" / "corrupt").iterdir())) == 2


@pytest.mark.parametrize("only", [{"status": "ok"}])
def test_status_only_record_never_reaches_the_table(tmp_path, only):
    run = tmp_path / "run"
    (run / "jobs").mkdir(parents=True)
    (run / "jobs" / "x.json").write_text(json.dumps(only))
    assert len(read_results(collect(run))) == 0


def test_interrupted_run_is_read_from_its_records(tmp_path, caplog):
    """A run stopped before it wrote results.parquet: its finished records are read, with
    one warning naming runner.resume=true; a finished run beside it is read as usual."""
    write_run(tmp_path / "done", [record(0, config_hash="h0")])
    jobs = tmp_path / "stopped" / "jobs"
    jobs.mkdir(parents=True)
    for r in (record(0), record(1)):
        write_text_atomic(jobs / f"{r['job_id']}.json", json.dumps(r))
    (jobs / "half.json").write_text('{"job_id": ')
    (jobs / "corrupt").mkdir()
    (jobs / "corrupt" / "old.json").write_text(json.dumps(record(5)))
    assert read.unfinished_runs(tmp_path) == [tmp_path / "stopped"]
    with caplog.at_level(logging.WARNING):
        df = read_results(tmp_path)
    assert sorted(df["start"]) == [0, 0, 1] and set(df["run_id"]) == {"done", "stopped"}
    said = [r.getMessage() for r in caplog.records if "no results.parquet" in r.getMessage()]
    assert len(said) == 1 and "2 finished job records" in said[0]
    assert "runner.resume=true" in said[0]
    assert any("half.json" in r.getMessage() for r in caplog.records)
    assert (jobs / "half.json").exists()  # named, never moved: the run may still be going
    assert len(read_results(tmp_path / "stopped")) == 2


def test_records_that_are_all_unusable_are_no_results(tmp_path):
    (tmp_path / "run" / "jobs").mkdir(parents=True)
    (tmp_path / "run" / "jobs" / "x.json").write_text("garbage")
    with pytest.raises(read.ResultsUnreadableError, match="no readable results"):
        read_results(tmp_path)


def test_only_the_asked_columns_are_read(tmp_path, monkeypatch):
    path = write_run(tmp_path / "run", [record(0, history=[3.0, 2.0]), record(1)])
    read_columns = []
    real = pq.read_table
    monkeypatch.setattr(read.pq, "read_table",
                        lambda *a, **k: read_columns.append(k.get("columns")) or real(*a, **k))
    df = read_results(path, columns=["best_cost"])
    assert set(df.columns) == {*read.KEEP_COLUMNS, "best_cost", read.STATUS_KNOWN}
    assert "history" not in read_columns[0] and "best_cost" in read_columns[0]
    assert df["best_cost"].tolist() == [1.0, 2.0]
    full = read_results(path)
    pd.testing.assert_frame_equal(df, full[df.columns])
    interrupted = tmp_path / "open"
    (interrupted / "jobs").mkdir(parents=True)
    write_text_atomic(interrupted / "jobs" / f"{record(5)['job_id']}.json",
                      json.dumps(record(5)))
    assert set(read_results(interrupted, columns=["n_evals"]).columns) == {
        *read.KEEP_COLUMNS, "n_evals", read.STATUS_KNOWN}
    with pytest.raises(ValueError, match="not results columns: nope"):
        read_results(path, columns=["nope"])
