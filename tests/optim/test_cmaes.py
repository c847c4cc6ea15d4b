"""IPOP-CMA-ES: budget, determinism, bounds, warm start, restarts, stopping rules."""

from __future__ import annotations

import numpy as np
import pytest

from penaltyrun.errors import ConfigError
from penaltyrun.optim import CMAESSettings, make_settings, minimize
from penaltyrun.optim.cmaes import run_cmaes

CENTER = np.array([0.3, -0.2, 0.5])
LB, UB = -np.ones(3), np.ones(3)


def sphere(Z):
    return ((Z - CENTER) ** 2).sum(axis=1)


def rastrigin(Z):
    D = 3.0 * (Z - CENTER)
    return 10 * D.shape[1] + (D**2 - 10 * np.cos(2 * np.pi * D)).sum(axis=1)


def test_finds_minimum_of_sphere():
    res = run_cmaes(sphere, LB, UB, CMAESSettings(max_evals=3000), seed=1)
    assert res.best_cost < 1e-10
    np.testing.assert_allclose(res.best_z, CENTER, atol=1e-5)


def test_same_seed_same_run_other_seed_other_run():
    s = CMAESSettings(max_evals=800)
    a = run_cmaes(rastrigin, LB, UB, s, seed=5)
    b = run_cmaes(rastrigin, LB, UB, s, seed=5)
    c = run_cmaes(rastrigin, LB, UB, s, seed=6)
    assert a.history == b.history and a.trace_evals == b.trace_evals
    np.testing.assert_array_equal(a.best_z, b.best_z)
    assert a.history != c.history


def test_budget_is_a_hard_cap_and_spent_by_restarts():
    # Rastrigin stops single runs early; IPOP restarts (doubling λ) spend the rest.
    res = run_cmaes(rastrigin, LB, UB, CMAESSettings(max_evals=2500, tolfun=1e-3), seed=2)
    assert res.n_evals == 2500
    assert res.stop_reason == "max_evals"
    assert res.trace_evals[-1] == 2500 and res.trace_best[-1] == res.best_cost


def test_restart_cap_without_budget():
    res = run_cmaes(sphere, LB, UB, CMAESSettings(restarts=1, tolfun=1e-6, tolx=1e-6), seed=3)
    assert res.stop_reason == "restarts" and res.n_evals > 0


def test_candidates_stay_in_the_box():
    seen = []

    def recorder(Z):
        seen.append(np.array(Z))
        return sphere(Z) + 5.0 * Z[:, 0]  # optimum pushed onto the lower bound of z0

    res = run_cmaes(recorder, LB, UB, CMAESSettings(max_evals=1500), seed=4)
    Z = np.concatenate(seen)
    assert np.all(Z >= LB) and np.all(Z <= UB)
    assert res.best_z[0] == pytest.approx(-1.0, abs=1e-3)


def test_warm_start_never_worse_than_x0():
    x0 = CENTER + 0.01
    res = minimize("cmaes", rastrigin, LB, UB, CMAESSettings(max_evals=50), seed=9, x0=x0)
    assert res.best_cost <= float(rastrigin(x0[None])[0])
    assert res.trace_evals[0] == 1  # x0 is evaluated first


@pytest.mark.parametrize(("options", "key"), [
    ({"sigma0": 0.0}, "optimizer.sigma0"),
    ({"sigma0": 2.0}, "optimizer.sigma0"),
    ({"popsize": 1}, "optimizer.popsize"),
    ({"incpopsize": 0.5}, "optimizer.incpopsize"),
    ({"restarts": -1}, "optimizer.restarts"),
    ({"max_evals": 0}, "optimizer.max_evals"),
    ({"polish": "newton"}, "optimizer.polish"),
    ({"polish_share": 1.0}, "optimizer.polish_share"),
])
def test_bad_settings_name_the_key(options, key):
    with pytest.raises(ConfigError) as info:
        make_settings("cmaes", options)
    assert info.value.key == key


def test_null_popsize_is_the_default():
    assert make_settings("cmaes", {"popsize": None}).popsize is None


def test_ipop_restarts_grow_the_population():
    sizes = []

    def recorder(Z):
        sizes.append(len(Z))
        return np.ones(len(Z))  # flat: every run stops on tolfun after one generation

    res = run_cmaes(recorder, LB, UB, CMAESSettings(restarts=3, popsize=5, incpopsize=2.0),
                    seed=1)
    assert sizes == [5, 10, 20, 40]
    assert res.stop_reason == "restarts" and res.n_evals == sum(sizes)


def test_runs_end_on_their_stopping_rules(caplog):
    with caplog.at_level("DEBUG", logger="penaltyrun.optim.cmaes"):
        res = run_cmaes(sphere, LB, UB, CMAESSettings(restarts=1, tolfun=1e-9, tolx=1e-12),
                        seed=3)
    stops = [r.getMessage() for r in caplog.records if "stopped on" in r.getMessage()]
    assert len(stops) == 2 and all("tolfun" in m for m in stops)
    assert res.best_cost < 1e-8


def test_global_random_state_is_never_used():
    np.random.seed(123)  # noqa: NPY002
    before = np.random.get_state()[1].copy()  # noqa: NPY002
    run_cmaes(rastrigin, LB, UB, CMAESSettings(max_evals=300), seed=5)
    np.testing.assert_array_equal(np.random.get_state()[1], before)  # noqa: NPY002
