"""Multi-start L-BFGS-B with exact gradients (``optimizer=lbfgs``).

Each local run is ``scipy.optimize.minimize(method="L-BFGS-B")`` in the unit cube (the box
[lb, ub] mapped to [0, 1]^dim, as CMA-ES searches, so eigenvalues and angles are on one
scale), with the cost divided by its value at the run's start (so ``gtol`` is relative)
and the exact gradient d cost / d z of the problem (:mod:`penaltyrun.optim.gradient`).
The first run starts from ``x0`` when one is given (warm start), every other from a point
uniform in the box drawn from the job seed, until ``starts`` runs are done or the budget is
spent.

**Budget in evaluation-equivalents.** Every value the search asks for is one evaluation
of the run's objective (counted, traced and capped as for every optimizer); every gradient
is charged ``grad_cost`` more evaluations (:data:`GRADIENT_COST`, measured by
``bench/gradient_cost.py``: the CPU time of one gradient divided by the CPU time of one
evaluation), so ``n_evals`` and ``max_evals`` compare with the other optimizers at equal
CPU.

A point where the gradient does not exist (a status other than ``converged``, a
non-differentiable map) ends that local run (``no_gradient``); the next start follows.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.optim.base import (
    BatchObjective,
    BudgetExhaustedError,
    CommonSettings,
    CountingObjective,
    OptimResult,
    as_counting,
    main_budget,
    require_int,
)

logger = logging.getLogger(__name__)

#: Evaluations charged per exact gradient: the CPU time of one ``problem=lqr`` gradient
#: d cost / d z over one single-candidate evaluation, median over n = 2 … 16 states,
#: diagonal and givens maps, continuous and discrete plants (1.8–1.9, rounded up;
#: ``bench/gradient_cost.py``, figures in bench/README.md).
GRADIENT_COST = 2.0

#: Gradient callable: z (dim,) → an object with ``grad`` (ndarray or None) and ``reason``.
GradientFn = Callable[[np.ndarray], Any]


class NoGradientError(Exception):
    """The cost has no gradient at the point the local search asked for."""


@dataclass(frozen=True)
class LBFGSSettings(CommonSettings):
    """Settings of multi-start L-BFGS-B (plus :class:`CommonSettings`).

    Attributes
    ----------
    starts : int or None
        Most local runs (``None``: until ``max_evals`` is spent; then ``max_evals`` is
        required).
    maxiter : int
        Iterations of one local run.
    ftol : float
        Stop a run when the relative reduction of the cost in one step is below this.
    gtol : float
        Stop a run when the largest entry of the projected gradient (unit cube, cost
        relative to its start value) is below this.
    maxcor : int
        Correction pairs kept by L-BFGS-B.
    grad_cost : float or None
        Evaluations charged per gradient (``None``: :data:`GRADIENT_COST`).
    """

    starts: int | None = 10
    maxiter: int = 2000
    ftol: float = 1e-15
    gtol: float = 1e-12
    maxcor: int = 20
    grad_cost: float | None = None

    def validate(self) -> None:
        """Check ranges (and the shared fields)."""
        super().validate()
        require_int("starts", self.starts, 1, allow_none=True)
        require_int("maxiter", self.maxiter, 1)
        require_int("maxcor", self.maxcor, 1)
        if self.starts is None and self.max_evals is None:
            raise ConfigError("optimizer.starts", "null (until the budget is spent) needs "
                              "optimizer.max_evals; set one of them")
        for key in ("ftol", "gtol"):
            value = getattr(self, key)
            if not (isinstance(value, (int, float)) and value > 0):
                raise ConfigError(f"optimizer.{key}", f"must be positive, got {value!r}")
        if self.grad_cost is not None and not (isinstance(self.grad_cost, (int, float))
                                               and 0 <= self.grad_cost < 1e6):
            raise ConfigError("optimizer.grad_cost", f"must be a number ≥ 0 (evaluations per "
                              f"gradient) or null, got {self.grad_cost!r}")

    @property
    def gradient_cost(self) -> float:
        """Evaluations charged per gradient."""
        return GRADIENT_COST if self.grad_cost is None else float(self.grad_cost)

    def search_evals(self, dim: int) -> int | None:
        """At most ``starts`` × ``maxiter`` × (1 + grad_cost) × (line-search factor 20)."""
        if self.starts is None:
            return None
        return int(self.starts * self.maxiter * 20 * (1.0 + self.gradient_cost))


def local_run(counted: CountingObjective, z0: np.ndarray, lb: np.ndarray, ub: np.ndarray,
              gradient: GradientFn, charge: float, options: LBFGSSettings
              ) -> tuple[str, int]:
    """One L-BFGS-B run from ``z0`` in the unit cube of [lb, ub] with exact gradients.

    Parameters
    ----------
    counted : CountingObjective
        The run's objective (values counted, traced and capped there).
    z0 : ndarray, shape (dim,)
        Start point (clipped into the box).
    lb, ub : ndarray, shape (dim,)
    gradient : callable
        z → an object with ``grad`` (ndarray or None) and ``reason``.
    charge : float
        Evaluations charged per gradient.
    options : LBFGSSettings
        ``maxiter``, ``ftol``, ``gtol``, ``maxcor``.

    Returns
    -------
    message : str
        scipy's message, or ``no_gradient: <reason>``.
    iterations : int
        L-BFGS-B iterations (0 when the run ended without a gradient).

    Raises
    ------
    BudgetExhaustedError
        When the run's budget is spent (the best so far is kept by ``counted``).
    """
    from scipy.optimize import minimize

    width = ub - lb
    scale = [0.0]

    def fun(u: np.ndarray) -> tuple[float, np.ndarray]:
        z = lb + np.clip(u, 0.0, 1.0) * width
        value = counted.scalar(z)
        if counted.transformed:
            raise ConfigError("optimizer", "the exact-gradient search minimizes the cost; "
                              "this problem optimizes another objective form")
        counted.charge(charge)  # before the work: a gradient past the budget is not made
        out = gradient(z)
        if out.grad is None:
            raise NoGradientError(out.reason)
        if not scale[0]:
            scale[0] = max(abs(value), 1e-300)
        return value / scale[0], np.asarray(out.grad) * width / scale[0]

    u0 = np.clip((np.asarray(z0, float) - lb) / width, 0.0, 1.0)
    try:
        res = minimize(fun, u0, jac=True, method="L-BFGS-B", bounds=[(0.0, 1.0)] * lb.size,
                       options={"maxiter": options.maxiter, "ftol": options.ftol,
                                "gtol": options.gtol, "maxcor": options.maxcor,
                                "maxfun": 20 * options.maxiter})
    except NoGradientError as exc:
        return f"no_gradient: {exc}", 0
    return str(res.message), int(res.nit)


def run_lbfgs(objective: BatchObjective, lb: np.ndarray, ub: np.ndarray,
              settings: LBFGSSettings, seed: int, x0: np.ndarray | None = None,
              gradient: GradientFn | None = None) -> OptimResult:
    """Minimize ``objective`` over [lb, ub] by multi-start L-BFGS-B with exact gradients.

    Parameters
    ----------
    objective : callable
        Batched objective Z (B, dim) → (B,), or a counting objective carrying the budget.
    lb, ub : ndarray, shape (dim,)
    settings : LBFGSSettings
    seed : int
        Job seed; the start points derive from it.
    x0 : ndarray, shape (dim,), optional
        Start of the first local run.
    gradient : callable
        z → the cost's gradient (:func:`penaltyrun.optim.gradient.z_gradient` bound to the
        problem and layout).

    Returns
    -------
    OptimResult
        ``stop_reason``: ``max_evals`` or ``starts``; ``n_iters`` the L-BFGS-B iterations
        of all runs; ``history`` the best cost after each local run.
    """
    if gradient is None:
        raise ConfigError("optimizer", "lbfgs needs the problem's exact gradient (its "
                          "gradient hook); this problem has none: pick another optimizer")
    counted = as_counting(objective, main_budget(settings))
    lb, ub = np.asarray(lb, float), np.asarray(ub, float)
    rng = np.random.default_rng(seed)
    history: list[float] = []
    stop = "starts"
    n_runs = settings.starts if settings.starts is not None else math.inf
    run = n_iters = 0
    try:
        while run < n_runs:
            z0 = lb + rng.random(lb.size) * (ub - lb) if (run or x0 is None) else \
                np.asarray(x0, float)
            run += 1
            message, nit = local_run(counted, z0, lb, ub, gradient, settings.gradient_cost,
                                     settings)
            n_iters += nit
            logger.debug("L-BFGS-B run %d: %s; best %.12g", run, message, counted.best_cost)
            history.append(counted.best_cost)
    except BudgetExhaustedError:
        stop = "max_evals"
        history.append(counted.best_cost)
    return counted.result(history, n_iters, stop)


def gradient_polish(counted: CountingObjective, z0: np.ndarray, lb: np.ndarray,
                    ub: np.ndarray, gradient: GradientFn | None, grad_cost: float | None
                    ) -> str:
    """``optimizer.polish=gradient``: one L-BFGS-B run with exact gradients from the
    search's best, inside the budget left (default :class:`LBFGSSettings` tolerances).

    Returns
    -------
    str
        ``converged`` (the local run ended on its own criteria), ``no_gradient`` or
        ``max_evals``.
    """
    if gradient is None:
        raise ConfigError("optimizer.polish", "gradient needs the problem's exact gradient; "
                          "this problem has none: use polish=L-BFGS-B (differences)")
    charge = GRADIENT_COST if grad_cost is None else float(grad_cost)
    try:
        message, _ = local_run(counted, np.asarray(z0, float), np.asarray(lb, float),
                               np.asarray(ub, float), gradient, charge, LBFGSSettings())
    except BudgetExhaustedError:
        return "max_evals"
    logger.debug("gradient polish: %s; best %.12g", message, counted.best_cost)
    return "no_gradient" if message.startswith("no_gradient") else "converged"


__all__ = ["GRADIENT_COST", "LBFGSSettings", "NoGradientError", "gradient_polish",
           "local_run", "run_lbfgs"]
