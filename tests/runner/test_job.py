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

    return plan_jobs(problem, case, "diagonal", "baseline", n_starts=1, root_seed=3,
                     problem_params=params, holdout=holdout)[0]


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


# ------------------------------------------------------------------ exact cutoff


def test_run_job_records_the_same_result_with_and_without_cutoff():
    from dataclasses import replace

    from penaltyrun.runner.job import run_job
    from penaltyrun.runner.plan import plan_jobs

    job = plan_jobs("zermelo", "default", "full", "pso", n_starts=1, root_seed=5,
                    optimizer_options={"n_particles": 10, "iters": 15, "max_evals": 150},
                    holdout=False)[0]
    off = replace(job, cutoff=False)
    assert job.cutoff and job.job_id == off.job_id  # not part of the job's identity
    on_rec, off_rec = run_job(job), run_job(off)
    for key in ("status", "best_cost", "best_z", "history", "trace_evals", "trace_best",
                "n_evals", "n_iters", "stop_reason", "n_nonfinite", "metrics"):
        assert on_rec[key] == off_rec[key], key


def test_objective_without_threshold_support_runs_every_candidate():
    from penaltyrun import optim
    from penaltyrun.problems.base import BatchEvaluation, MatrixSpec
    from penaltyrun.runner.job import _objective
    from penaltyrun.runner.setup import build_layout

    class UserProblem:  # a user problem of the old protocol: no thresholds keyword
        name, case, scalars = "user", "default", ()
        matrices = (MatrixSpec("K", 2, (0.1, 10.0)),)

        def evaluate_batch(self, mats, scalars=None):
            cost = np.trace(mats["K"], axis1=1, axis2=2)
            return BatchEvaluation(cost=cost, converged=np.ones(cost.size, bool),
                                   status=np.array(["converged"] * cost.size, dtype=object))

    from types import SimpleNamespace

    from penaltyrun.runner.swarm import LocalEvaluation

    prob = UserProblem()
    layout = build_layout(prob, "full", {})
    settings = optim.make_settings("pso", {"n_particles": 5, "iters": 3})
    job = SimpleNamespace(job_id="user", cutoff=True)
    beat = _objective(LocalEvaluation(), job, prob, layout, "full", settings)
    assert not beat.accepts_thresholds
    lb, ub = layout.bounds()
    res = optim.minimize("pso", beat, lb, ub, settings, 1)
    assert res.n_evals == 15 and beat.n_cutoff == 0


def test_jobs_run_with_one_blas_thread(monkeypatch):
    """The BLAS thread limit holds while the job runs and is lifted afterwards."""
    from threadpoolctl import threadpool_info

    from penaltyrun.runner import job as job_module

    seen = {}

    def fake(job, evaluation=None):
        seen["threads"] = {p["num_threads"] for p in threadpool_info()
                           if p["user_api"] == "blas"}
        return {"status": "ok"}

    monkeypatch.setattr(job_module, "_run_job", fake)
    before = [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]
    assert job_module.run_job(None) == {"status": "ok"}
    assert seen["threads"] <= {job_module.BLAS_THREADS}
    controller = job_module._CONTROLLER[0]
    assert job_module.run_job(None) == {"status": "ok"}  # the second job reuses it
    assert job_module._CONTROLLER[0] is controller
    assert seen["threads"] <= {job_module.BLAS_THREADS}
    assert [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"] == before


def test_blas_limit_finds_the_libraries_again_after_new_imports(monkeypatch):
    """A module imported after the controller was made may load another BLAS: the next
    job's limit is taken from a new controller."""
    import sys
    import types

    from penaltyrun.runner import job as job_module

    with job_module.blas_limit():
        pass
    first = job_module._CONTROLLER[0]
    monkeypatch.setitem(sys.modules, "penaltyrun_test_new_module", types.ModuleType("x"))
    with job_module.blas_limit():
        pass
    assert job_module._CONTROLLER[0] is not first


# ------------------------------------------------------------------ the record's fields


def test_every_field_a_job_writes_is_a_defined_record_field(tmp_path):
    from penaltyrun.jobrecord import FIELDS, SCHEMA_VERSION
    from penaltyrun.runner.job import run_job
    from penaltyrun.runner.pool import failure_record
    from penaltyrun.runner.records import load_record, write_record

    job = _baseline_job("zermelo", "default", {"holdout_radii": [3.0],
                                                "holdout_n_angles": 3})
    finished = run_job(job)
    assert finished["status"] in ("ok", "diverged"), finished.get("error")
    broken = run_job(_baseline_job("zermelo", "default", {"no_such_param": 1}))
    assert broken["status"] == "failed"
    for record in (finished, broken, failure_record(job, "worker died")):
        assert set(record) <= set(FIELDS), set(record) - set(FIELDS)
        path = write_record(tmp_path, job, {**record, "job_id": job.job_id})
        stored, reason = load_record(path)
        assert reason == "" and stored["schema_version"] == SCHEMA_VERSION
        assert set(stored) <= set(FIELDS)
