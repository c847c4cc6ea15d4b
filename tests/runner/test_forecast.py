"""The run forecast: wall models, longest-first dispatch, candidate timing, cell budgets,
workers=auto and the heartbeat's "N of M evaluations"."""

import importlib
import logging
import os

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from penaltyrun.errors import ConfigError
from penaltyrun.runner import forecast as fc
from penaltyrun.runner.job import Heartbeat
from penaltyrun.runner.options import available_cores, check_runner_options, resolve_workers
from penaltyrun.runner.plan import order_longest_first, plan_jobs
from penaltyrun.runner.spec import RunnerOptions

PSO = {"n_particles": 6, "iters": 4, "ftol": 0.0, "ftol_iter": 1}


# ---------------------------------------------------------------- wall models


def test_job_level_wall_small_cases():
    assert fc.job_level_wall([5.0, 3.0, 3.0, 2.0, 2.0, 2.0], 2) == 9.0  # LPT: 5+2+2 | 3+3+2
    assert fc.job_level_wall([4.0] * 10, 4) == 12.0  # 3 rounds, not 10 * 4 / 4
    assert fc.job_level_wall([4.0] * 10, 64) == 4.0
    assert fc.job_level_wall([], 8) == 0.0
    with pytest.raises(ValueError):
        fc.job_level_wall([1.0], 0)


@given(st.lists(st.floats(0.0, 100.0), min_size=1, max_size=40), st.integers(1, 70))
def test_job_level_wall_between_bound_and_four_thirds(cpus, cores):
    wall, bound = fc.job_level_wall(cpus, cores), fc.wall_bound(cpus, cores)
    assert bound - 1e-9 <= wall <= 4.0 / 3.0 * bound + max(cpus) + 1e-9
    assert wall <= sum(cpus) + 1e-9


def test_longest_first_order_is_stable_and_keeps_unknowns_last():
    jobs = plan_jobs("zermelo", "default", "full", "pso", n_starts=4, root_seed=0)
    ids = [j.job_id for j in jobs]
    expected = {ids[0]: 1.0, ids[1]: 5.0, ids[3]: 5.0}
    ordered = [j.job_id for j in order_longest_first(jobs, expected)]
    assert ordered == [ids[1], ids[3], ids[0], ids[2]]
    assert order_longest_first(jobs, None) == jobs
    assert order_longest_first(jobs, {}) == jobs


def test_execute_dispatches_longest_first(tmp_path, monkeypatch):
    ex = importlib.import_module("penaltyrun.runner.executor")
    jobs = plan_jobs("zermelo", "default", "full", "pso", n_starts=3, root_seed=0)
    seen = []
    monkeypatch.setattr(ex, "run_job", lambda job: seen.append(job.job_id) or
                        {"job_id": job.job_id, "status": "ok"})
    ex.execute(jobs, tmp_path, RunnerOptions(workers=1),
               expected_s={jobs[0].job_id: 1.0, jobs[1].job_id: 3.0, jobs[2].job_id: 2.0})
    assert seen == [jobs[1].job_id, jobs[2].job_id, jobs[0].job_id]


# ---------------------------------------------------------------- timing and budgets


def test_timing_of_random_candidates():
    jobs = plan_jobs("zermelo", "default", "full", "pso", n_starts=3, root_seed=0,
                     optimizer_options=PSO)
    cell = fc.forecast_cell(jobs, samples=4, root_seed=7)
    assert len(cell.timing.samples_s) == 4 and all(t >= 0 for t in cell.timing.samples_s)
    assert cell.timing.mean_s > 0 and np.isfinite(cell.timing.warmup_s)
    assert cell.evals == 24  # 6 particles × 4 iterations
    assert cell.extra >= 1
    assert cell.total_evals == 3 * (24 + cell.extra)
    assert cell.job_cpu_s == pytest.approx((24 + cell.extra) * cell.timing.mean_s)
    assert set(cell.expected_s()) == {j.job_id for j in jobs}
    assert "4 batches of 6" in cell.timing.describe()
    off = fc.forecast_cell(jobs, samples=0)
    assert off.job_cpu_s is None and "forecast_samples=0" in off.timing.describe()


def test_forecast_samples_zero_turns_the_run_forecast_off(caplog):
    jobs = plan_jobs("zermelo", "default", "full", "pso", n_starts=2, root_seed=0,
                     optimizer_options=PSO)
    with caplog.at_level(logging.INFO, logger="penaltyrun.runner.forecast"):
        assert fc.log_forecast(jobs, 0, 1, workers=2) == {}
        assert not caplog.records
        expected = fc.log_forecast(jobs, 2, 1, workers=2)
    assert set(expected) == {j.job_id for j in jobs}
    assert [r.getMessage()[:9] for r in caplog.records] == ["forecast:"] * 3


def test_timing_error_is_reported_not_raised():
    class Broken:
        def evaluate_batch(self, mats, scalars=None):
            raise RuntimeError("kernel exploded")

    class Layout:
        def bounds(self):
            return np.zeros(2), np.ones(2)

        def split(self, Z):
            return {"K": Z}, {}

    timing = fc.time_candidates(Broken(), Layout(), 3, seed=0)
    assert timing.mean_s is None and "kernel exploded" in timing.error


@pytest.mark.parametrize("optimizer, options, warmed", [
    ("lbfgs", {"max_evals": 50, "starts": 1}, 1), ("cmaes", {"max_evals": 50}, 0),
    ("cmaes", {"max_evals": 50, "polish": "gradient"}, 1)])
def test_a_cell_that_uses_gradients_computes_one_before_the_fork(monkeypatch, optimizer,
                                                                 options, warmed):
    """The forecast loads the gradient's kernels in the parent (one untimed gradient), so
    that no forked job's CPU trace pays for them; without samples it does nothing."""
    from penaltyrun.optim import gradient

    calls = []
    original = gradient.z_gradient
    monkeypatch.setattr(gradient, "z_gradient", lambda *a: calls.append(1) or original(*a))
    jobs = plan_jobs("lqr", "default", "givens", optimizer, n_starts=2, root_seed=0,
                     optimizer_options=options, holdout=False)
    fc.forecast_cell(jobs, samples=1, root_seed=5)
    assert len(calls) == warmed
    fc.forecast_cell(jobs, samples=0)
    assert len(calls) == warmed


def test_a_gradient_warm_up_that_fails_is_left_to_the_jobs(caplog):
    class Layout:
        def bounds(self):
            return np.zeros(2), np.ones(2)

        def split(self, Z):
            raise RuntimeError("decode exploded")

    class Problem:
        def gradient(self, mats, scalars=None):
            raise AssertionError("not reached")

    with caplog.at_level(logging.DEBUG, logger="penaltyrun.runner.forecast"):
        fc.warm_gradient(Problem(), Layout(), seed=0)
    assert "decode exploded" in caplog.text


def test_extra_evaluations_count_the_held_out_set():
    jobs = plan_jobs("qlaw", "A", "diagonal", "pso", n_starts=1, root_seed=0,
                     optimizer_options=PSO)
    with_holdout = fc.forecast_cell(jobs, samples=0)
    assert with_holdout.extra == 1 + 12  # detail + one per held-out scenario (12)
    no_holdout = plan_jobs("qlaw", "A", "diagonal", "pso", n_starts=1, root_seed=0,
                           optimizer_options=PSO, holdout=False)
    assert fc.forecast_cell(no_holdout, samples=0).extra == 1


def test_warm_start_jobs_stay_within_max_evals():
    jobs = plan_jobs("zermelo", "default", "full", "pso", n_starts=1, root_seed=0,
                     optimizer_options={**PSO, "iters": 1000, "max_evals": 300},
                     warm_start_share=0.3)
    assert fc.forecast_cell(jobs, samples=0).evals == 300


def test_summary_lines_and_hours():
    jobs = plan_jobs("zermelo", "default", "full", "pso", n_starts=2, root_seed=0,
                     optimizer_options=PSO)
    lines = fc.summary_lines(fc.forecast_cell(jobs, samples=2), workers=2)
    assert lines[0].startswith("forecast: 2 jobs × ≤ 24 evaluations")
    assert "on 2 workers" in lines[-1] and "64 cores" in lines[-1] and "512 cores" in lines[-1]
    assert fc.hours(7200.0) == "2 h" and fc.hours(90.0) == "1.5 min"
    assert fc.hours(3600.0 * 744) == "744 h (31.0 d)" and fc.hours(None) == "?"


# ---------------------------------------------------------------- workers=auto


def test_workers_auto_is_every_core():
    assert resolve_workers("auto") == available_cores()
    if hasattr(os, "sched_getaffinity"):
        assert available_cores() == len(os.sched_getaffinity(0))
    assert resolve_workers(3) == 3
    check_runner_options({"workers": "auto"})


@pytest.mark.parametrize("value", [0, -2, "all", 1.5, True, None])
def test_bad_workers_value(value):
    with pytest.raises(ConfigError, match="runner.workers: must be a positive integer or auto"):
        resolve_workers(value)


# ---------------------------------------------------------------- heartbeat


def test_heartbeat_says_n_of_m(caplog):
    beat = Heartbeat(lambda Z: Z[:, 0], "job-z", interval_s=0.0, total=40)
    with caplog.at_level(logging.INFO, logger="penaltyrun.runner.job"):
        beat(np.ones((10, 2)))
    line = caplog.records[-1].getMessage()
    assert line.startswith("job-z: running, 10 of 40 evaluations (25.0 %, ≤ ")
    assert "left at this pace" in line and "best cost so far 1" in line
    assert Heartbeat(lambda Z: Z[:, 0], "j").progress(1.0) == "0 evaluations (no bound)"
