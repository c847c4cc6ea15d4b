"""optim.planned_evals: the most evaluations one start can spend, checked against real runs
of every optimizer on a cheap objective (stall and convergence stops off, so the bound is
reached)."""

import numpy as np
import pytest

from penaltyrun import optim

LB, UB = -np.ones(3), np.ones(3)


def sphere(Z):
    return np.sum(np.asarray(Z) ** 2, axis=1)


@pytest.mark.parametrize(("name", "options", "expected"), [
    ("pso", {"n_particles": 7, "iters": 5, "ftol": 0.0, "ftol_iter": 1}, 7 * 5),
    ("pso_matlab", {"swarm_size": 6, "max_iterations": 4, "function_tolerance": 0.0},
     6 * (4 + 1)),
    ("pso_matlab", {"max_iterations": 2, "function_tolerance": 0.0}, 30 * (2 + 1)),
    ("de", {"popsize": 4, "iters": 3, "tol": 0.0, "polish": "none"}, 12 * (3 + 1)),
    ("grid", {"points_per_dim": 4, "n_local": 1, "local_max_evals": 10}, 4 ** 3 + 10),
    ("baseline", {}, 1),
])
def test_bound_is_what_a_run_spends(name, options, expected):
    settings = optim.make_settings(name, options)
    assert optim.planned_evals(settings, 3) == expected
    x0 = np.zeros(3) if name == "baseline" else None
    result = optim.minimize(name, sphere, LB, UB, settings, seed=1, x0=x0)
    if name == "grid":  # local searches may converge before their share
        assert result.n_evals <= expected
    else:
        assert result.n_evals == expected


def test_max_evals_caps_and_polish():
    pso = {"n_particles": 10, "iters": 50, "ftol": 0.0, "ftol_iter": 1}
    assert optim.planned_evals(optim.make_settings("pso", {**pso, "max_evals": 120}), 3) == 120
    assert optim.planned_evals(optim.make_settings("pso", {**pso, "max_evals": 10**6}),
                               3) == 500
    # an uncapped polish: only max_evals bounds the job
    polished = optim.make_settings("pso", {**pso, "polish": "L-BFGS-B", "max_evals": 900})
    assert optim.planned_evals(polished, 3) == 900
    assert optim.planned_evals(optim.make_settings("pso", {**pso, "polish": "L-BFGS-B"}),
                               3) is None
    result = optim.minimize("pso", sphere, LB, UB, polished, seed=2)
    assert result.n_evals <= 900


def test_cmaes_is_bounded_by_max_evals_only():
    assert optim.planned_evals(optim.make_settings("cmaes", {"max_evals": None}), 3) is None
    settings = optim.make_settings("cmaes", {"max_evals": 200})
    assert optim.planned_evals(settings, 3) == 200
    assert optim.minimize("cmaes", sphere, LB, UB, settings, seed=3).n_evals == 200


def test_default_pso_matlab_sizes_follow_dimension():
    settings = optim.make_settings("pso_matlab", {})
    assert optim.planned_evals(settings, 15) == 100 * (200 * 15 + 1)
