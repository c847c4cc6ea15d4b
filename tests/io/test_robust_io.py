"""Results files: written atomically; unreadable ones skipped by readers with a warning."""

import json

import pyarrow.parquet as pq
import pytest

from penaltyrun import io
from penaltyrun.errors import ResultsUnreadableError
from penaltyrun.io import schema


def _run_dir(tmp_path, name="run", n=2):
    run = tmp_path / name
    (run / "jobs").mkdir(parents=True)
    for i in range(n):
        record = {"job_id": f"j{i}", "problem": "zermelo", "case": "default",
                  "param": "diagonal", "optimizer": "pso", "seed": i, "status": "ok",
                  "best_cost": 1.0 + i, "start": i}
        (run / "jobs" / f"j{i}.json").write_text(json.dumps(record))
    return run


def test_collect_replaces_results_atomically(tmp_path, monkeypatch):
    run = _run_dir(tmp_path)
    path = io.collect(run)
    assert len(io.read_results(path)) == 2
    assert sorted(p.name for p in run.iterdir()) == ["jobs", "results.parquet"]

    def broken(table, where, **kw):
        where.write(b"PAR1 half")  # the temporary file, as an open binary file
        raise OSError("disk full")

    monkeypatch.setattr(schema.pq, "write_table", broken)
    (run / "jobs" / "j2.json").write_text(json.dumps(
        {"job_id": "j2", "problem": "zermelo", "case": "default", "param": "diagonal",
         "optimizer": "pso", "seed": 2, "start": 2, "status": "ok", "best_cost": 1.0}))
    with pytest.raises(OSError, match="disk full"):
        io.collect(run)
    assert len(pq.read_table(path)) == 2  # the previous file is intact
    assert sorted(p.name for p in run.iterdir()) == ["jobs", "results.parquet"]


def test_collect_skips_unreadable_record(tmp_path, caplog):
    run = _run_dir(tmp_path)
    (run / "jobs" / "j1.json").write_text('{"job_id": "j1", "sta')
    df = io.read_results(io.collect(run))
    assert list(df["job_id"]) == ["j0"]
    assert "j1.json" in caplog.text
    assert (run / "jobs" / "corrupt").is_dir()  # moved aside, its job runs again on resume


def test_read_results_skips_unreadable_files(tmp_path, caplog):
    good = io.collect(_run_dir(tmp_path, "a"))
    truncated = tmp_path / "b" / "results.parquet"
    truncated.parent.mkdir()
    truncated.write_bytes(good.read_bytes()[:200])
    garbage = tmp_path / "c" / "results.parquet"
    garbage.parent.mkdir()
    garbage.write_text("not parquet at all")
    df = io.read_results(tmp_path)
    assert len(df) == 2
    assert str(truncated) in caplog.text and str(garbage) in caplog.text
    with pytest.raises(ResultsUnreadableError, match="no readable results"):
        io.read_results([truncated, garbage])
