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


def test_problem_parameters_apply():
    base = penaltyrun.evaluate("zermelo", {"K": np.eye(2)})
    moved = penaltyrun.evaluate("zermelo", {"K": np.eye(2)}, params={"x0": [-4.0, 3.0]})
    assert moved["cost"] < base["cost"]
