"""Problem parameters of the wrong kind (text for numbers, a number for a list) are one
clear error when the problem is built, not a failure deep inside an evaluation."""

import pytest

from penaltyrun.errors import ConfigError
from penaltyrun.problems import make as make_problem


@pytest.mark.parametrize(("problem", "params", "fragment"), [
    ("zermelo", {"x0": "far"}, "problem.params.x0: expected a list"),
    ("zermelo", {"x0": ["a", "b"]}, "problem.params.x0: expected a list of numbers"),
    ("zermelo", {"x0": 3.0}, "problem.params.x0: expected a list"),
    ("zermelo", {"t_max": "long"}, "problem.params.t_max: expected a number"),
    ("attitude_lqr", {"inertia": [[10.0, "x", 0.5], [1, 15, 0], [0.5, 0, 20]]},
     "problem.params.inertia: expected a list of numbers"),
])
def test_parameters_of_the_wrong_kind_are_refused(problem, params, fragment):
    with pytest.raises(ConfigError, match=fragment):
        make_problem(problem, "default" if problem == "zermelo" else "detumble", params)


def test_numbers_and_nested_lists_of_numbers_are_taken():
    prob = make_problem("attitude_lqr", "detumble",
                        {"inertia": [[10.0, 1.0, 0.5], [1.0, 15.0, -0.7], [0.5, -0.7, 20.0]]})
    assert prob is not None
    assert make_problem("zermelo", "default", {"x0": [1, 2], "t_max": 5}) is not None
