"""Build the problem, decision layout and optimizer settings of a job (validated)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, TypeVar

from penaltyrun import optim, penalty, problems
from penaltyrun.errors import ConfigError
from penaltyrun.penalty.layout import DecisionLayout
from penaltyrun.problems.base import Problem

T = TypeVar("T")


def build_layout(problem: Problem, param: str, options: Mapping[str, Any]) -> DecisionLayout:
    """Decision layout: every matrix of ``problem`` parameterized by ``param``.

    ``options["eig_bounds"]`` (if not None) overrides the problem's eigenvalue bounds.
    """
    specs = []
    for spec in problem.matrices:
        bounds = options.get("eig_bounds") or spec.eig_bounds
        if len(bounds) != 2:
            raise ConfigError("param.eig_bounds", "expected [lower, upper]")
        specs.append((spec.name, penalty.make(param, spec.size, tuple(bounds),
                                              options.get("cayley_bound", 100.0))))
    scalars = [(s.name, s.bounds) for s in problem.scalars]
    return DecisionLayout(tuple(specs), tuple(scalars))


def build(problem: str, case: str | None, problem_params: Mapping[str, Any], param: str,
          param_options: Mapping[str, Any], optimizer: str,
          optimizer_options: Mapping[str, Any], problem_module: str | None = None
          ) -> tuple[Problem, DecisionLayout, Any]:
    """Validate and build (problem instance, decision layout, optimizer settings).

    ``problem_module`` names the module of a problem outside penaltyrun (a problem
    config's ``module:``; see :func:`penaltyrun.problems.module`).

    The settings of an optimizer or polish that uses the exact gradient charge what the
    problem declares one gradient to cost unless ``optimizer.grad_cost`` is given
    (:func:`penaltyrun.optim.with_gradient_cost`).

    Raises
    ------
    ConfigError
        On any invalid name or value, naming the key; also a grid optimizer whose grid
        does not fit the decision dimension (:func:`penaltyrun.optim.check_dimension`), and
        a gradient charge neither given nor declared by the problem.
    """
    settings = optim.make_settings(optimizer, optimizer_options)
    if param not in penalty.KINDS:
        raise ConfigError("param", f"unknown parameterization {param!r}",
                          allowed=penalty.KINDS)
    prob = checked("problem.params", problems.make, problem, case, problem_params,
                   problem_module)
    layout = checked("param", build_layout, prob, param, param_options)
    optim.check_dimension(settings, layout.dim)
    return prob, layout, optim.with_gradient_cost(settings, prob)


def checked(key: str, func: Callable[..., T], *args: Any) -> T:
    """``func(*args)``; an error other than ConfigError (a problem's or a map's own
    ``TypeError``, ``ValueError``, ``KeyError``, ``IndexError`` on a bad value) becomes one
    ConfigError on ``key``."""
    try:
        return func(*args)
    except ConfigError:
        raise
    except (TypeError, ValueError, KeyError, IndexError) as exc:
        text = " ".join(str(exc).split()) or type(exc).__name__
        raise ConfigError(key, f"invalid value: {text}") from None
