"""Differential evolution adapter (scipy)."""

from __future__ import annotations

import numpy as np
import pytest
from batched_objectives import CENTER, LB, UB, Recorder, quadratic

from penaltyrun.optim import DESettings, minimize
from penaltyrun.optim.de import run_de


def test_finds_minimum_of_quadratic():
    res = minimize("de", quadratic, LB, UB, DESettings(popsize=10, iters=100,
                                                        polish="L-BFGS-B"), seed=1)
    assert res.best_cost < 1e-10
    np.testing.assert_allclose(res.best_z, CENTER, atol=1e-5)
    assert res.history[-1] == pytest.approx(res.best_cost, abs=1e-15)
    assert res.n_nonfinite == 0
    assert res.stop_reason in ("ftol+polish", "iters+polish")


def test_deterministic_per_seed():
    s = DESettings(popsize=5, iters=20, polish="none")
    a = run_de(quadratic, LB, UB, s, seed=7)
    b = run_de(quadratic, LB, UB, s, seed=7)
    c = run_de(quadratic, LB, UB, s, seed=8)
    assert a.history == b.history
    np.testing.assert_array_equal(a.best_z, b.best_z)
    assert a.n_evals == b.n_evals
    assert a.history != c.history


def test_history_non_increasing_and_one_entry_per_generation():
    res = run_de(quadratic, LB, UB, DESettings(popsize=6, iters=30, tol=0.0, polish="none"),
                 seed=3)
    assert len(res.history) == res.n_iters == 30
    assert np.all(np.diff(res.history) <= 0)
    assert res.stop_reason == "iters"


def test_batches_inside_bounds_and_evals_counted():
    rec = Recorder(quadratic)
    lb, ub = np.array([0.4, -1.0, 0.0]), np.array([1.0, 1.0, 0.25])  # optimum clipped
    res = minimize("de", rec, lb, ub, DESettings(popsize=5, iters=15, polish="L-BFGS-B"),
                   seed=0)
    assert res.stop_reason.endswith("+polish")
    assert all(Z.ndim == 2 and Z.shape[1] == 3 for Z in rec.batches)
    allZ = np.concatenate(rec.batches)
    assert np.all(allZ >= lb) and np.all(allZ <= ub)
    assert res.n_evals == len(allZ)  # polish evaluations are counted too
    assert np.all(res.best_z >= lb) and np.all(res.best_z <= ub)
    assert res.best_z[0] == pytest.approx(0.4, abs=1e-6)


def test_nonfinite_costs_replaced_and_counted():
    def nasty(Z):
        cost = quadratic(Z)
        cost[Z[:, 0] < -0.5] = np.nan
        return cost

    res = run_de(nasty, LB, UB, DESettings(popsize=8, iters=20, polish="none"), seed=4)
    assert res.n_nonfinite > 0
    assert np.isfinite(res.best_cost) and all(np.isfinite(res.history))


def test_minimize_dispatches_to_de():
    s = DESettings(popsize=5, iters=10, polish="none")
    a = minimize("de", quadratic, LB, UB, s, seed=11)
    b = run_de(quadratic, LB, UB, s, seed=11)
    assert a.history == b.history
