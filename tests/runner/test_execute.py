"""Runner: records per job, failures recorded not raised, resume, local pool and dask."""

import importlib.util
import json

import numpy as np
import pytest

from penaltyrun import io, runner
from penaltyrun.runner.spec import RunnerOptions

FAST_PSO = {"n_particles": 10, "iters": 15, "ftol_iter": 5}


def jobs(n=2, problem_params=None, param="diagonal", seed=1):
    return runner.plan_jobs("zermelo", "default", param, "pso", n_starts=n, root_seed=seed,
                            problem_params=problem_params or {}, optimizer_options=FAST_PSO,
                            meta={"git_commit": "test"})


def test_records_written_per_job_and_collected(tmp_path):
    written = runner.execute(jobs(2), tmp_path)
    assert len(written) == 2
    record = json.loads(written[0].read_text())
    assert record["status"] == "ok" and record["best_converged"]
    assert len(record["best_z"]) == 2 and record["z_names"] == ["K.lam1", "K.lam2"]
    assert record["n_evals"] == FAST_PSO["n_particles"] * record["n_iters"]
    assert record["history"] == sorted(record["history"], reverse=True)
    K = np.asarray(record["matrices"]["K"])
    assert K.shape == (2, 2) and K[0, 1] == 0.0
    df = io.read_results(io.collect(tmp_path))
    assert len(df) == 2 and set(df["git_commit"]) == {"test"}


def test_failing_job_is_recorded_and_run_goes_on(tmp_path):
    bad = jobs(1, problem_params={"x0": "not a vector"}, param="givens")
    good = jobs(1)
    runner.execute(bad + good, tmp_path)
    df = io.read_results(io.collect(tmp_path))
    assert sorted(df["status"]) == ["failed", "ok"]
    failed = df[df["status"] == "failed"].iloc[0]
    assert failed["error"] and np.isnan(failed["best_cost"])


def test_diverged_when_nothing_can_converge(tmp_path):
    runner.execute(jobs(1, problem_params={"t_max": 0.5}), tmp_path)
    df = io.read_results(io.collect(tmp_path))
    row = df.iloc[0]
    assert row["status"] == "diverged" and not row["best_converged"]
    assert np.isfinite(row["best_cost"]) and "horizon" in row["error"]


def test_resume_skips_finished_and_retries_failed(tmp_path):
    planned = jobs(3)
    runner.execute(planned[:2], tmp_path)
    assert [j.job_id for j in runner.pending_jobs(planned, tmp_path, resume=True)] == \
        [planned[2].job_id]
    record_path = runner.job_path(tmp_path, planned[0])
    record = json.loads(record_path.read_text())
    record["status"] = "failed"
    record_path.write_text(json.dumps(record))
    todo = runner.pending_jobs(planned, tmp_path, resume=True, retry_failed=True)
    assert {j.job_id for j in todo} == {planned[0].job_id, planned[2].job_id}
    assert len(runner.pending_jobs(planned, tmp_path, resume=False)) == 3


def test_process_pool_matches_serial(tmp_path):
    serial = runner.run_job(jobs(1, seed=5)[0])
    runner.execute(jobs(2, seed=5), tmp_path / "pool", RunnerOptions(workers=2))
    pooled = json.loads(runner.job_path(tmp_path / "pool", jobs(1, seed=5)[0]).read_text())
    assert pooled["best_cost"] == serial["best_cost"]
    assert pooled["best_z"] == serial["best_z"]


def test_full_map_job_reaches_paper_cost(tmp_path):
    job = runner.plan_jobs("zermelo", "default", "full", "pso", n_starts=1, root_seed=3,
                           optimizer_options={"n_particles": 30, "iters": 100})[0]
    record = runner.run_job(job)
    assert record["status"] == "ok"
    assert record["best_cost"] == pytest.approx(24.82646, rel=1e-4)


@pytest.mark.skipif(importlib.util.find_spec("distributed") is None,
                    reason="dask.distributed not installed (optional extra)")
def test_dask_backend_runs_jobs(tmp_path):
    written = runner.execute(jobs(2), tmp_path, RunnerOptions(workers=1, backend="dask"))
    assert len(written) == 2
    assert all(json.loads(p.read_text())["status"] == "ok" for p in written)


def test_bad_runner_settings(tmp_path):
    from penaltyrun.errors import ConfigError

    with pytest.raises(ConfigError, match="runner.workers"):
        runner.execute(jobs(1), tmp_path, RunnerOptions(workers=0))
    with pytest.raises(ConfigError, match="allowed: local, dask"):
        runner.execute(jobs(1), tmp_path, RunnerOptions(backend="slurm"))
