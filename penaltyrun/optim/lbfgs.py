"""Multi-start L-BFGS-B with exact gradients (``optimizer=lbfgs``).

Each local run is ``scipy.optimize.minimize(method="L-BFGS-B")`` in the unit cube (the box
[lb, ub] mapped to [0, 1]^dim, as CMA-ES searches, so eigenvalues and angles are on one
scale), with the cost divided by its value at the run's start (so ``gtol`` is relative)
and the exact gradient d cost / d z of the problem (:mod:`penaltyrun.optim.gradient`).
With ``log_positive`` the variables whose box is strictly positive (the eigenvalues of
every map, the entries of the diagonal) are mapped to the cube on a log scale,
z = lb·(ub/lb)^u: a relative change of a small eigenvalue is then as large a step as the
same relative change of a large one, which keeps the local problem far better conditioned
when the optimum's eigenvalues sit near the lower end of a wide box.
The first run starts from ``x0`` when one is given (warm start), every other from a point
uniform in the box drawn from the job seed, until ``starts`` runs are done or the budget is
spent.

**Budget in evaluation-equivalents.** Every value the search asks for is one evaluation
of the run's objective (counted, traced and capped as for every optimizer); every gradient
is charged ``grad_cost`` more evaluations: the CPU time of one gradient over that of one
evaluation, as the problem declares it (:class:`~penaltyrun.problems.base.GradientCost`,
measured by the benchmarks in ``bench/``) unless ``optimizer.grad_cost`` says otherwise
(:func:`penaltyrun.optim.gradient.with_gradient_cost` fills it in), so ``n_evals`` and
``max_evals`` compare with the other optimizers at equal CPU. The result reports the
gradients charged and the charge per gradient.

A point where the gradient does not exist (a status other than ``converged``, a
non-differentiable map) is stepped back from (:func:`backtracking_run`): the run restarts
from its best point with a gradient inside a trust region that excludes the failed point.
A start without a gradient ends that start (``no_gradient``); the next start follows.
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
    missing_gradient_charge,
    require_int,
)

logger = logging.getLogger(__name__)

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
    log_positive : bool
        Search the variables whose box is strictly positive on a log scale (the box and
        the start points are the same; only L-BFGS-B's coordinates change).
    """

    starts: int | None = 10
    maxiter: int = 2000
    ftol: float = 1e-15
    gtol: float = 1e-12
    maxcor: int = 20
    log_positive: bool = False

    @property
    def uses_gradient(self) -> bool:
        """Every run calls the exact gradient."""
        return True

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

    def search_evals(self, dim: int) -> int | None:
        """At most ``starts`` × ``maxiter`` × (1 + grad_cost) × (line-search factor 20);
        ``None`` while the charge per gradient is not known."""
        if self.starts is None or self.grad_cost is None:
            return None
        return int(self.starts * self.maxiter * 20 * (1.0 + self.grad_cost))


def require_charge(grad_cost: float | None) -> float:
    """The evaluations charged per gradient; a run that would charge none is refused.

    Raises
    ------
    ConfigError
        ``grad_cost`` is None: neither ``optimizer.grad_cost`` nor the problem says what a
        gradient costs.
    """
    if grad_cost is None:
        raise missing_gradient_charge()
    return float(grad_cost)


class UnitCube:
    """The map between the box [lb, ub] and L-BFGS-B's unit cube: linear, or on a log
    scale for the strictly positive variables when ``log_positive`` (z = lb·(ub/lb)^u)."""

    def __init__(self, lb: np.ndarray, ub: np.ndarray, log_positive: bool = False) -> None:
        self.lb, self.ub = np.asarray(lb, float), np.asarray(ub, float)
        self.log = (self.lb > 0) if log_positive else np.zeros(self.lb.size, bool)
        self.low = np.where(self.log, self.lb, 1.0)
        self.span = np.where(self.log, np.log(np.where(self.log, self.ub, 1.0) / self.low),
                             self.ub - self.lb)

    def to_box(self, u: np.ndarray) -> np.ndarray:
        """z in [lb, ub] of u (clipped to the cube), shape (dim,)."""
        u = np.clip(np.asarray(u, float), 0.0, 1.0)
        z = np.where(self.log, self.low * np.exp(u * self.span), self.lb + u * self.span)
        return np.clip(z, self.lb, self.ub)

    def to_cube(self, z: np.ndarray) -> np.ndarray:
        """u in [0, 1]^dim of z (clipped to the box), shape (dim,)."""
        z = np.clip(np.asarray(z, float), self.lb, self.ub)
        shifted = np.where(self.log, np.log(np.where(self.log, z, 1.0) / self.low),
                           z - self.lb)
        return np.clip(shifted / self.span, 0.0, 1.0)

    def dz_du(self, z: np.ndarray) -> np.ndarray:
        """Diagonal of the map's Jacobian dz/du at z, shape (dim,)."""
        return np.where(self.log, np.asarray(z, float) * self.span, self.span)


@dataclass
class LocalRun:
    """Outcome of one L-BFGS-B run (:func:`local_run`).

    Attributes
    ----------
    message : str
        scipy's message, or ``no_gradient: <reason>`` when a point it asked for has no
        gradient.
    iterations : int
        L-BFGS-B iterations (0 when the run ended without a gradient).
    anchor : ndarray, shape (dim,), or None
        The lowest-cost point of the run at which the gradient existed, in the unit cube
        (None: not even the start had one).
    failed_at : ndarray, shape (dim,), or None
        The point without a gradient that ended the run, in the unit cube.
    """

    message: str
    iterations: int
    anchor: np.ndarray | None = None
    failed_at: np.ndarray | None = None

    @property
    def no_gradient(self) -> bool:
        """The run ended at a point without a gradient."""
        return self.message.startswith("no_gradient")


def local_run(counted: CountingObjective, u0: np.ndarray, cube: UnitCube,
              gradient: GradientFn, charge: float, options: LBFGSSettings,
              region: tuple[np.ndarray, np.ndarray] | None = None) -> LocalRun:
    """One L-BFGS-B run from ``u0`` in the unit cube of [lb, ub] with exact gradients.

    Parameters
    ----------
    counted : CountingObjective
        The run's objective (values counted, traced and capped there).
    u0 : ndarray, shape (dim,)
        Start point in the unit cube.
    cube : UnitCube
        The map between the box and the cube.
    gradient : callable
        z → an object with ``grad`` (ndarray or None) and ``reason``.
    charge : float
        Evaluations charged per gradient.
    options : LBFGSSettings
        ``maxiter``, ``ftol``, ``gtol``, ``maxcor``.
    region : (ndarray, ndarray), optional
        Lower and upper corners (cube units) of the part of the cube the run may search
        (default: the whole cube).

    Returns
    -------
    LocalRun

    Raises
    ------
    BudgetExhaustedError
        When the run's budget is spent (the best so far is kept by ``counted``).
    """
    from scipy.optimize import minimize

    low, high = region if region is not None else (np.zeros(cube.lb.size),
                                                   np.ones(cube.lb.size))
    scale = [0.0]
    best: dict[str, Any] = {"value": math.inf, "u": None, "failed": None}

    def fun(u: np.ndarray) -> tuple[float, np.ndarray]:
        z = cube.to_box(u)
        value = counted.scalar(z)
        if counted.transformed:
            raise ConfigError("optimizer", "the exact-gradient search minimizes the cost; "
                              "this problem optimizes another objective form")
        counted.charge_gradient(charge)  # before the work: past the budget it is not made
        out = gradient(z)
        if out.grad is None:
            best["failed"] = np.array(u, float)
            raise NoGradientError(out.reason)
        if not scale[0]:
            scale[0] = max(abs(value), 1e-300)
        if value < best["value"]:
            best["value"], best["u"] = value, np.array(u, float)
        return value / scale[0], np.asarray(out.grad) * cube.dz_du(z) / scale[0]

    try:
        res = minimize(fun, np.clip(u0, low, high), jac=True, method="L-BFGS-B",
                       bounds=list(zip(low, high)),
                       options={"maxiter": options.maxiter, "ftol": options.ftol,
                                "gtol": options.gtol, "maxcor": options.maxcor,
                                "maxfun": 20 * options.maxiter})
    except NoGradientError as exc:
        return LocalRun(f"no_gradient: {exc}", 0, best["u"], best["failed"])
    return LocalRun(str(res.message), int(res.nit), best["u"])


#: Local runs one :func:`backtracking_run` makes at most (each after the previous one ended
#: at a point without a gradient, or on the edge of its trust region).
MAX_LOCAL_RUNS = 30
#: Smallest trust-region half-width (unit-cube units) a backtracking run shrinks to.
MIN_RADIUS = 1e-9
#: Fractions of the way to the cube's centre a start without a gradient is moved, one after
#: the other, until the gradient exists (a search's best often lies where a map has no
#: derivative, e.g. GEAGSP with an angle on its bound).
NUDGES = (1e-4, 1e-2, 1e-1)


def backtracking_run(counted: CountingObjective, z0: np.ndarray, cube: UnitCube,
                     gradient: GradientFn, charge: float, options: LBFGSSettings
                     ) -> tuple[str, int]:
    """L-BFGS-B from ``z0`` that steps back from points without a gradient.

    L-BFGS-B needs the gradient at every point it tries. When a trial point has none (a
    status change, a map's singular set), the run is restarted from the best point where
    the gradient existed, confined to a box around it (trust region, cube units) half as
    wide as the distance to the failed point, so the next steps stay where the cost is
    smooth. A run that converges on the edge of its trust region is restarted from its
    best point with the region doubled (the whole cube once it covers it). A start without
    a gradient is moved towards the cube's centre by the fractions :data:`NUDGES` in turn
    until one has a gradient (the start itself stays evaluated: the best is never worse).
    It ends when a run converges inside its region, when no nudged start has a gradient,
    or after :data:`MAX_LOCAL_RUNS` runs or a region below :data:`MIN_RADIUS`.

    Returns
    -------
    message : str
        The last run's message (``no_gradient: <reason>`` when it ended without one).
    iterations : int
        L-BFGS-B iterations of all runs.

    Raises
    ------
    BudgetExhaustedError
        When the budget is spent (the best so far is kept by ``counted``).
    """
    u = start = cube.to_cube(z0)
    radius, iterations, nudges = 1.0, 0, list(NUDGES)
    for _ in range(MAX_LOCAL_RUNS):
        region = (np.clip(u - radius, 0.0, 1.0), np.clip(u + radius, 0.0, 1.0))
        run = local_run(counted, u, cube, gradient, charge, options,
                        None if radius >= 1.0 else region)
        iterations += run.iterations
        if run.anchor is None:  # only a (nudged) start can lack a gradient
            if not nudges:
                return run.message, iterations
            share = nudges.pop(0)
            u = (1.0 - share) * start + share * 0.5
            continue
        if run.no_gradient:
            step = float(np.max(np.abs(run.failed_at - run.anchor)))
            radius = min(radius, step) / 2.0
            if radius < MIN_RADIUS:
                return run.message, iterations
        else:
            inner = (run.anchor > region[0] + 1e-12) | (region[0] <= 0.0)
            inner &= (run.anchor < region[1] - 1e-12) | (region[1] >= 1.0)
            if radius >= 1.0 or bool(np.all(inner)):
                return run.message, iterations
            radius = min(2.0 * radius, 1.0)
        u = run.anchor
    return run.message, iterations


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
    charge = require_charge(settings.grad_cost)
    counted = as_counting(objective, main_budget(settings))
    lb, ub = np.asarray(lb, float), np.asarray(ub, float)
    cube = UnitCube(lb, ub, settings.log_positive)
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
            message, nit = backtracking_run(counted, z0, cube, gradient, charge, settings)
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
    search's best, inside the budget left (default :class:`LBFGSSettings` tolerances),
    each gradient charged ``grad_cost`` evaluations.

    Returns
    -------
    str
        ``converged`` (the local run ended on its own criteria), ``no_gradient`` or
        ``max_evals``.
    """
    if gradient is None:
        raise ConfigError("optimizer.polish", "gradient needs the problem's exact gradient; "
                          "this problem has none: use polish=L-BFGS-B (differences)")
    charge = require_charge(grad_cost)
    try:
        cube = UnitCube(np.asarray(lb, float), np.asarray(ub, float))
        message, _ = backtracking_run(counted, np.asarray(z0, float), cube, gradient,
                                      charge, LBFGSSettings())
    except BudgetExhaustedError:
        return "max_evals"
    logger.debug("gradient polish: %s; best %.12g", message, counted.best_cost)
    return "no_gradient" if message.startswith("no_gradient") else "converged"


__all__ = ["MAX_LOCAL_RUNS", "MIN_RADIUS", "NUDGES", "LBFGSSettings", "LocalRun", "NoGradientError",
           "UnitCube", "backtracking_run", "gradient_polish", "local_run", "require_charge",
           "run_lbfgs"]
