"""In-memory problems on dask workers: shipped with cloudpickle, or one clear error."""

from __future__ import annotations

import threading

import numpy as np
import pytest

import penaltyrun
from penaltyrun import problems
from penaltyrun.api.compose import compose, run_spec
from penaltyrun.errors import ConfigError
from penaltyrun.runner import execute
from penaltyrun.runner.objects import object_paths, pickled
from penaltyrun.runner.spec import RunnerOptions


def _jobs(prob, path, n_starts=2):
    config = compose(prob.name, path, case=None, param="full", optimizer="cmaes",
                     optimizer_options={"max_evals": 60}, params=None,
                     runner={"n_starts": n_starts, "seed": 1})
    return run_spec(config).plan(prob.case, {})


def test_an_unpicklable_problem_is_refused_for_dask_before_any_worker_starts(tmp_path):
    lock = threading.Lock()

    def cost(K):
        with lock:
            return float(np.trace(K))

    prob = penaltyrun.from_cost(cost, {"K": (2, (0.1, 10.0))}, name="locked")
    with problems.hold(prob) as path:
        jobs = _jobs(prob, path)
        assert object_paths(jobs) == ["object:locked"]
        with pytest.raises(ConfigError, match="cannot be sent to dask workers: cloudpickle"):
            execute(jobs, tmp_path, RunnerOptions(workers=1, backend="dask"))
    assert not list((tmp_path / "jobs").glob("*.json"))


def test_a_picklable_problem_round_trips():
    import cloudpickle

    scale = 3.0
    prob = penaltyrun.from_cost(lambda K: scale * float(np.trace(K)), {"K": (2, (0.1, 10.0))},
                                name="scaled")
    with problems.hold(prob) as path:
        blobs = pickled(_jobs(prob, path))
    copy = cloudpickle.loads(blobs["object:scaled"])
    assert copy.evaluate({"K": np.eye(2)})["cost"] == 6.0


@pytest.mark.slow
def test_dask_gives_the_records_of_the_local_pool(tmp_path):
    pytest.importorskip("distributed")
    prob = penaltyrun.from_cost(lambda K: float(np.sum((K - np.eye(2)) ** 2)),
                                {"K": (2, (0.1, 10.0))}, name="shipped")
    with problems.hold(prob) as path:
        jobs = _jobs(prob, path)
        execute(jobs, tmp_path / "dask", RunnerOptions(workers=2, backend="dask"))
        execute(jobs, tmp_path / "local", RunnerOptions(workers=1))
    from penaltyrun.runner.records import read_record

    for job in jobs:
        a = read_record(tmp_path / "dask" / "jobs" / f"{job.job_id}.json")
        b = read_record(tmp_path / "local" / "jobs" / f"{job.job_id}.json")
        assert a["best_cost"] == b["best_cost"] and a["best_z"] == b["best_z"]
