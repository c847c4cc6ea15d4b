"""What a gradient costs the budget: optimizer=lbfgs and polish=gradient charge each gradient
what the problem declares (``gradient_cost``), or ``optimizer.grad_cost`` when given; n_evals
is the evaluations plus charge × gradients, and the result says both."""

import numpy as np
import pytest

from penaltyrun import optim
from penaltyrun.errors import ConfigError
from penaltyrun.optim.gradient import z_gradient
from penaltyrun.problems import lqr
from penaltyrun.runner.setup import build, build_layout


def _discrete_plant():
    """A 2-state discrete plant: its declared charge, 2.5, is not a whole number."""
    rng = np.random.default_rng(5)
    A = np.eye(2) + 0.05 * rng.normal(size=(2, 2))
    return lqr.make_problem("default", {"A": A.tolist(), "B": (0.05 * rng.normal(size=(2, 1)))
                                        .tolist(), "dt": 0.05, "t_max": 10.0})


def _counted_run(prob, name, options, seed=3):
    """Run ``name`` with the problem's charge filled in; count values and gradients."""
    layout = build_layout(prob, "givens", {})
    lb, ub = layout.bounds()
    calls = {"values": 0, "grads": 0}

    def objective(Z):
        calls["values"] += len(Z)
        return prob.evaluate_batch(layout.split(Z)[0])

    def gradient(z):
        calls["grads"] += 1
        return z_gradient(prob, layout, z)

    settings = optim.with_gradient_cost(optim.make_settings(name, options), prob)
    return optim.minimize(name, objective, lb, ub, settings, seed, gradient=gradient), calls


def test_lbfgs_charges_the_declared_cost_and_n_evals_adds_it_up():
    prob = _discrete_plant()
    charge = prob.gradient_cost().evaluations
    assert charge == 2.5
    res, calls = _counted_run(prob, "lbfgs", {"starts": 2, "max_evals": 150})
    assert calls["grads"] > 0 and res.n_gradients == calls["grads"]
    assert res.grad_cost == charge
    # a fraction of an evaluation carries over to the next gradient's charge
    assert res.n_evals == calls["values"] + int(charge * calls["grads"])


def test_an_explicit_grad_cost_overrides_the_declaration():
    prob = lqr.make_problem("default", {})
    assert prob.gradient_cost().evaluations != 7.0
    res, calls = _counted_run(prob, "lbfgs", {"starts": 1, "max_evals": 80,
                                              "grad_cost": 7})
    assert res.grad_cost == 7.0
    assert res.n_evals == calls["values"] + 7 * calls["grads"]


def test_polish_gradient_is_charged_too():
    prob = lqr.make_problem("default", {})
    charge = prob.gradient_cost().evaluations
    res, calls = _counted_run(prob, "pso", {"max_evals": 100, "polish": "gradient",
                                            "polish_share": 0.5})
    assert "+polish" in res.stop_reason and res.n_evals <= 100
    assert res.n_gradients == calls["grads"] > 0 and res.grad_cost == charge
    assert res.n_evals == calls["values"] + int(charge * calls["grads"])
    override, _ = _counted_run(prob, "pso", {"max_evals": 60, "polish": "gradient",
                                             "polish_share": 0.5, "grad_cost": 3.5})
    assert override.grad_cost == 3.5


def test_a_run_without_gradients_charges_none():
    res, calls = _counted_run(lqr.make_problem("default", {}), "cmaes", {"max_evals": 60})
    assert res.n_gradients == calls["grads"] == 0 and res.grad_cost is None


@pytest.mark.parametrize("value", [0, -2, "fast", True, float("inf"), float("nan")])
def test_a_bad_grad_cost_is_one_line_naming_the_key(value):
    with pytest.raises(ConfigError, match="optimizer.grad_cost") as err:
        optim.make_settings("lbfgs", {"grad_cost": value})
    assert "\n" not in str(err.value)


def test_grad_cost_without_gradients_is_refused():
    with pytest.raises(ConfigError, match="optimizer.grad_cost.*polish=gradient"):
        optim.make_settings("cmaes", {"grad_cost": 3})
    assert optim.make_settings("cmaes", {"grad_cost": 3, "polish": "gradient"}).grad_cost == 3


def test_the_job_setup_fills_in_the_declared_charge():
    prob, _, settings = build("zermelo", None, {}, "givens", {}, "lbfgs", {})
    assert settings.grad_cost == prob.gradient_cost().evaluations
    assert optim.declared_gradient_cost(prob) == prob.gradient_cost()
    _, _, given = build("zermelo", None, {}, "givens", {}, "lbfgs", {"grad_cost": 1.5})
    assert given.grad_cost == 1.5
    _, _, plain = build("zermelo", None, {}, "givens", {}, "cmaes", {})
    assert plain.grad_cost is None  # no gradient used, nothing charged


def test_an_undeclared_cost_needs_grad_cost():
    import penaltyrun

    def cost(K):
        return float(np.sum((K - np.eye(2)) ** 2))

    def grad(K):
        return {"K": 2 * (K - np.eye(2))}

    prob = penaltyrun.from_cost(cost, {"K": (2, (0.1, 10.0))}, gradient=grad)
    settings = optim.make_settings("lbfgs", {"starts": 1})
    with pytest.raises(ConfigError, match="optimizer.grad_cost.*does not declare"):
        optim.with_gradient_cost(settings, prob)
    assert optim.with_gradient_cost(optim.make_settings("lbfgs", {"grad_cost": 2}),
                                    prob).grad_cost == 2
    with pytest.raises(ConfigError, match="optimizer.grad_cost"):  # the optimizer itself
        optim.minimize("lbfgs", lambda Z: np.zeros(len(Z)), np.zeros(2), np.ones(2), settings,
                       0, gradient=lambda z: None)
    declared = penaltyrun.from_cost(cost, {"K": (2, (0.1, 10.0))}, gradient=grad,
                                    gradient_cost=1.5)
    assert optim.with_gradient_cost(settings, declared).grad_cost == 1.5
    for bad in (0, -1.0, "x"):
        with pytest.raises(ConfigError, match="gradient_cost"):
            penaltyrun.from_cost(cost, {"K": (2, (0.1, 10.0))}, gradient=grad,
                                 gradient_cost=bad)
    with pytest.raises(ConfigError, match="gradient_cost.*needs gradient"):
        penaltyrun.from_cost(cost, {"K": (2, (0.1, 10.0))}, gradient_cost=2.0)


def test_records_say_what_was_charged(tmp_path):
    import penaltyrun

    prob = lqr.make_problem("default", {})
    rec = penaltyrun.tune("lqr", param="givens", optimizer="lbfgs",
                          optimizer_options={"starts": 1, "max_evals": 3000}, n_starts=1,
                          seed=4, workers=1, run_dir=tmp_path / "run").records.iloc[0]
    assert rec["grad_cost"] == prob.gradient_cost().evaluations
    assert rec["n_gradients"] > 0 and rec["n_evals"] >= rec["grad_cost"] * rec["n_gradients"]
