"""The gradient of the cost with respect to the optimizer's variables z, and first-order
measures at a point of the box.

The chain rule: a problem with the ``gradient`` hook
(:class:`~penaltyrun.problems.base.GradientProblem`) gives d cost / d M for each tuned
matrix M; each matrix's parameterization pulls it back to its block of z by its exact
vector-Jacobian product (:meth:`~penaltyrun.penalty.maps.Parameterization.vjp`), and a
scalar's derivative is its own entry. Where the problem has no gradient, or the map none
(GEAGSP next to a skipped Gram–Schmidt vector), the result carries the reason instead.

The charge of a gradient: a problem may declare what one gradient costs in evaluations
(:class:`~penaltyrun.problems.base.GradientCost`, its ``gradient_cost`` hook);
:func:`with_gradient_cost` makes that the ``grad_cost`` of settings that use gradients
unless ``optimizer.grad_cost`` is given.

First-order measures in a box [lb, ub]: the projected gradient
P(z) = clip(z − g, lb, ub) − z (zero exactly at a first-order stationary point of the
bounded problem), its infinity norm, and the bounds a coordinate sits on (within
:data:`BOUND_TOL` of the side).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, TypeVar

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.optim.base import missing_gradient_charge
from penaltyrun.penalty import DecisionLayout, NotDifferentiableError
from penaltyrun.problems.base import CostGradient, GradientCost, gradient_support
from penaltyrun.problems.hooks import hooks

S = TypeVar("S")

#: A coordinate within this fraction of its box side of a bound is on that bound.
BOUND_TOL = 1e-10


@dataclass(frozen=True)
class ZGradient:
    """d cost / d z at one decision vector, or why it does not exist.

    Attributes
    ----------
    cost : float
        The candidate's cost.
    status : str
        The candidate's status (``""`` when the problem has no gradient hook).
    grad : ndarray, shape (dim,), or None
        d cost / d z in the layout's order (``z_names``); None when it does not exist.
    reason : str
        Why there is no gradient; empty when there is one.
    """

    cost: float
    status: str
    grad: np.ndarray | None
    reason: str = ""

    @property
    def exists(self) -> bool:
        """Whether the gradient exists at this point."""
        return self.grad is not None


def z_gradient(problem: Any, layout: DecisionLayout, z: np.ndarray) -> ZGradient:
    """The cost of ``problem`` at z and its gradient d cost / d z.

    Parameters
    ----------
    problem : Problem
        A problem; without the ``gradient`` hook the result says so.
    layout : DecisionLayout
        The decision layout (maps of the matrices, scalars).
    z : ndarray, shape (dim,)

    Returns
    -------
    ZGradient
    """
    z = np.asarray(z, dtype=float).reshape(-1)
    support = gradient_support(problem)
    if support:
        return ZGradient(float("nan"), "", None, support)
    mats, scalars = layout.split(z[None])
    one = {name: value[0] for name, value in mats.items()}
    given = {name: float(value[0]) for name, value in scalars.items()} or None
    return chain(layout, z, problem.gradient(one, given))


def chain(layout: DecisionLayout, z: np.ndarray, out: CostGradient) -> ZGradient:
    """d cost / d z from the problem's gradient ``out`` at the matrices of z: each matrix
    block through its map's VJP, each scalar its own entry."""
    z = np.asarray(z, dtype=float).reshape(-1)
    if not out.exists:
        return ZGradient(float(out.cost), str(out.status), None, out.reason)
    parts = []
    pos = 0
    try:
        for name, param in layout.matrices:
            parts.append(param.vjp(z[pos:pos + param.dim], np.asarray(out.matrices[name])))
            pos += param.dim
    except NotDifferentiableError as exc:
        return ZGradient(float(out.cost), str(out.status), None,
                         f"the {param.kind} map of {name} is not differentiable here ({exc})")
    parts.append(np.asarray([float((out.scalars or {})[name]) for name, _ in layout.scalars]))
    grad = np.concatenate(parts)
    if not np.all(np.isfinite(grad)):
        return ZGradient(float(out.cost), str(out.status), None, "non-finite gradient")
    return ZGradient(float(out.cost), str(out.status), grad, "")


def declared_gradient_cost(problem: Any) -> GradientCost | None:
    """What ``problem`` declares one exact gradient to cost (its ``gradient_cost`` hook), or
    None when it declares nothing (no hook, or the hook returns None).

    Raises
    ------
    ConfigError
        The hook returns something other than a :class:`GradientCost`.
    """
    hook = hooks(problem).gradient_cost
    if hook is None:
        return None
    found = hook()
    if found is not None and not isinstance(found, GradientCost):
        name = getattr(problem, "name", type(problem).__name__)
        raise ConfigError("problem", f"{name}.gradient_cost() must return a GradientCost, got "
                                     f"{type(found).__name__}")
    return found


def with_gradient_cost(settings: S, problem: Any) -> S:
    """``settings`` with ``grad_cost`` set to the problem's declared cost of one gradient
    when they use gradients (``optimizer=lbfgs``, ``polish=gradient``) and do not set it;
    otherwise unchanged (also when the problem has no gradient: that is refused elsewhere).

    Raises
    ------
    ConfigError
        The settings use gradients, set no ``grad_cost`` and the problem declares none.
    """
    if not getattr(settings, "uses_gradient", False) or settings.grad_cost is not None \
            or gradient_support(problem):
        return settings
    declared = declared_gradient_cost(problem)
    if declared is None:
        raise missing_gradient_charge(getattr(problem, "name", type(problem).__name__))
    return replace(settings, grad_cost=declared.evaluations)


def projected_gradient(z: np.ndarray, grad: np.ndarray, lb: np.ndarray, ub: np.ndarray
                       ) -> np.ndarray:
    """P(z) = clip(z − grad, lb, ub) − z, shape (dim,): zero at a first-order stationary
    point of min cost(z) over the box."""
    return np.clip(z - grad, lb, ub) - z


def active_bounds(z: np.ndarray, lb: np.ndarray, ub: np.ndarray, names: list[str]
                  ) -> list[str]:
    """Names of the coordinates on a bound, as ``"<name>=lower"`` / ``"<name>=upper"``."""
    tol = BOUND_TOL * np.maximum(ub - lb, 1.0)
    out = []
    for i, name in enumerate(names):
        if z[i] <= lb[i] + tol[i]:
            out.append(f"{name}=lower")
        elif z[i] >= ub[i] - tol[i]:
            out.append(f"{name}=upper")
    return out


def first_order(problem: Any, layout: DecisionLayout, z: np.ndarray) -> dict[str, Any]:
    """First-order record columns of one decision vector: ``grad_norm`` (‖P(z)‖∞, NaN
    without a gradient), ``active_bounds`` (list of names) and ``gradient_note`` (why there
    is no gradient; empty when there is one)."""
    lb, ub = layout.bounds()
    z = np.asarray(z, dtype=float)
    names = layout.names()
    out = z_gradient(problem, layout, z)
    norm = float(np.max(np.abs(projected_gradient(z, out.grad, lb, ub)), initial=0.0)) \
        if out.exists else float("nan")
    return {"grad_norm": norm, "active_bounds": active_bounds(z, lb, ub, names),
            "gradient_note": out.reason}


__all__ = ["BOUND_TOL", "ZGradient", "active_bounds", "chain", "declared_gradient_cost",
           "first_order", "projected_gradient", "with_gradient_cost", "z_gradient"]
