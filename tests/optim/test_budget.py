"""The evaluation budget, the anytime trace and the shared polish, for every optimizer."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from penaltyrun.optim import make_settings, minimize
from penaltyrun.optim.base import BudgetExhaustedError, CountingObjective

CENTER = np.array([0.3, -0.2, 0.5, 0.1])
LB, UB = -np.ones(4), np.ones(4)


def bumpy(Z):
    D = Z - CENTER
    return (D**2).sum(axis=1) + 0.1 * (1 - np.cos(8 * D)).sum(axis=1)


SEARCHES = {"pso": {"n_particles": 17, "iters": 1000, "ftol_iter": 1000},
            "de": {"popsize": 7, "iters": 1000, "tol": 0.0},
            "cmaes": {},
            "pso_matlab": {"swarm_size": 17, "function_tolerance": 0.0}}


@pytest.mark.parametrize("name", sorted(SEARCHES))
@pytest.mark.parametrize("polish", ["none", "L-BFGS-B", "Nelder-Mead"])
def test_max_evals_is_a_hard_cap(name, polish):
    settings = make_settings(name, {**SEARCHES[name], "max_evals": 600, "polish": polish})
    calls = []

    def recorded(Z):
        calls.append(len(Z))
        return bumpy(Z)

    res = minimize(name, recorded, LB, UB, settings, seed=3)
    assert res.n_evals == sum(calls) <= 600
    assert res.n_evals >= 600 - 4 * 5 or "+polish" in res.stop_reason  # budget used up
    if polish != "none":
        assert "+polish" in res.stop_reason


@pytest.mark.parametrize("name", sorted(SEARCHES))
def test_trace_is_the_best_so_far_step_function(name):
    settings = make_settings(name, {**SEARCHES[name], "max_evals": 400})
    costs = []

    def recorded(Z):
        c = bumpy(Z)
        costs.extend(c.tolist())
        return c

    res = minimize(name, recorded, LB, UB, settings, seed=4)
    running = np.minimum.accumulate(costs)
    evals = np.asarray(res.trace_evals)
    assert evals[-1] == res.n_evals == len(costs)
    np.testing.assert_array_equal(res.trace_best, running[evals - 1])
    assert np.all(np.diff(res.trace_best) <= 0) and np.all(np.diff(evals) > 0)
    assert res.best_cost == running[-1] == pytest.approx(float(bumpy(res.best_z[None])[0]))


@given(sizes=st.lists(st.integers(1, 40), min_size=1, max_size=30),
       cap=st.integers(1, 200))
def test_counting_objective_never_exceeds_the_cap(sizes, cap):
    counted = CountingObjective(lambda Z: Z[:, 0], max_evals=cap)
    rng = np.random.default_rng(0)
    for n in sizes:
        try:
            counted(rng.random((n, 2)))
        except BudgetExhaustedError:
            break
    assert counted.n_evals == min(cap, sum(sizes))


def test_polish_improves_a_stalled_search_within_budget():
    settings = make_settings("pso", {"n_particles": 10, "iters": 3, "max_evals": 1000,
                                     "polish": "L-BFGS-B"})
    plain = minimize("pso", bumpy, LB, UB, make_settings("pso", {"n_particles": 10,
                                                                 "iters": 3}), seed=1)
    polished = minimize("pso", bumpy, LB, UB, settings, seed=1)
    assert polished.best_cost < plain.best_cost
    assert polished.best_cost < 1e-10 and polished.n_evals <= 1000
