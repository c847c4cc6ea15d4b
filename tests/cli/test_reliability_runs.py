"""A run's results are exactly its own (subprocess tests): one run per directory, the job
id covers the seed and held-out setting, records are checked on read, the report counts
each job once."""

import json
import os
import shutil
import signal
import time

import pandas as pd
import pytest
from cli_subprocess import FAST_JOBS, SLOW_JOBS, cli, one_error_line, popen, records, report

from penaltyrun.io import RESULTS_FILE


@pytest.mark.slow  # about 8 s: three runs
def test_second_run_into_a_busy_directory_is_refused_and_a_dead_one_never_blocks(tmp_path):
    run = tmp_path / "run"
    first = popen(*SLOW_JOBS, "runner.n_starts=4", "runner.workers=1", f"hydra.run.dir={run}",
                  cwd=tmp_path)
    try:
        lock = run / ".penaltyrun.lock"
        t0 = time.monotonic()
        while not (lock.exists() and lock.read_text()):
            assert time.monotonic() - t0 < 300, "the first run never took the lock"
            time.sleep(0.2)
        os.killpg(first.pid, signal.SIGSTOP)  # holds the lock as long as we like
        second = cli(*SLOW_JOBS, "runner.n_starts=4", "runner.seed=2", f"hydra.run.dir={run}",
                     cwd=tmp_path, timeout=120)
        assert second.returncode == 2, second.stderr
        line = one_error_line(second)
        assert f"in use by another penaltyrun run (pid {first.pid}, started 20" in line
    finally:
        os.killpg(first.pid, signal.SIGKILL)
        first.communicate(timeout=60)
    assert lock.exists()  # left by the killed run: a resume takes it over
    resumed = cli(*SLOW_JOBS, "runner.n_starts=4", "runner.workers=1", "runner.resume=true",
                  f"hydra.run.dir={run}", cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    assert len(pd.read_parquet(run / RESULTS_FILE)) == 4


@pytest.mark.slow  # about 11 s: three runs into one directory
def test_resume_with_another_seed_or_holdout_never_mixes(tmp_path):
    run = tmp_path / "run"
    base = [*FAST_JOBS, "runner.n_starts=4", f"hydra.run.dir={run}"]
    assert cli(*base, "runner.seed=1", cwd=tmp_path).returncode == 0
    for extra in (["runner.seed=2"], ["runner.seed=1", "runner.holdout=false"]):
        proc = cli(*base, *extra, "runner.resume=true", cwd=tmp_path)
        out = proc.stderr + proc.stdout
        assert proc.returncode == 0, out
        assert "0 of 4 jobs already finished" in out
        assert "left out" in out and "of another configuration" in out
        df = pd.read_parquet(run / RESULTS_FILE)
        assert len(df) == 4 and df["job_id"].nunique() == 4
        assert all(json.loads(r["packages"])["numpy"] for r in records(run))  # provenance
    mine = pd.read_parquet(run / RESULTS_FILE)
    assert (mine["holdout"].isna()).all()  # the last run was without held-out data


@pytest.mark.slow  # about 11 s: several resumed runs
def test_records_are_checked_on_resume(tmp_path):
    run = tmp_path / "run"
    args = [*FAST_JOBS, "runner.n_starts=4", f"hydra.run.dir={run}"]
    assert cli(*args, cwd=tmp_path).returncode == 0
    files = sorted((run / "jobs").glob("*.json"))
    shutil.copy(files[0], files[1])  # another job's record under this job's name
    for path, change in ((files[2], {"best_cost": float("nan")}), (files[3], {"best_cost": "abc"})):
        rec = json.loads(path.read_text())
        rec.update(change)
        path.write_text(json.dumps(rec))
    proc = cli(*args, "runner.resume=true", cwd=tmp_path)
    out = proc.stderr + proc.stdout
    assert proc.returncode == 0, out
    assert "Traceback" not in out
    assert "1 of 4 jobs already finished" in out
    for path, reason in ((files[1], f"job_id '{files[0].stem}' is not the file's job"),
                         (files[2], "best_cost is NaN"),
                         (files[3], "best_cost must be a number")):
        assert f"{path} is not usable ({reason}" in out
    assert len(list((run / "jobs" / "corrupt").iterdir())) == 3
    df = pd.read_parquet(run / RESULTS_FILE)
    assert sorted(df["start"]) == [0, 1, 2, 3] and set(df["status"]) == {"ok"}


@pytest.mark.slow  # about 8 s: two runs and reports
def test_report_counts_a_copied_run_once_and_skips_foreign_files(tmp_path):
    run = tmp_path / "all" / "run"
    assert cli(*FAST_JOBS, "runner.n_starts=3", f"hydra.run.dir={run}",
               cwd=tmp_path).returncode == 0
    shutil.copytree(run, tmp_path / "all" / "backup")
    foreign = tmp_path / "all" / "foreign" / RESULTS_FILE
    foreign.parent.mkdir()
    pd.DataFrame({"x": [1.0]}).to_parquet(foreign)
    proc = report(str(tmp_path / "all"))
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    assert "left out 3 duplicate rows" in proc.stderr
    assert str(tmp_path / "all" / "backup" / RESULTS_FILE) in proc.stderr
    assert f"skipped results file {foreign}: not penaltyrun results" in proc.stderr
    alone = report(str(foreign))
    assert alone.returncode == 2 and "no readable results" in one_error_line(alone)
