"""The time left in a run, against a simulated dispatch of jobs to workers."""

import heapq

import numpy as np
import pytest

from penaltyrun.runner.eta import DispatchEta
from penaltyrun.runner.executor import dispatch_slots


def simulate(durations, slots):
    """Each job to the first worker that falls free, in order (as the runner's pool does):
    the (finish time, duration) of every job in finishing order, and the run's end."""
    free = [(0.0, k) for k in range(min(slots, len(durations)))]
    heapq.heapify(free)
    done = []
    for d in durations:
        start, worker = heapq.heappop(free)
        done.append((start + d, d))
        heapq.heappush(free, (start + d, worker))
    done.sort()
    return done, max(t for t, _ in done)


def estimates(durations, slots):
    """(true time left, estimate, elapsed-rate estimate) at each finished job."""
    done, end = simulate(durations, slots)
    eta = DispatchEta(len(durations), slots)
    return [(end - t, eta.finished(t, d), t / i * (len(durations) - i))
            for i, (t, d) in enumerate(done, start=1)]


@pytest.mark.parametrize("slots", [1, 2, 3, 4])
def test_equal_jobs_are_forecast_exactly(slots):
    rows = estimates([30.0] * 10, slots)
    for truth, est, _ in rows:
        assert est == pytest.approx(truth, abs=1e-9)
    assert rows[-1][1] == 0.0


def test_two_workers_the_elapsed_rate_is_twice_the_truth_and_the_dispatch_is_not():
    """The case users met: 10 jobs of about 28 s on 2 workers, each worker's first job
    longer (loading compiled kernels). The rate estimate announced several times the time
    left after the first job; the dispatch is nearer from the start, and exact once as
    many jobs as workers have finished that were not a worker's first."""
    durations = [44.0, 44.0] + [28.0] * 8
    rows = estimates(durations, 2)
    truth, est, rate = rows[0]
    assert rate / truth > 3.0 and est / truth < 1.6
    for truth, est, rate in rows[:4]:
        assert abs(est - truth) <= abs(rate - truth)
    for truth, est, _ in rows[4:]:
        assert est == pytest.approx(truth, abs=1e-9)


@pytest.mark.parametrize("sigma", [0.1, 0.3])
@pytest.mark.parametrize("slots", [2, 4])
def test_uneven_jobs_are_forecast_better_than_by_the_rate(slots, sigma):
    """Jobs of one cell differ (lognormal durations, spread ``sigma``): over 20 runs the
    dispatch's error, as a share of the run's length, is smaller than the rate's on
    average over each run and, by far, while the first jobs finish."""
    ours, rate, ours_first, rate_first = [], [], [], []
    for seed in range(20):
        durations = list(np.random.default_rng(seed).lognormal(np.log(30.0), sigma, 40))
        rows = estimates(durations, slots)
        total = simulate(durations, slots)[1]
        ours.append(np.mean([abs(e - t) for t, e, _ in rows]) / total)
        rate.append(np.mean([abs(r - t) for t, _, r in rows]) / total)
        ours_first.append(np.mean([abs(e - t) for t, e, _ in rows[:slots]]) / total)
        rate_first.append(np.mean([abs(r - t) for t, _, r in rows[:slots]]) / total)
    assert np.mean(ours) < 0.07 and np.mean(ours) < 0.8 * np.mean(rate)
    assert np.mean(ours_first) < 0.5 * np.mean(rate_first)


def test_unknown_workers_fall_back_to_the_elapsed_rate():
    eta = DispatchEta(10, None)
    assert eta.finished(20.0, 5.0) == pytest.approx(180.0)
    assert eta.finished(30.0) == pytest.approx(120.0)


def test_a_job_without_its_duration_still_counts():
    eta = DispatchEta(4, 2)
    # taken to have run since the start, 10 s: the twin in flight ends now, one queued
    assert eta.finished(10.0, None) == pytest.approx(10.0)
    assert eta.finished(10.0, 10.0) == pytest.approx(10.0)
    assert eta.finished(20.0, 10.0) == pytest.approx(0.0)  # the last one ends at 20 s too


def test_slots_of_each_backend():
    assert dispatch_slots(1, 8) == 1
    assert dispatch_slots(4, 1) == 1
    assert dispatch_slots(4, 8) == 4
    assert dispatch_slots(4, 8, "dask") == 4  # a LocalCluster of 4 processes
    assert dispatch_slots(4, 8, "dask", "tcp://h:8786") is None
    assert dispatch_slots(4, 8, "dask", None, "dask") is None
