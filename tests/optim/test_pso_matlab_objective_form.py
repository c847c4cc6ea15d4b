"""Objective forms through the optimizer layer: the optimizer sees an objective's
``objective`` values (e.g. −1/J) while the best, the trace and the result keep its costs;
MATLAB's stall test then runs on −1/J."""

from __future__ import annotations

import numpy as np
import pytest

from penaltyrun import optim
from penaltyrun.optim.base import CountingObjective
from penaltyrun.optim.pso_matlab import PSOMatlabSettings, run_pso_matlab, stalled
from penaltyrun.problems.base import BatchEvaluation


def _neg_reciprocal(cost_func):
    """Objective returning J as the cost and −1/J as the optimizer's value."""

    def func(Z):
        J = cost_func(Z)
        return BatchEvaluation(cost=J, converged=np.ones(J.size, bool),
                               status=np.full(J.size, "converged", dtype=object),
                               objective=-1.0 / J)

    return func


def _bowl(Z):
    """J = 80 + 100·|z − 0.3|² ≥ 80: |−1/J| < 1, so MATLAB's stall test is absolute on it."""
    return 80.0 + 100.0 * np.sum((np.asarray(Z) - 0.3) ** 2, axis=1)


def test_counting_objective_hands_on_the_objective_and_keeps_the_cost():
    counted = CountingObjective(_neg_reciprocal(_bowl))
    Z = np.array([[0.3, 0.3], [0.0, 0.0], [1.0, 1.0]])
    out = counted(Z)
    np.testing.assert_array_equal(out, -1.0 / _bowl(Z))
    assert counted.best_cost == 80.0 and np.array_equal(counted.best_z, Z[0])
    assert counted.trace_best == [80.0]


def test_nonfinite_objective_values_are_replaced_in_both():
    def func(Z):
        return BatchEvaluation(cost=np.array([1.0, 2.0]), converged=np.ones(2, bool),
                               status=np.array(["converged"] * 2, dtype=object),
                               objective=np.array([np.nan, -0.5]))

    counted = CountingObjective(func, nonfinite_cost=1e9)
    out = counted(np.zeros((2, 1)))
    assert list(out) == [1e9, -0.5] and counted.n_nonfinite == 1 and counted.best_cost == 2.0


def test_same_moves_under_both_forms_until_the_earlier_stop():
    """Same ordering → with the same seed the swarm moves identically: the −1/J run is a
    prefix of the J run, and its history is in J."""
    settings = PSOMatlabSettings(swarm_size=12, max_iterations=150)
    lb, ub = np.zeros(3), np.ones(3)
    on_j = run_pso_matlab(_bowl, lb, ub, settings, seed=5)
    on_rec = run_pso_matlab(_neg_reciprocal(_bowl), lb, ub, settings, seed=5)
    k = on_rec.n_iters
    assert on_rec.history == on_j.history[:k]
    assert on_rec.n_evals == 12 * (k + 1) < on_j.n_evals
    assert min(on_rec.history) >= 80.0 and on_rec.best_cost == on_rec.history[-1]


def test_stall_test_sees_neg_reciprocal_on_a_hand_made_sequence():
    """Iteration k returns J = 95 − 1e-4·k for every particle: over 20 iterations J changes
    by 2e-3 (relative 2.1e-5 > 1e-6: no stall), −1/J by 2.2e-7 (absolute, ≤ 1e-6: stall)."""
    calls = []

    def scripted(Z):
        J = np.full(Z.shape[0], 95.0 - 1e-4 * len(calls))
        calls.append(1)
        return J

    settings = PSOMatlabSettings(swarm_size=6, max_iterations=60)
    lb, ub = np.zeros(2), np.ones(2)
    on_j = run_pso_matlab(scripted, lb, ub, settings, seed=1)
    calls.clear()
    on_rec = run_pso_matlab(_neg_reciprocal(scripted), lb, ub, settings, seed=1)
    assert on_j.stop_reason == "iters" and on_j.n_iters == 60
    # the code's test: from iteration W + 1 = 21 on, |best_k − best_(k−W+1)| ≤ tol
    assert on_rec.stop_reason == "ftol" and on_rec.n_iters == 21
    assert on_rec.n_evals == 6 * 22
    bests = [95.0 - 1e-4 * k for k in range(22)]
    assert stalled([-1.0 / b for b in bests], 20, 1e-6, "code")
    assert not stalled(bests, 20, 1e-6, "code")
    np.testing.assert_allclose(on_rec.history, bests[1:], rtol=0, atol=1e-12)


def test_every_optimizer_records_the_cost():
    lb, ub = np.zeros(2), np.ones(2)
    for name, opts in {"pso": {"n_particles": 6, "iters": 5},
                       "de": {"popsize": 2, "iters": 4, "polish": "none"},
                       "cmaes": {"max_evals": 60}}.items():
        res = optim.minimize(name, _neg_reciprocal(_bowl), lb, ub,
                             optim.make_settings(name, opts), seed=3)
        assert res.best_cost >= 80.0 and res.best_cost == pytest.approx(
            float(_bowl(res.best_z[None])[0]))
        assert all(b >= 80.0 for b in res.trace_best)
