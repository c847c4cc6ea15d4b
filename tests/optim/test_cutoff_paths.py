"""The exact cutoff leaves the optimizer's path unchanged (bitwise), through the runner's
objective, on an attitude and a low-thrust problem; and it does cut."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from penaltyrun import optim, problems
from penaltyrun.optim.base import CountingObjective
from penaltyrun.runner.job import _objective
from penaltyrun.runner.setup import build_layout
from penaltyrun.runner.swarm import LocalEvaluation

CELLS = {
    "attitude": ("attitude_lyapunov", "detumble", {}),
    "qlaw": ("qlaw", "C", {}),
}
OPTIMIZERS = {
    "pso": {"n_particles": 8, "iters": 6, "max_evals": 60},
    "pso_matlab": {"swarm_size": 8, "max_iterations": 6, "max_evals": 60},
    "de": {"popsize": 1, "iters": 5, "max_evals": 70, "polish": "none"},
}


def _run(cell, name, cutoff, seed=123):
    problem, case, params = CELLS[cell]
    prob = problems.make(problem, case, params)
    layout = build_layout(prob, "full", {})
    lb, ub = layout.bounds()
    settings = optim.make_settings(name, OPTIMIZERS[name])
    job = SimpleNamespace(job_id="test", cutoff=cutoff)
    objective = _objective(LocalEvaluation(), job, prob, layout, "full", settings)
    return optim.minimize(name, objective, lb, ub, settings, seed), objective


@pytest.mark.parametrize("cell", sorted(CELLS))
@pytest.mark.parametrize("name", sorted(OPTIMIZERS))
def test_same_path_with_and_without_cutoff(cell, name):
    off, beat_off = _run(cell, name, cutoff=False)
    on, beat_on = _run(cell, name, cutoff=True)
    assert beat_off.n_cutoff == 0
    assert beat_on.n_cutoff > 0, "the cutoff never fired: the comparison would be vacuous"
    assert on.best_cost == off.best_cost
    assert np.array_equal(on.best_z, off.best_z)
    assert on.history == off.history
    assert on.trace_evals == off.trace_evals and on.trace_best == off.trace_best
    assert (on.n_evals, on.n_iters, on.stop_reason, on.n_nonfinite) == \
        (off.n_evals, off.n_iters, off.stop_reason, off.n_nonfinite)


def test_cmaes_and_grid_pass_no_thresholds():
    seen = []

    def func(Z, thresholds=None):
        seen.append(thresholds)
        return np.sum((Z - 0.3) ** 2, axis=1)

    func.accepts_thresholds = True
    lb, ub = np.zeros(2), np.ones(2)
    optim.minimize("cmaes", func, lb, ub, optim.make_settings("cmaes", {"max_evals": 60}), 1)
    optim.minimize("grid", func, lb, ub,
                   optim.make_settings("grid", {"points_per_dim": 5, "n_local": 1,
                                                "local_max_evals": 10}), 1)
    assert seen and all(t is None for t in seen)


def test_thresholds_reach_only_objectives_that_accept_them():
    calls = []

    def plain(Z):
        calls.append(Z.shape[0])
        return Z.sum(axis=1)

    counted = CountingObjective(plain, max_evals=5)
    assert not counted.cutoff
    np.testing.assert_array_equal(counted(np.ones((3, 2)), np.zeros(3)), [2.0, 2.0, 2.0])

    def keyword(Z, thresholds=None):
        calls.append(thresholds)
        return Z.sum(axis=1)

    keyword.accepts_thresholds = True
    counted = CountingObjective(keyword, max_evals=4)
    assert counted.cutoff
    counted(np.ones((3, 2)), np.array([1.0, 2.0, 3.0]))
    with pytest.raises(optim.base.BudgetExhaustedError):  # the budget cuts thresholds too
        counted(np.ones((3, 2)), np.array([4.0, 5.0, 6.0]))
    np.testing.assert_array_equal(calls[-1], [4.0])


def test_pso_thresholds_are_personal_bests():
    """Each particle's threshold is its personal best before the evaluation (inf first)."""
    log = []

    def func(Z, thresholds=None):
        cost = np.sum((Z - 0.3) ** 2, axis=1)
        log.append((cost, thresholds))
        return cost

    func.accepts_thresholds = True
    for name, opts in (("pso", {"n_particles": 5, "iters": 4}),
                       ("pso_matlab", {"swarm_size": 5, "max_iterations": 4})):
        log.clear()
        optim.minimize(name, func, np.zeros(2), np.ones(2), optim.make_settings(name, opts), 3)
        pbest = np.full(5, np.inf)
        for cost, thr in log:
            if thr is not None:
                np.testing.assert_array_equal(thr, pbest)
            pbest = np.minimum(pbest, cost)
        assert any(t is not None for _, t in log)


def test_de_thresholds_are_the_replaced_members_costs():
    """From the second generation, trial i's threshold is member i's cost."""
    from scipy.optimize import differential_evolution

    log = []

    def func(Z, thresholds=None):
        log.append(thresholds)
        return np.sum((Z - 0.3) ** 2, axis=1)

    func.accepts_thresholds = True
    settings = optim.make_settings("de", {"popsize": 3, "iters": 4, "polish": "none",
                                          "tol": 0.0})
    optim.minimize("de", func, np.zeros(2), np.ones(2), settings, 5)
    assert log[0] is None and log[1] is None  # initial population, first trials
    assert all(t is not None and t.shape == (6,) for t in log[2:])
    energies = []
    differential_evolution(lambda x: np.sum((x.T - 0.3) ** 2, axis=1), [(0, 1)] * 2,
                           maxiter=4, popsize=3, tol=0.0, mutation=(0.5, 1.0),
                           recombination=0.7, polish=False,
                           seed=np.random.default_rng(5), vectorized=True,
                           updating="deferred",
                           callback=lambda intermediate_result: energies.append(
                               np.array(intermediate_result.population_energies)))
    for thr, members in zip(log[2:], energies):
        np.testing.assert_array_equal(thr, members)
