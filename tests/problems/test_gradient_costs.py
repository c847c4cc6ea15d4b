"""Every built-in problem with a gradient declares what one gradient costs in evaluations
(``gradient_cost``), measured by a benchmark named in the declaration, and that is the
charge optimizer=lbfgs and polish=gradient use."""

from pathlib import Path

import numpy as np
import pytest

from penaltyrun import optim
from penaltyrun.problems import REGISTRY, criteria, gradient_costs, lqr, make
from penaltyrun.problems.base import GradientCost, gradient_support
from penaltyrun.problems.hooks import hooks

ROOT = Path(__file__).resolve().parents[2]


def _charge(prob):
    """The charge per gradient an lbfgs run and a polish=gradient run of ``prob`` use."""
    lbfgs = optim.with_gradient_cost(optim.make_settings("lbfgs", {}), prob).grad_cost
    polish = optim.with_gradient_cost(optim.make_settings("cmaes", {"polish": "gradient"}),
                                      prob).grad_cost
    assert lbfgs == polish
    return lbfgs


def _instances():
    """Every registered problem at its default case, under every criterion it has."""
    for name in REGISTRY:
        prob = make(name, None, {}, None)
        yield name, prob
        if getattr(getattr(prob, "params", None), "criterion", None) is not None:
            for crit in criteria.CRITERIA:
                if crit != prob.params.criterion:
                    yield f"{name}:{crit}", make(name, None, {"criterion": crit}, None)


@pytest.mark.parametrize(("label", "prob"), list(_instances()), ids=lambda v: str(v)[:40])
def test_each_problem_with_a_gradient_declares_its_cost_and_that_is_charged(label, prob):
    if gradient_support(prob):
        assert _charge(prob) is None  # nothing to charge: lbfgs is refused before any job
        return
    declared = prob.gradient_cost()
    assert isinstance(declared, GradientCost) and declared.evaluations > 0
    assert hooks(prob).gradient_cost is not None
    assert _charge(prob) == declared.evaluations
    # the source names the benchmark that measured it, and its table
    script = declared.source.split()[0]
    assert script.startswith("bench/") and (ROOT / script).is_file()
    assert "bench/README.md" in declared.source


@pytest.mark.parametrize(("params", "want"), [
    ({}, 4.0),  # the known-answer plant: 2 states, continuous
    ({"A": (-np.eye(12)).tolist(), "B": np.eye(12).tolist()}, 2.5),
    ({"A": (-np.eye(20)).tolist(), "B": np.eye(20).tolist()}, 2.0),
    ({"dt": 0.1, "A": (0.9 * np.eye(2)).tolist(), "B": [[0.1], [0.2]]}, 2.5),
])
def test_lqr_declares_by_plant_size_and_time(params, want):
    prob = lqr.make_problem("default", params)
    assert prob.gradient_cost().evaluations == want
    n = prob.plant.n_states
    table = gradient_costs.LQR_DISCRETE if prob.dt else gradient_costs.LQR_CONTINUOUS
    assert want == next(cost for largest, cost in table if n <= largest)


def test_declarations_follow_the_criterion_and_the_law():
    for crit in criteria.CRITERIA:
        mpc = make("mpc_rendezvous", None, {"criterion": crit}, None)
        assert mpc.gradient_cost().evaluations == gradient_costs.MPC[crit]
    for law in ("attitude_lyapunov", "attitude_lqr"):
        for crit in (criteria.TERMINAL, criteria.TIME_ENERGY):
            prob = make(law, None, {"criterion": crit}, None)
            assert prob.gradient_cost().evaluations == gradient_costs.ATTITUDE[law, crit]
    # a gradient costs more under time_energy (bounded steps near the arrival)
    for law in ("attitude_lyapunov", "attitude_lqr"):
        assert gradient_costs.ATTITUDE[law, criteria.TIME_ENERGY] > \
            2 * gradient_costs.ATTITUDE[law, criteria.TERMINAL]


def test_multi_scenario_training_charges_the_base_problems_cost():
    starts = [{"x0": (-8.0, 6.0)}, {"x0": (3.0, -4.0)}]
    prob = make("zermelo", None, {"train_scenarios": starts}, None)
    assert not gradient_support(prob)
    assert _charge(prob) == gradient_costs.ZERMELO


@pytest.mark.parametrize("value", [0, -1.0, float("nan"), float("inf"), "2", True])
def test_a_declaration_is_a_positive_number(value):
    with pytest.raises(ValueError, match="positive number of evaluations"):
        GradientCost(value)
