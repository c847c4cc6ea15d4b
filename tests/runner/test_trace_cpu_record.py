"""Every finished job records the CPU seconds of its anytime trace (``trace_cpu_s``)."""

from __future__ import annotations

import numpy as np
import pytest

from penaltyrun import runner
from penaltyrun.runner.job import run_job


def check_trace(record: dict) -> None:
    cpu = np.asarray(record["trace_cpu_s"], float)
    assert cpu.shape == (len(record["trace_evals"]),) == (len(record["trace_best"]),)
    assert np.all(cpu >= 0) and np.all(np.diff(cpu) >= 0)


@pytest.mark.parametrize("optimizer, options", [
    ("cmaes", {"max_evals": 120}), ("lbfgs", {"max_evals": 120, "starts": 1})])
def test_a_job_records_one_cpu_time_per_trace_point(optimizer, options):
    job = runner.plan_jobs("lqr", "default", "givens", optimizer, n_starts=1, root_seed=3,
                           optimizer_options=options, holdout=False)[0]
    record = run_job(job)
    assert record["status"] == "ok", record.get("error")
    check_trace(record)


def test_a_warm_started_job_continues_the_cpu_trace_of_its_diagonal_stage():
    job = runner.plan_jobs("lqr", "default", "givens", "cmaes", n_starts=1, root_seed=3,
                           optimizer_options={"max_evals": 200}, holdout=False,
                           warm_start_share=0.5)[0]
    record = run_job(job)
    assert record["status"] == "ok", record.get("error")
    check_trace(record)
    diag_points = sum(1 for n in record["trace_evals"] if n <= record["warm_start"]["n_evals"])
    assert 0 < diag_points < len(record["trace_evals"])


def test_a_failed_job_has_no_cpu_trace():
    job = runner.plan_jobs("lqr", "default", "givens", "cmaes", n_starts=1, root_seed=3,
                           problem_params={"no_such_param": 1}, optimizer_options={"max_evals": 50},
                           holdout=False)[0]
    record = run_job(job)
    assert record["status"] == "failed" and "trace_cpu_s" not in record
