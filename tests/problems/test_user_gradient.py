"""A user's cost with its own gradient (from_cost(..., gradient=...)): the same gradient
capability as problem=lqr — evaluate(gradient=True) against central differences, lbfgs
reaching the known optimum, a failing gradient as a reason."""

import numpy as np
import pytest

import penaltyrun
from penaltyrun.errors import ConfigError
from penaltyrun.problems import base

TARGET = np.array([[2.0, 0.8], [0.8, 1.0]])


def _cost(K):
    return float(np.sum((K - TARGET) ** 2))


def _grad(K):
    return {"K": 2.0 * (K - TARGET)}


def test_user_gradient_chains_through_the_map_like_a_built_in():
    prob = penaltyrun.from_cost(_cost, {"K": (2, (0.1, 10.0))}, gradient=_grad)
    assert base.gradient_support(prob) == ""
    z = np.array([1.5, 0.7, 0.4])  # givens: two eigenvalues, one angle
    out = penaltyrun.evaluate(prob, z=z.tolist(), param="givens", gradient=True)
    for i in range(z.size):
        e = np.zeros(z.size)
        e[i] = 1e-6
        cd = (penaltyrun.evaluate(prob, z=(z + e).tolist(), param="givens")["cost"]
              - penaltyrun.evaluate(prob, z=(z - e).tolist(), param="givens")["cost"]) / 2e-6
        assert out["grad"][i] == pytest.approx(cd, rel=1e-6)


def test_lbfgs_reaches_the_optimum_of_a_user_cost(tmp_path):
    # the gradient of this cost is one numpy expression like the cost: about one evaluation
    prob = penaltyrun.from_cost(_cost, {"K": (2, (0.1, 10.0))}, gradient=_grad,
                                gradient_cost=1.0)
    rec = penaltyrun.tune(prob, param="givens", optimizer="lbfgs",
                          optimizer_options={"starts": 2, "max_evals": 2000}, n_starts=1,
                          seed=1, workers=1, run_dir=tmp_path / "run").records.iloc[0]
    assert rec["best_cost"] < 1e-12 and rec["grad_norm"] < 1e-6
    assert rec["grad_cost"] == 1.0 and rec["n_gradients"] > 0


def test_a_cost_without_gradient_says_so_and_a_bad_gradient_is_a_reason():
    plain = penaltyrun.from_cost(_cost, {"K": (2, (0.1, 10.0))})
    assert "no gradient" in base.gradient_support(plain)
    bad = penaltyrun.from_cost(_cost, {"K": (2, (0.1, 10.0))},
                               gradient=lambda K: {"K": np.ones(3)})
    out = bad.gradient({"K": np.eye(2)})
    assert not out.exists and "2x2" in out.reason
    with pytest.raises(ConfigError, match="gradient"):
        penaltyrun.from_cost(_cost, {"K": (2, (0.1, 10.0))}, gradient=3)
