"""Problems from a user's cost function (penaltyrun.problems.user_cost.from_cost)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from penaltyrun import problems
from penaltyrun.errors import ConfigError
from penaltyrun.problems.base import Problem
from penaltyrun.problems.user_cost import FAILURE_COST, from_cost

K_STAR = np.array([[2.0, 0.8], [0.8, 1.0]])


def _cost(K, eta=0.0):
    return float(np.sum((K - K_STAR) ** 2)) + eta


def _batched(K, eta):
    return np.sum((K - K_STAR) ** 2, axis=(1, 2)) + eta


def _candidates(n=5, seed=0):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, 2, 2))
    return A @ A.transpose(0, 2, 1) + 0.5 * np.eye(2)


def test_follows_the_problem_protocol():
    prob = from_cost(_cost, {"K": (2, (0.1, 10.0))}, scalars={"eta": (0.0, 1.0)})
    assert isinstance(prob, Problem)
    assert prob.matrices[0].name == "K" and prob.matrices[0].size == 2
    assert prob.matrices[0].eig_bounds == (0.1, 10.0)
    assert prob.scalars[0].bounds == (0.0, 1.0)
    assert prob.name == "user" and prob.case == "default"


def test_batched_and_one_by_one_give_the_same_costs():
    K = _candidates()
    eta = np.linspace(0.0, 1.0, len(K))
    one = from_cost(_cost, {"K": (2, (0.1, 10.0))}, scalars={"eta": (0.0, 1.0)})
    many = from_cost(_batched, {"K": (2, (0.1, 10.0))}, scalars={"eta": (0.0, 1.0)},
                     batched=True)
    a = one.evaluate_batch({"K": K}, {"eta": eta})
    b = many.evaluate_batch({"K": K}, {"eta": eta})
    expected = [np.sum((k - K_STAR) ** 2) + e for k, e in zip(K, eta)]
    np.testing.assert_allclose(a.cost, expected, rtol=1e-14)
    np.testing.assert_allclose(b.cost, expected, rtol=1e-14)
    assert a.converged.all() and list(b.status) == ["converged"] * len(K)
    assert one.evaluate({"K": K_STAR}, {"eta": 0.25})["cost"] == pytest.approx(0.25)


def test_raising_and_nonfinite_candidates_are_statuses():
    def cost(K):
        if K[0, 0] > 5:
            raise ValueError("too stiff")
        if K[1, 1] > 5:
            return math.nan
        return float(np.trace(K))

    prob = from_cost(cost, {"K": (2, (0.1, 10.0))})
    K = np.array([np.eye(2), np.diag([6.0, 1.0]), np.diag([1.0, 6.0]), 2 * np.eye(2)])
    res = prob.evaluate_batch({"K": K})
    assert list(res.status) == ["converged", "error", "nonfinite", "converged"]
    assert list(res.cost) == [2.0, FAILURE_COST, FAILURE_COST, 4.0]
    assert np.isfinite(res.cost).all()
    detail = prob.evaluate({"K": np.diag([6.0, 1.0])})
    assert detail["status"] == "error" and "ValueError: too stiff" in detail["error"]
    assert detail["converged"] is False


def test_a_raising_batch_is_evaluated_candidate_by_candidate():
    def cost(K):
        if np.any(K[:, 0, 0] > 5):
            raise ValueError("one bad candidate spoils the batch")
        return np.trace(K, axis1=1, axis2=2)

    prob = from_cost(cost, {"K": (2, (0.1, 10.0))}, batched=True)
    res = prob.evaluate_batch({"K": np.array([np.eye(2), np.diag([6.0, 1.0])])})
    assert list(res.status) == ["converged", "error"]
    assert list(res.cost) == [2.0, FAILURE_COST]


@pytest.mark.parametrize("kwargs, key", [
    ({"cost": 3, "matrices": {"K": (2, (0.1, 1.0))}}, "cost"),
    ({"cost": _cost, "matrices": {}}, "matrices"),
    ({"cost": _cost, "matrices": {"K": (0, (0.1, 1.0))}}, "matrices.K"),
    ({"cost": _cost, "matrices": {"K": (2, (0.0, 1.0))}}, "matrices.K"),
    ({"cost": _cost, "matrices": {"K": (2, (2.0, 1.0))}}, "matrices.K"),
    ({"cost": _cost, "matrices": {"K": 2}}, "matrices.K"),
    ({"cost": _cost, "matrices": {"K": (2, (0.1, 1.0))}, "scalars": {"K": (0, 1)}},
     "scalars.K"),
    ({"cost": _cost, "matrices": {"K": (2, (0.1, 1.0))}, "name": "my cost"}, "name"),
])
def test_bad_input_is_one_config_error(kwargs, key):
    cost = kwargs.pop("cost")
    matrices = kwargs.pop("matrices")
    with pytest.raises(ConfigError) as err:
        from_cost(cost, matrices, **kwargs)
    assert err.value.key == key


def test_held_problem_is_served_by_the_registry_only_while_held():
    prob = from_cost(_cost, {"K": (2, (0.1, 10.0))}, name="heldcost")
    with problems.hold(prob) as path:
        assert path == "object:heldcost"
        assert problems.make("heldcost", None, {}, path) is prob
        with pytest.raises(ConfigError, match="takes no parameters"):
            problems.make("heldcost", None, {"x": 1}, path)
        other = from_cost(_cost, {"K": (2, (0.1, 10.0))}, name="heldcost")
        with pytest.raises(ConfigError, match="another in-memory problem"):
            with problems.hold(other):
                pass
    with pytest.raises(ConfigError, match="exists only in the Python process"):
        problems.make("heldcost", None, {}, "object:heldcost")
