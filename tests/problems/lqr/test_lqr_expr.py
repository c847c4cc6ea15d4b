"""The plant YAML's arithmetic (penaltyrun/problems/lqr/expr.py): values, refusals, and a
property on random expressions against a value computed alongside the text."""

import math
import operator

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun.errors import ConfigError
from penaltyrun.problems import lqr
from penaltyrun.problems.lqr import expr

NAMES = {"r": 0.3, "J": 2.5, "g": 9.81}


@pytest.mark.parametrize("text, value", [
    ("r/J", 0.3 / 2.5), ("-g/J*cos(pi/6)", -9.81 / 2.5 * math.cos(math.pi / 6)),
    ("2**-3", 0.125), ("-(1+2)*3", -9.0), ("sqrt(J)**2", 2.5), ("+r", 0.3),
    ("atan2(1, 1)", math.pi / 4), ("abs(-r)", 0.3), ("1e-3", 1e-3), ("exp(log(J))", 2.5),
])
def test_allowed_arithmetic(text, value):
    assert expr.evaluate(text, NAMES, "k") == pytest.approx(value, rel=1e-15)


@pytest.mark.parametrize("text, words", [
    ("r.real", "Attribute"), ("().__class__", "Attribute"),
    ("__import__('os')", "not an allowed function"), ("open('x')", "not an allowed function"),
    ("eval('1')", "not an allowed function"), ("math.sqrt(2)", "not an allowed function"),
    ("sqrt(x=2)", "positional"), ("sqrt(*[4])", "positional"),
    ("[1][0]", "Subscript"), ("(lambda: 1)()", "not an allowed function"), ("lambda: 1", "Lambda"),
    ("q/2", "'q' is not defined"), ("'a'", "not a number"), ("True", "not a number"),
    ("1 < 2", "Compare"), ("1/0", "division by zero"), ("10.0**400", "out of range"),
    ("2**5000", "exponent"), ("(-8)**(1/3)", "not a real number"), ("sqrt(-1)", "sqrt"),
    ("1 +", "cannot parse"), ("r if J else g", "IfExp"), ("r // J", "BinOp"),
])
def test_refusals_name_the_key(text, words):
    with pytest.raises(ConfigError) as err:
        expr.evaluate(text, NAMES, "problem.params.A")
    assert err.value.key == "problem.params.A" and words in str(err.value)


@pytest.mark.parametrize("text", ["-" * 999 + "1", "(" * 300 + "1" + ")" * 300, "x" * 1001])
def test_pathological_text_is_a_config_error(text):
    with pytest.raises(ConfigError):
        expr.evaluate(text, NAMES, "k")


def test_constants_build_on_each_other_and_reach_every_numeric_key():
    prob = lqr.make_problem("default", {
        "constants": {"J": 4.0, "b": "J/8", "w": "sqrt(J)"},
        "A": [[0, 1], [0, "-b/J"]], "B": [[0], ["1/J"]], "t_max": "5*w",
        "x0": [["w/2", 0]], "u_max": "J", "q_bounds": ["1/J", "J**2"]})
    np.testing.assert_array_equal(prob.plant.A, [[0, 1], [0, -0.125]])
    np.testing.assert_array_equal(prob.plant.B, [[0], [0.25]])
    assert prob.t_max == 10.0 and prob.x0.tolist() == [[1.0, 0.0]]
    assert prob.u_max.tolist() == [4.0] and prob.matrices[0].eig_bounds == (0.25, 16.0)
    assert dict(prob.params.constants) == {"J": 4.0, "b": 0.5, "w": 2.0}


@pytest.mark.parametrize("constants, key", [
    ({"b": "J/8", "J": 4.0}, "problem.params.constants.b"),
    ({"sqrt": 1.0}, "problem.params.constants.sqrt"),
    ({"2x": 1.0}, "problem.params.constants.2x"),
])
def test_bad_constants(constants, key):
    with pytest.raises(ConfigError) as err:
        lqr.make_problem("default", {"constants": constants, "A": [[0]], "B": [[1]]})
    assert err.value.key == key


def test_names_are_not_read_from_python():
    with pytest.raises(ConfigError, match="'np' is not defined"):
        lqr.make_problem("default", {"A": [["np"]], "B": [[1]]})


_OPS = {"+": operator.add, "-": operator.sub, "*": operator.mul, "/": operator.truediv}


def _trees(leaves):
    def extend(children):
        binary = st.tuples(children, st.sampled_from(sorted(_OPS)), children).map(
            lambda t: (f"({t[0][0]} {t[1]} {t[2][0]})", _apply(t[1], t[0][1], t[2][1])))
        unary = children.map(lambda c: (f"-{c[0]}", None if c[1] is None else -c[1]))
        root = children.filter(lambda c: c[1] is not None and c[1] >= 0).map(
            lambda c: (f"sqrt({c[0]})", math.sqrt(c[1])))
        return binary | unary | root
    return st.recursive(leaves, extend, max_leaves=12)


def _apply(op, a, b):
    if a is None or b is None or (op == "/" and b == 0):
        return None
    return _OPS[op](a, b)


LEAVES = (st.floats(-1e3, 1e3, allow_nan=False).map(lambda x: (repr(x), x))
          | st.sampled_from(sorted(NAMES)).map(lambda k: (k, NAMES[k]))
          | st.just(("pi", math.pi)))


@settings(max_examples=300, deadline=None)
@given(tree=_trees(LEAVES))
def test_random_arithmetic_matches_its_value(tree):
    text, value = tree
    if value is None or not math.isfinite(value):
        with pytest.raises(ConfigError):
            expr.evaluate(text, NAMES, "k")
        return
    assert expr.evaluate(text, NAMES, "k") == value  # same operations, same order: exact
