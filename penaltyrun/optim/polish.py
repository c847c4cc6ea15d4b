"""Bounded local search from a point, inside the run's evaluation budget.

Used by ``optimizer.polish`` (after any optimizer) and by the ``grid`` optimizer (from the
best grid cells). Gradient methods get a forward-difference gradient evaluated as one batch
of dim + 1 candidates, so the batched kernels stay batched.
"""

from __future__ import annotations

import logging

import numpy as np

from penaltyrun.optim.base import BudgetExhaustedError, CountingObjective

logger = logging.getLogger(__name__)

GRADIENT_METHODS = ("L-BFGS-B", "TNC", "SLSQP")
#: Relative forward-difference step (≈ sqrt of machine epsilon).
FD_STEP = 1.5e-8


def _value_and_gradient(counted: CountingObjective, lb: np.ndarray, ub: np.ndarray):
    """f(x) and its forward-difference gradient from one batch of dim + 1 evaluations."""

    def fun(x: np.ndarray) -> tuple[float, np.ndarray]:
        x = np.clip(np.asarray(x, float), lb, ub)
        h = FD_STEP * np.maximum(1.0, np.abs(x))
        h = np.where(x + h > ub, -h, h)  # step inward at the upper bound
        Z = np.vstack([x, x + np.diag(h)])
        cost = counted(Z)
        return float(cost[0]), (cost[1:] - cost[0]) / h

    return fun


def local_search(counted: CountingObjective, x0: np.ndarray, lb: np.ndarray, ub: np.ndarray,
                 method: str, max_evals: float = float("inf")) -> str:
    """Minimize from ``x0`` within [lb, ub] with ``scipy.optimize.minimize(method=...)``.

    Parameters
    ----------
    counted : CountingObjective
        The run's objective; its best candidate and trace are updated as it evaluates.
    x0 : ndarray, shape (dim,)
        Start point (inside the box).
    lb, ub : ndarray, shape (dim,)
        Box bounds.
    method : str
        A bounded method of ``scipy.optimize.minimize``.
    max_evals : float
        Evaluations this search may spend (besides the objective's own cap).

    Returns
    -------
    str
        ``"converged"``, ``"local_budget"`` or ``"max_evals"`` (run budget spent).
    """
    from scipy.optimize import Bounds, minimize  # imported when a search runs (0.3 s)

    lb, ub = np.asarray(lb, float), np.asarray(ub, float)
    start = counted.n_evals
    saved_limit = counted.limit
    if np.isfinite(max_evals):
        local_limit = start + int(max_evals)
        counted.limit = local_limit if saved_limit is None else min(saved_limit, local_limit)
    bounds = Bounds(lb, ub)
    x0 = np.clip(np.asarray(x0, float), lb, ub)
    try:
        if method in GRADIENT_METHODS:
            minimize(_value_and_gradient(counted, lb, ub), x0, method=method, jac=True,
                     bounds=bounds)
        else:
            minimize(counted.scalar, x0, method=method, bounds=bounds)
        outcome = "converged"
    except BudgetExhaustedError:
        exhausted_run = saved_limit is not None and counted.n_evals >= saved_limit
        outcome = "max_evals" if exhausted_run else "local_budget"
    finally:
        counted.limit = saved_limit
    logger.debug("local %s from the best: %d evaluations, %s, best %.6g", method,
                 counted.n_evals - start, outcome, counted.best_cost)
    return outcome
