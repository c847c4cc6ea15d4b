"""penaltyrun.evaluate: the mode=evaluate dict, from names, modules and from_cost problems."""

from __future__ import annotations

import numpy as np
import pytest
from known_optimum import K_STAR

import penaltyrun
from penaltyrun.errors import ConfigError


def test_evaluate_a_cost_problem(quad):
    result = penaltyrun.evaluate(quad, {"K": K_STAR + 0.1 * np.eye(2)})
    assert result["cost"] == pytest.approx(0.02) and result["converged"] is True
    assert result["status"] == "converged" and result["error"] == ""


@pytest.mark.parametrize("matrices, key", [
    ({"X": np.eye(2)}, "matrices.X"),
    ({}, "matrices.K"),
    ({"K": np.eye(3)}, "matrices.K"),
    ({"K": [[1.0, 2.0], [2.0, 1.0]]}, "matrices.K"),
])
def test_bad_matrices_name_the_key(quad, matrices, key):
    with pytest.raises(ConfigError) as err:
        penaltyrun.evaluate(quad, matrices)
    assert err.value.key == key


@pytest.mark.parametrize("kwargs, key, words", [
    ({"matrices": np.eye(2)}, "matrices", "must be a mapping {'K': ...}"),
    ({"matrices": [[1.0, 0.0], [0.0, 1.0]]}, "matrices", "got a list"),
    ({"matrices": {"K": np.eye(2)}, "scalars": {"rho": "x"}}, "scalars.rho",
     "must be a number"),
    ({"matrices": {"K": np.eye(2)}, "scalars": {"rho": 0.5, "rh0": 0.9}}, "scalars.rh0",
     "not a scalar"),
    ({"matrices": {"K": np.eye(2)}, "scalars": [0.5]}, "scalars", "must be a mapping"),
    ({"matrices": None, "z": [1.0, 1.0, 0.1, 0.5], "param": "givens",
      "scalars": {"rho": 0.5}, "param_options": {"eig_bound": [0.5, 5.0]}},
     "param.eig_bound", "not an option"),
])
def test_malformed_candidates_are_one_config_error(kwargs, key, words):
    prob = penaltyrun.from_cost(lambda K, rho: float(np.sum(K) + rho), {"K": (2, (0.1, 10.0))},
                                scalars={"rho": (0.0, 1.0)})
    matrices = kwargs.pop("matrices")
    with pytest.raises(ConfigError) as err:
        penaltyrun.evaluate(prob, matrices, **kwargs)
    assert err.value.key == key and words in str(err.value) and "\n" not in str(err.value)


def test_problem_parameters_apply():
    base = penaltyrun.evaluate("zermelo", {"K": np.eye(2)})
    moved = penaltyrun.evaluate("zermelo", {"K": np.eye(2)}, params={"x0": [-4.0, 3.0]})
    assert moved["cost"] < base["cost"]
