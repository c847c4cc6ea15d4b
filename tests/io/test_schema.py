"""The Parquet results schema: normalization, collect, read back."""

from __future__ import annotations

import json
import logging
import math
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from penaltyrun.io import (
    COLUMNS,
    RESULTS_FILE,
    SCHEMA,
    collect,
    decode_json,
    find_results,
    read_results,
    to_table,
)
from penaltyrun.io.schema import JSON_COLUMNS, SCHEMA_VERSION, normalize


def record(start=0, **overrides):
    rec = {
        "job_id": f"zermelo-default-geagsp-pso-s{start:03d}",
        "problem": "zermelo", "case": "default", "param": "geagsp", "optimizer": "pso",
        "start": start, "seed": 1000 + start, "status": "ok", "error": None,
        "best_cost": 1.5 + start, "best_converged": True, "best_status": "converged",
        "t_final": 2.0, "best_z": [0.1 * start, 0.2, 0.3], "z_names": ["K.lam1", "K.lam2",
                                                                        "K.ang1"],
        "matrices": {"K": [[1.0, 0.5], [0.5, 2.0]]}, "scalars": {},
        "metrics": {"miss": 1e-6, "steps": 120}, "n_evals": 300, "n_iters": 10,
        "stop_reason": "ftol", "n_nonfinite": 0, "history": [3.0, 2.0, 1.5 + start],
        "wall_time_s": 0.25, "optimizer_settings": {"n_particles": 30},
        "problem_params": {}, "param_options": {"eig_bounds": [0.1, 10.0]},
        "config_hash": "abc", "config": "a: 1\n", "package_version": "0.1.0",
        "git_commit": "unknown", "started_at": "2026-01-01T00:00:00",
        "finished_at": "2026-01-01T00:00:01",
    }
    rec.update(overrides)
    return rec


def write_run(run_dir, records):
    jobs = run_dir / "jobs"
    jobs.mkdir(parents=True)
    for r in records:
        (jobs / f"{r['job_id']}.json").write_text(json.dumps(r))
    return collect(run_dir)


# --------------------------------------------------------------------------- normalize


def test_normalize_fills_missing_fields_and_serializes_json():
    row = normalize({"job_id": "j", "metrics": {"a": [1, 2]}, "scalars": '{"x": 1}',
                     "unknown_field": 5}, run_id="run1")
    assert list(row) == list(COLUMNS)
    assert row["run_id"] == "run1"
    assert row["schema_version"] == SCHEMA_VERSION
    assert row["best_cost"] is None and row["history"] is None
    assert "unknown_field" not in row
    assert isinstance(row["metrics"], str)
    assert json.loads(row["metrics"]) == {"a": [1, 2]}
    assert row["scalars"] == '{"x": 1}'  # already text: kept as is


def test_normalize_keeps_record_run_id_and_stringifies_odd_values():
    row = normalize({"run_id": "own", "metrics": {"path": Path("/x")}},
                    run_id="other")
    assert row["run_id"] == "own"
    assert json.loads(row["metrics"]) == {"path": "/x"}


def test_to_table_has_the_schema():
    table = to_table([record(0), {"job_id": "bare"}], run_id="r")
    assert table.schema.equals(SCHEMA)
    assert table.num_rows == 2
    rows = table.to_pylist()
    assert rows[1]["best_cost"] is None and rows[1]["run_id"] == "r"
    assert rows[0]["best_z"] == [0.0, 0.2, 0.3]
    for col in JSON_COLUMNS:
        assert table.schema.field(col).type == SCHEMA.field(col).type


def test_to_table_empty():
    table = to_table([])
    assert table.num_rows == 0 and table.schema.equals(SCHEMA)


# --------------------------------------------------------------------------- collect / read


def test_collect_and_read_back_file_and_folder(tmp_path):
    run = tmp_path / "run_a"
    path = write_run(run, [record(0), record(1, status="failed", best_cost=None,
                                              history=[], error="boom")])
    assert path == run / RESULTS_FILE and path.exists()
    assert pq.read_schema(path).equals(SCHEMA)
    for source in (path, run, str(run)):
        df = read_results(source)
        assert len(df) == 2
        assert list(df.columns) == [*COLUMNS, "status_known"]
    df = read_results(path).sort_values("start").reset_index(drop=True)
    assert (df["run_id"] == "run_a").all()
    assert df.loc[0, "best_cost"] == 1.5
    assert math.isnan(df.loc[1, "best_cost"])
    assert df.loc[1, "error"] == "boom"
    # list columns survive as sequences with the original values
    np.testing.assert_allclose(list(df.loc[0, "best_z"]), [0.0, 0.2, 0.3])
    assert list(df.loc[0, "z_names"]) == ["K.lam1", "K.lam2", "K.ang1"]
    np.testing.assert_allclose(list(df.loc[0, "history"]), [3.0, 2.0, 1.5])
    assert len(df.loc[1, "history"]) == 0
    # JSON columns stay text and decode to the original objects
    assert decode_json(df.loc[0, "matrices"]) == {"K": [[1.0, 0.5], [0.5, 2.0]]}
    assert decode_json(df.loc[0, "metrics"]) == {"miss": 1e-6, "steps": 120}
    assert decode_json(df.loc[0, "param_options"]) == {"eig_bounds": [0.1, 10.0]}
    assert df.loc[0, "start"] == 0 and df.loc[1, "start"] == 1
    assert df["schema_version"].tolist() == [SCHEMA_VERSION] * 2


def test_collect_only_the_planned_jobs(tmp_path):
    run = tmp_path / "run"
    write_run(run, [record(0), record(1), record(2, job_id="zermelo-other-settings-s000")])
    planned = [record(0)["job_id"], record(1)["job_id"], "not-run-yet"]
    df = read_results(collect(run, planned))
    assert sorted(df["job_id"]) == sorted(planned[:2])
    assert (run / "jobs" / "zermelo-other-settings-s000.json").exists()  # nothing deleted
    assert len(read_results(collect(run))) == 3


def test_nonfinite_floats_survive(tmp_path):
    run = tmp_path / "r"
    write_run(run, [record(0, status="diverged", best_cost=float("inf"),
                           history=[float("nan"), 1.0])])
    df = read_results(run)
    assert df.loc[0, "best_cost"] == float("inf")
    h = list(df.loc[0, "history"])
    assert math.isnan(h[0]) and h[1] == 1.0


def test_several_run_folders_concatenated(tmp_path):
    write_run(tmp_path / "multirun" / "r1", [record(0), record(1)])
    write_run(tmp_path / "multirun" / "r2",
              [record(0, param="diagonal", job_id="zermelo-default-diagonal-pso-s000")])
    (tmp_path / "multirun" / "r3" / "jobs").mkdir(parents=True)  # not collected: ignored
    found = find_results(tmp_path)
    assert [p.parent.name for p in found] == ["r1", "r2"]
    df = read_results(tmp_path)
    assert len(df) == 3
    assert sorted(df["run_id"]) == ["r1", "r1", "r2"]
    assert set(df.loc[df["run_id"] == "r2", "param"]) == {"diagonal"}
    # explicit list of files
    df2 = read_results(found)
    assert len(df2) == 3


def test_a_results_file_that_is_a_pipe_or_folder_is_skipped_with_its_name(tmp_path, caplog):
    write_run(tmp_path / "ok", [record(0)])
    (tmp_path / "pipe").mkdir()
    os.mkfifo(tmp_path / "pipe" / RESULTS_FILE)  # opening it to read would block
    (tmp_path / "dir" / RESULTS_FILE).mkdir(parents=True)
    with caplog.at_level(logging.WARNING):
        assert find_results(tmp_path) == [tmp_path / "ok" / RESULTS_FILE]
        assert find_results(tmp_path / "pipe" / RESULTS_FILE) == []
    skipped = [r.getMessage() for r in caplog.records if "not a regular file" in r.getMessage()]
    assert len(skipped) == 3 and all(RESULTS_FILE in m for m in skipped)


def test_collect_without_jobs_writes_empty_table(tmp_path):
    run = tmp_path / "empty_run"
    (run / "jobs").mkdir(parents=True)
    path = collect(run)
    df = read_results(path)
    assert len(df) == 0 and list(df.columns) == [*COLUMNS, "status_known"]


def test_read_results_on_empty_folder(tmp_path):
    with pytest.raises(FileNotFoundError, match=RESULTS_FILE):
        read_results(tmp_path)
    with pytest.raises(FileNotFoundError):
        read_results([])


def test_decode_json():
    assert decode_json(None) is None
    assert decode_json("") is None
    assert decode_json('{"a": [1, 2]}') == {"a": [1, 2]}


# --------------------------------------------------------------------------- timestamps


def test_times_are_timestamp_columns(tmp_path):
    run = tmp_path / "run"
    write_run(run, [record(0, started_at="2026-03-01T10:00:00.250000+00:00",
                           finished_at="2026-03-01T12:00:01+02:00"),
                    record(1, started_at="not a time", finished_at=None)])
    schema = pq.read_schema(run / RESULTS_FILE)
    for name in ("started_at", "finished_at"):
        assert schema.field(name).type == pa.timestamp("us", tz="UTC")
    df = read_results(run).sort_values("start").reset_index(drop=True)
    assert isinstance(df["started_at"].dtype, pd.DatetimeTZDtype)
    assert df.loc[0, "started_at"] == pd.Timestamp("2026-03-01T10:00:00.25", tz="UTC")
    assert df.loc[0, "finished_at"] == pd.Timestamp("2026-03-01T10:00:01", tz="UTC")
    assert pd.isna(df.loc[1, "started_at"]) and pd.isna(df.loc[1, "finished_at"])
    wall = (df.loc[0, "finished_at"] - df.loc[0, "started_at"]).total_seconds()
    assert wall == pytest.approx(0.75)


def test_schema_2_files_with_text_times_are_read_as_timestamps(tmp_path):
    old_schema = pa.schema([pa.field(n, pa.string() if n in ("started_at", "finished_at")
                                     else SCHEMA.field(n).type) for n in COLUMNS])
    rows = [normalize(record(0), run_id="old")]
    rows[0].update({"started_at": "2025-12-31T23:59:59+00:00",
                    "finished_at": "2026-01-01T00:00:01", "schema_version": 2})
    (tmp_path / "old").mkdir()
    pq.write_table(pa.Table.from_pylist(rows, schema=old_schema),
                   tmp_path / "old" / RESULTS_FILE)
    write_run(tmp_path / "new", [record(1)])
    df = read_results(tmp_path).sort_values("start").reset_index(drop=True)
    assert isinstance(df["started_at"].dtype, pd.DatetimeTZDtype)
    assert df["schema_version"].tolist() == [2, SCHEMA_VERSION]
    assert df.loc[0, "started_at"] == pd.Timestamp("2025-12-31T23:59:59", tz="UTC")
    assert df.loc[0, "finished_at"] == pd.Timestamp("2026-01-01T00:00:01", tz="UTC")
    assert df.loc[1, "started_at"] == pd.Timestamp("2026-01-01T00:00:00", tz="UTC")


def test_pso_matlab_records_from_before_the_reading_settings_say_page(tmp_path):
    old = {"swarm_size": None, "inertia_update": "every_iteration"}
    new = {**old, "neighbourhood": "with_self", "stall_test": "code"}
    write_run(tmp_path / "r", [
        record(0, optimizer="pso_matlab", optimizer_settings=old),
        record(1, optimizer="pso_matlab", optimizer_settings=new),
        record(2, optimizer="pso", optimizer_settings={"n_particles": 30})])
    settings = [decode_json(s) for s in read_results(tmp_path / "r")
                .sort_values("start")["optimizer_settings"]]
    assert settings[0] == {**old, "neighbourhood": "others", "stall_test": "page"}
    assert settings[1] == new
    assert settings[2] == {"n_particles": 30}


def test_decode_json_treats_every_missing_value_as_none():
    """Concatenating frames of which only some have a JSON column leaves NaN in the others."""
    import pandas as pd
    frame = pd.concat([pd.DataFrame({"a": [1]}), pd.DataFrame({"a": [2], "holdout": ['{"x": 1}']})],
                      ignore_index=True)
    assert decode_json(frame.loc[0, "holdout"]) is None
    assert decode_json(frame.loc[1, "holdout"]) == {"x": 1}
    assert decode_json(None) is None and decode_json("") is None


# --------------------------------------------------------------------------- schema 6


REPO = Path(__file__).resolve().parents[2]
CL_COLUMNS = ("closed_loop", "cl_eig_real", "cl_eig_imag", "cl_slowest_real",
              "cl_min_damping", "cl_gain_norm", "cl_gain_cond")


def test_closed_loop_columns_round_trip(tmp_path):
    loop = {"time": "continuous", "dt": None, "matrix": [[-1.0, -0.5], [-0.5, -2.0]],
            "gain": [[1.0, 0.5], [0.5, 2.0]], "state_names": ["x", "y"],
            "input_names": ["u1", "u2"]}
    rec = record(closed_loop=loop, cl_eig_real=[-0.79, -2.21], cl_eig_imag=[0.0, 0.0],
                 cl_slowest_real=-0.79, cl_min_damping=1.0, cl_gain_norm=2.21,
                 cl_gain_cond=math.inf)
    df = read_results(write_run(tmp_path / "run", [rec, record(start=1)]))
    first, second = df.iloc[0], df.iloc[1]
    assert decode_json(first["closed_loop"]) == loop
    assert list(first["cl_eig_real"]) == [-0.79, -2.21]
    assert first["cl_slowest_real"] == -0.79 and first["cl_gain_cond"] == math.inf
    assert decode_json(second["closed_loop"]) is None and math.isnan(second["cl_slowest_real"])
    assert int(first["schema_version"]) == SCHEMA_VERSION


def test_committed_study_of_an_older_schema_reads_with_null_diagnostics():
    path = REPO / "studies" / "referee_zermelo" / "results.parquet"
    raw = pq.read_table(path)
    assert max(v for v in raw.column("schema_version").to_pylist() if v is not None) \
        < SCHEMA_VERSION
    df = read_results(path)
    assert len(df) == raw.num_rows and not df.attrs["skipped_files"]
    for name in CL_COLUMNS:
        assert df[name].isna().all()
    old = raw.to_pandas()
    pd.testing.assert_series_equal(df["best_cost"], old["best_cost"], check_names=False)
    assert list(df["job_id"]) == list(old["job_id"])


def test_a_time_that_leaves_the_calendar_in_utc_is_stored_as_null(caplog):
    """0001-01-01T00:00:00+01:00 is before year 1 in UTC: one warning and null, not an
    OverflowError that stopped every later write of the run's results."""
    from penaltyrun.io.schema import to_timestamp

    with caplog.at_level("WARNING"):
        assert to_timestamp("0001-01-01T00:00:00+01:00") is None
    assert "out of range" in caplog.text
    assert to_timestamp("2026-01-01T00:00:00+01:00").hour == 23
