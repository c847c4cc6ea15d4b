"""Job-level helpers: the progress heartbeat of long jobs."""

import logging

import numpy as np

from penaltyrun.runner.job import Heartbeat


def test_heartbeat_passes_costs_through_and_logs_progress(caplog):
    beat = Heartbeat(lambda Z: Z.sum(axis=1), "job-x", interval_s=0.0)
    with caplog.at_level(logging.INFO, logger="penaltyrun.runner.job"):
        np.testing.assert_array_equal(beat(np.array([[1.0, 2.0], [0.5, 0.5]])), [3.0, 1.0])
        beat(np.array([[np.inf, 0.0], [4.0, 0.0]]))
    assert beat.n_evals == 4 and beat.best == 1.0
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 2
    assert lines[-1].startswith("job-x: running, 4 evaluations")
    assert "best cost so far 1" in lines[-1]


def test_heartbeat_is_quiet_within_its_interval(caplog):
    beat = Heartbeat(lambda Z: Z[:, 0], "job-y", interval_s=3600.0)
    with caplog.at_level(logging.INFO, logger="penaltyrun.runner.job"):
        for _ in range(5):
            beat(np.ones((3, 2)))
    assert beat.n_evals == 15
    assert not caplog.records
