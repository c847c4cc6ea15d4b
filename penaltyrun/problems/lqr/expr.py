"""Arithmetic in the plant YAML: a safe resolver for strings such as ``"r/J"`` or
``"-g/l*cos(theta0)"``.

An expression is parsed with :func:`ast.parse` (``mode="eval"``) and evaluated by walking
the tree; nothing is ever passed to ``eval``. Allowed:

* numbers (int, float), the names in ``constants`` (a mapping given in the YAML, each value
  a number or an expression over the names defined before it) and :data:`NAMES`;
* binary ``+ - * / **``, unary ``-`` and ``+``, parentheses;
* calls of the functions in :data:`FUNCTIONS` with positional arguments.

Everything else (attribute access, subscripts, comparisons, lambdas, keyword arguments,
calls of anything not whitelisted, undefined names, strings) is refused with a
:class:`~penaltyrun.errors.ConfigError` naming the key; so is a result that is not a finite
number (a division by zero, an overflow).
"""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Callable, Mapping
from typing import Any

from penaltyrun.errors import ConfigError
from penaltyrun.typed import is_number

#: Functions an expression may call (one or two positional arguments).
FUNCTIONS: dict[str, Callable[..., float]] = {
    "sqrt": math.sqrt, "sin": math.sin, "cos": math.cos, "tan": math.tan,
    "exp": math.exp, "log": math.log, "abs": abs, "atan2": math.atan2,
}
#: Constants every expression knows.
NAMES: dict[str, float] = {"pi": math.pi, "e": math.e}
#: Largest |exponent| of ``**`` (keeps ``10**10**10`` from running for minutes).
MAX_EXPONENT = 1024
_BINARY: dict[type, Callable[[Any, Any], Any]] = {
    ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
    ast.Div: operator.truediv, ast.Pow: operator.pow,
}
_UNARY: dict[type, Callable[[Any], Any]] = {ast.USub: operator.neg, ast.UAdd: operator.pos}
_MAX_LENGTH = 1000


def _walk(node: ast.AST, names: Mapping[str, float], key: str, text: str) -> float:
    def refuse(what: str) -> ConfigError:
        return ConfigError(key, f"cannot evaluate {text!r}: {what} (allowed: numbers, names "
                           "defined in constants, + - * / **, parentheses, "
                           f"{', '.join(sorted(FUNCTIONS))}, {', '.join(sorted(NAMES))})")

    if isinstance(node, ast.Constant):
        if not is_number(node.value):
            raise refuse(f"{node.value!r} is not a number")
        return float(node.value)
    if isinstance(node, ast.Name):
        if node.id in names:
            return names[node.id]
        if node.id in NAMES:
            return NAMES[node.id]
        raise refuse(f"name {node.id!r} is not defined (define it under constants)")
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        left = _walk(node.left, names, key, text)
        right = _walk(node.right, names, key, text)
        if isinstance(node.op, ast.Pow) and abs(right) > MAX_EXPONENT:
            raise refuse(f"exponent {right!r} is larger than {MAX_EXPONENT}")
        try:
            value = _BINARY[type(node.op)](left, right)
        except (ZeroDivisionError, OverflowError, ValueError) as exc:
            raise refuse(str(exc)) from None
        if isinstance(value, complex):
            raise refuse(f"{left!r} ** {right!r} is not a real number")
        return value
    if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
        return _UNARY[type(node.op)](_walk(node.operand, names, key, text))
    if isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
            what = ast.unparse(node.func)
            raise refuse(f"{what!r} is not an allowed function")
        if node.keywords or any(isinstance(a, ast.Starred) for a in node.args):
            raise refuse("only positional arguments are allowed")
        args = [_walk(a, names, key, text) for a in node.args]
        try:
            return FUNCTIONS[node.func.id](*args)
        except (TypeError, ValueError, OverflowError) as exc:
            raise refuse(f"{node.func.id}: {exc}") from None
    raise refuse(f"{type(node).__name__} is not allowed")


def evaluate(text: str, names: Mapping[str, float], key: str) -> float:
    """The value of one expression.

    Parameters
    ----------
    text : str
        The expression, e.g. ``"r/J"``.
    names : mapping of str to float
        Defined names (the resolved ``constants``).
    key : str
        Config key named in errors.

    Raises
    ------
    ConfigError
        Syntax errors, anything outside the allowed grammar, undefined names, and results
        that are not finite real numbers.
    """
    if len(text) > _MAX_LENGTH:
        raise ConfigError(key, f"expression longer than {_MAX_LENGTH} characters")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except RecursionError:
        raise ConfigError(key, f"expression nested too deeply: {text[:40]!r}...") from None
    except SyntaxError as exc:
        raise ConfigError(key, f"cannot parse {text!r} as arithmetic ({exc.msg}); quote "
                          "expressions in YAML, e.g. \"r/J\"") from None
    try:
        value = _walk(tree.body, names, key, text)
    except RecursionError:
        raise ConfigError(key, f"expression nested too deeply: {text[:40]!r}...") from None
    if isinstance(value, complex) or not math.isfinite(value):
        raise ConfigError(key, f"{text!r} evaluates to {value!r}, not a finite real number")
    return float(value)


def resolve_constants(constants: Mapping[str, Any] | None, key: str) -> dict[str, float]:
    """``constants`` as numbers, each expression over the names defined before it.

    Raises
    ------
    ConfigError
        A name that is not an identifier or shadows a function or built-in constant, or a
        value that is neither a number nor a valid expression.
    """
    names: dict[str, float] = {}
    if constants is None:
        return names
    if not isinstance(constants, Mapping):
        raise ConfigError(key, f"need a mapping name: value, got {constants!r}")
    for name, value in constants.items():
        if not isinstance(name, str) or not name.isidentifier() or name in FUNCTIONS \
                or name in NAMES:
            raise ConfigError(f"{key}.{name}", "not a usable name (an identifier that is not "
                              f"one of {', '.join(sorted({*FUNCTIONS, *NAMES}))})")
        names[name] = resolve_value(value, names, f"{key}.{name}")
    return names


def resolve_value(value: Any, names: Mapping[str, float], key: str) -> Any:
    """``value`` with every string (also inside nested lists) replaced by its number;
    numbers, ``None`` and booleans pass unchanged."""
    if isinstance(value, str):
        return evaluate(value, names, key)
    if isinstance(value, (list, tuple)):
        return type(value)(resolve_value(v, names, key) for v in value)
    if isinstance(value, Mapping):
        raise ConfigError(key, f"need a number or a list, got a mapping {dict(value)!r}")
    return value


__all__ = ["FUNCTIONS", "MAX_EXPONENT", "NAMES", "evaluate", "resolve_constants",
           "resolve_value"]
