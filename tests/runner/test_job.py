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


# ------------------------------------------------------------------ held-out hook


def _baseline_job(problem, case, params, holdout=True):
    from penaltyrun.runner.plan import plan_jobs

    return plan_jobs(problem, case, "diagonal", "baseline", 1, 3, params, {}, {}, {},
                     holdout=holdout)[0]


def test_holdout_hook_stores_every_problems_held_out_results():
    import json

    from penaltyrun import problems
    from penaltyrun.runner.job import run_job

    cells = [("zermelo", "default", {"holdout_radii": [3.0], "holdout_n_angles": 3}),
             ("attitude_lyapunov", "schaub_detumble", {"holdout_n_perturbed": 3}),
             ("qlaw", "C", {"holdout_n_perturbed": 1, "holdout_control_steps": [60.0],
                            "holdout_substeps": [2]})]
    for problem, case, params in cells:
        record = run_job(_baseline_job(problem, case, params))
        assert record["status"] in ("ok", "diverged"), record.get("error")
        held = json.loads(json.dumps(record["holdout"]))
        prob = problems.make(problem, case, params)
        mats = {k: np.asarray(v) for k, v in record["matrices"].items()}
        direct = prob.holdout(mats, record["scalars"] or None)
        assert list(held["scenario"]) == list(direct["scenario"]), problem
        np.testing.assert_allclose(held["cost"], np.asarray(direct["cost"], float), rtol=1e-12)
        assert len(held["converged"]) == len(held["scenario"])
    off = run_job(_baseline_job("zermelo", "default", {}, holdout=False))
    assert off["holdout"] is None
