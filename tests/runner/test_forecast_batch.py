"""The forecast times candidates at the optimizer's batch size."""

from __future__ import annotations

import math

import numpy as np

from penaltyrun import optim
from penaltyrun.runner import forecast as fc
from penaltyrun.runner.setup import build


def test_optimizer_batch_sizes():
    assert fc.optimizer_batch(optim.make_settings("pso", {"n_particles": 17}), 6) == 17
    assert fc.optimizer_batch(optim.make_settings("pso_matlab", {"swarm_size": 500}), 6) == 500
    assert fc.optimizer_batch(optim.make_settings("pso_matlab", {}), 6) == 60  # min(100, 10·6)
    assert fc.optimizer_batch(optim.make_settings("cmaes", {}), 27) == 4 + int(3 * math.log(27))
    assert fc.optimizer_batch(optim.make_settings("cmaes", {"popsize": 40}), 27) == 40
    assert fc.optimizer_batch(optim.make_settings("de", {"popsize": 5}), 3) == 15
    assert fc.optimizer_batch(optim.make_settings("grid", {}), 3) == 1


class Counting:
    """A problem that records the batch sizes it is called with."""

    def __init__(self) -> None:
        self.sizes: list[int] = []

    def evaluate_batch(self, mats, scalars=None):  # noqa: ANN001, ANN201
        self.sizes.append(next(iter(mats.values())).shape[0])


def test_batches_have_the_optimizer_size_and_give_per_evaluation_times():
    problem, layout, _ = build("zermelo", "default", {}, "full", {}, "pso", {})
    counting = Counting()
    timing = fc.time_candidates(counting, layout, 3, seed=0, batch=7)
    assert counting.sizes == [1, 1, 7, 7, 7]  # warm-up, one alone (size check), 3 batches
    assert timing.batch == 7 and len(timing.samples_s) == 3
    real = fc.time_candidates(problem, layout, 2, seed=0, batch=50)
    assert real.batch == 50 and all(np.isfinite(real.samples_s))


def test_slow_problems_get_smaller_batches(monkeypatch):
    problem, layout, _ = build("zermelo", "default", {}, "full", {}, "pso", {})
    counting = Counting()
    monkeypatch.setattr(fc, "BATCH_CALL_S", 0.0)  # any candidate is "too slow" for a batch
    timing = fc.time_candidates(counting, layout, 2, seed=0, batch=500)
    assert timing.batch == 1 and counting.sizes == [1, 1, 1, 1]
