"""The shared criterion definitions (:mod:`penaltyrun.problems.criteria`) and multi-scenario
tuning under the new criteria."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun import problems as registry
from penaltyrun.errors import ConfigError
from penaltyrun.problems import criteria, multiscenario


def test_names_and_defaults():
    assert criteria.CRITERIA[0] == "deadline"
    assert criteria.CriterionParams().criterion == "deadline"
    for name in ("attitude_lyapunov", "attitude_lqr", "mpc_rendezvous", "lqr"):
        params = registry.module(name).Params()
        assert params.criterion == "deadline" and params.terminal_weight is None
        assert all(hasattr(params, key) for key in criteria.SETTINGS)


@settings(max_examples=50, deadline=None)
@given(st.integers(1, 6), st.integers(0, 2 ** 31 - 1))
def test_terminal_matrix_accepts_psd_and_diagonals(n, seed):
    rng = np.random.default_rng(seed)
    root = rng.normal(size=(n, max(1, n - 1)))
    S = root @ root.T
    assert np.allclose(criteria.terminal_matrix(S.tolist(), n, "k"), S, rtol=0, atol=1e-12)
    d = rng.uniform(0.0, 5.0, n)
    assert np.array_equal(criteria.terminal_matrix(d.tolist(), n, "k"), np.diag(d))
    x = rng.normal(size=(4, n))
    assert np.allclose(criteria.terminal_cost(x, S), np.einsum("ki,ij,kj->k", x, S, x))


@pytest.mark.parametrize("value,words", [
    ("abc", "expected 2 diagonal entries"), ([[1.0, 0.5], [0.0, 1.0]], "symmetric"),
    ([[1.0, 2.0], [2.0, 1.0]], "semidefinite"), ([1.0, float("nan")], "finite"),
    ([1.0, 2.0, 3.0], "shape (3,)"),
])
def test_terminal_matrix_errors_are_one_line(value, words):
    with pytest.raises(ConfigError) as err:
        criteria.terminal_matrix(value, 2, "problem.params.terminal_weight")
    assert str(err.value).startswith("problem.params.terminal_weight: ")
    assert words in str(err.value) and "\n" not in str(err.value)


def test_hashed_node_drops_only_unset_criterion_keys():
    node = {"name": "x", "params": {"criterion": None, "rho": 0.1, "t_max": None}}
    assert criteria.hashed_node(node) == {"name": "x", "params": {"rho": 0.1, "t_max": None}}
    assert node["params"]["criterion"] is None    # the input is not modified
    quantile = {"name": "x", "params": {"train_quantile": None, "train_aggregate": None}}
    assert criteria.hashed_node(quantile) == {"name": "x", "params": {"train_aggregate": None}}


def test_time_energy_and_terminal_values():
    assert criteria.time_energy_cost(2.0, 10.0, 0.5) == 7.0
    assert criteria.terminal_cost([1.0, 2.0], np.diag([1.0, 3.0])) == 13.0


@pytest.mark.parametrize("name,case,scenarios,criterion", [
    ("attitude_lyapunov", "rest_to_rest",
     [{}, {"attitude": (30.0, 20.0, 10.0)}], "time_energy"),
    ("attitude_lqr", "rest_to_rest", [{}, {"attitude": (30.0, 20.0, 10.0)}], "terminal"),
    ("mpc_rendezvous", "default", [{}, {"s0": (50.0, -500.0, 0.0, 0.0, 0.0, 0.0)}],
     "time_energy"),
    ("lqr", "default", [{}, {"x0": [[1.0, 1.0, 0.0]]}], "terminal"),
])
def test_multiscenario_aggregates_the_criterion(name, case, scenarios, criterion):
    mod = registry.module(name)
    multi = multiscenario.build(mod, case, {"criterion": criterion,
                                            "train_scenarios": scenarios})
    mats = {s.name: np.eye(s.size) * np.sqrt(s.eig_bounds[0] * s.eig_bounds[1])
            for s in multi.matrices}
    costs = [mod.make_problem(case, {"criterion": criterion, **sc}).evaluate(mats)["cost"]
             for sc in scenarios]
    assert multi.evaluate(mats)["cost"] == pytest.approx(np.mean(costs), rel=1e-12)
    assert multi.params.criterion == criterion


@pytest.mark.parametrize("name,deadline_label,unit", [
    ("attitude_lyapunov", "J = ∫½‖u‖² dt (N²·m²·s)", "N²·m²·s"),
    ("mpc_rendezvous", "Δv = Σ Tₛ‖u_k‖₂ (m/s)", "m²/s³"),
    ("lqr", "J = mean over x0 of ∫₀ᵀ (xᵀW_x x + uᵀW_u u) dt (weighted state² × time "
            "(user units))", "weighted state² × time (user units)"),
])
def test_reports_name_the_criterion(name, deadline_label, unit):
    from penaltyrun.problems import report_hooks

    mod = registry.module(name)
    assert report_hooks.info(mod, mod.DEFAULT_CASE, {}).cost_label == deadline_label
    free = report_hooks.info(mod, mod.DEFAULT_CASE, {"criterion": "time_energy", "rho": 0.5})
    fixed = report_hooks.info(mod, mod.DEFAULT_CASE, {"criterion": "terminal"})
    assert "ρ = 0.5" in free.cost_name and free.cost_unit == unit and free.paper is None
    assert "x(T)ᵀ S x(T)" in fixed.cost_name and fixed.paper is None
