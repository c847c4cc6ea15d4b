"""penaltyrun.typed: "an integer" / "a number" never takes a bool, and is written once."""

from __future__ import annotations

import ast
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import penaltyrun
from penaltyrun.typed import is_int, is_number

PACKAGE = Path(penaltyrun.__file__).parent


@pytest.mark.parametrize("flag", [False, True])
def test_a_bool_is_neither_an_integer_nor_a_number(flag):
    for value in (True, False, np.bool_(True)):
        assert not is_int(value, any_integral=flag)
        assert not is_number(value, any_real=flag)


@given(st.integers())
def test_every_python_int_is_an_integer_and_a_number(n):
    assert is_int(n) and is_number(n)
    assert is_int(n, any_integral=True) and is_number(n, any_real=True)


@given(st.floats(allow_nan=True, allow_infinity=True))
def test_every_float_is_a_number_not_an_integer(x):
    assert is_number(x) and is_number(np.float64(x))
    assert not is_int(x) and not is_int(x, any_integral=True)


def test_numpy_scalars_count_only_when_asked():
    assert not is_int(np.int64(3)) and is_int(np.int64(3), any_integral=True)
    assert not is_number(np.float32(1.5)) and is_number(np.float32(1.5), any_real=True)
    assert not is_number(np.int32(2)) and is_number(np.int32(2), any_real=True)
    assert is_number(Fraction(1, 3), any_real=True) and not is_number(Fraction(1, 3))


@pytest.mark.parametrize("value", ["3", None, [1], 1 + 2j, {"a": 1}])
def test_other_values_are_refused(value):
    assert not is_int(value) and not is_int(value, any_integral=True)
    assert not is_number(value) and not is_number(value, any_real=True)


def _isinstance_of(node: ast.AST) -> set[str]:
    """Names of the types ``node`` (``isinstance(x, T)``, possibly negated) checks."""
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
        node = node.operand
    if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
            and node.func.id == "isinstance" and len(node.args) == 2):
        return set()
    return {n.id if isinstance(n, ast.Name) else n.attr for n in ast.walk(node.args[1])
            if isinstance(n, (ast.Name, ast.Attribute))}


def int_checks_by_hand(source: str) -> list[int]:
    """Lines where ``source`` checks "an int / a number but not a bool" itself: one
    ``and`` / ``or`` of an ``isinstance(..., bool)`` and an ``isinstance`` of a number type."""
    numeric = {"int", "float", "Real", "Integral", "integer", "floating", "Number"}
    lines = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.BoolOp):
            kinds = [_isinstance_of(v) for v in node.values]
            if {"bool"} in kinds and any(k & numeric for k in kinds):
                lines.append(node.lineno)
    return lines


def test_the_scan_finds_a_hand_written_check():
    assert int_checks_by_hand("ok = isinstance(v, bool) or not isinstance(v, int)") == [1]
    assert int_checks_by_hand("ok = isinstance(v, Real) and not isinstance(v, bool)") == [1]
    assert int_checks_by_hand("ok = isinstance(v, (int, np.integer)) and v > 0") == []
    assert int_checks_by_hand("ok = isinstance(v, bool) or v == 'auto'") == []
    assert int_checks_by_hand("ok = v is None or isinstance(v, (bool, int, str))") == []


def test_no_module_checks_int_but_not_bool_by_hand():
    found = [f"{path.relative_to(PACKAGE.parent)}:{line}"
             for path in sorted(PACKAGE.rglob("*.py")) if path.name != "typed.py"
             for line in int_checks_by_hand(path.read_text(encoding="utf-8"))]
    assert found == [], f"use penaltyrun.typed.is_int / is_number instead: {found}"
