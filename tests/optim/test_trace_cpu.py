"""The anytime trace's CPU seconds (``trace_cpu_s``): one per trace point, from the start of
the search, measured with ``time.process_time``."""

from __future__ import annotations

import time

import numpy as np
import pytest

from penaltyrun.optim import make_settings, minimize
from penaltyrun.optim.base import CountingObjective

LB, UB = -np.ones(3), np.ones(3)


def burn(seconds: float) -> None:
    """Spend about ``seconds`` of CPU time in this process."""
    end = time.process_time() + seconds
    while time.process_time() < end:
        pass


def test_each_trace_point_carries_the_cpu_spent_since_the_search_began():
    def slow(Z):
        burn(0.02 * len(Z))
        return np.array([10.0 - k for k in range(len(Z))]) + np.sum(Z, axis=1)

    counted = CountingObjective(slow)
    counted(np.zeros((1, 3)))          # 0.02 s, first point
    counted(-0.5 * np.ones((3, 3)))    # 0.06 s more, a new best
    counted(np.ones((2, 3)))           # 0.04 s more, no improvement: no point
    res = counted.result([], 0, "test")
    assert res.trace_evals == [1, 4, 6]  # closed at the last evaluation
    cpu = np.asarray(res.trace_cpu_s)
    assert cpu.shape == (3,) and np.all(np.diff(cpu) >= 0)
    assert cpu[0] >= 0.02 and cpu[1] - cpu[0] >= 0.06 and cpu[2] - cpu[1] >= 0.04
    assert cpu[2] < 5.0  # the CPU of this search, not of the process since it started


@pytest.mark.parametrize("name, options", [
    ("cmaes", {"max_evals": 300}), ("pso", {"max_evals": 300, "n_particles": 10}),
    ("de", {"max_evals": 300, "popsize": 5}), ("pso_matlab", {"max_evals": 300})])
def test_every_optimizer_returns_one_cpu_time_per_trace_point(name, options):
    res = minimize(name, lambda Z: np.sum((Z - 0.2) ** 2, axis=1), LB, UB,
                   make_settings(name, options), seed=1)
    assert len(res.trace_cpu_s) == len(res.trace_evals) == len(res.trace_best)
    assert np.all(np.diff(res.trace_cpu_s) >= 0) and res.trace_cpu_s[0] >= 0


def test_lbfgs_trace_counts_the_gradient_work():
    from types import SimpleNamespace

    def gradient(z):
        burn(0.01)
        return SimpleNamespace(grad=2 * (z - 0.2), reason="")

    res = minimize("lbfgs", lambda Z: np.sum((Z - 0.2) ** 2, axis=1), LB, UB,
                   make_settings("lbfgs", {"max_evals": 200, "starts": 1, "grad_cost": 2}),
                   seed=1,
                   gradient=gradient)
    assert len(res.trace_cpu_s) == len(res.trace_evals)
    gradients = sum(1 for _ in res.trace_evals)  # at least one gradient before each new best
    assert res.trace_cpu_s[-1] >= 0.01 * min(gradients, 2)
