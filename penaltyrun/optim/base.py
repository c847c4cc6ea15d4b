"""Optimizer contract: minimize a batched objective over a box within an evaluation budget.

An objective takes a batch Z of shape (B, dim) and returns B finite costs. Every optimizer
wraps it in a :class:`CountingObjective`, which counts evaluations, enforces the hard cap
``max_evals`` (a batch that would cross it is cut, then :class:`BudgetExhaustedError` ends the
search), keeps the best candidate ever evaluated and records the anytime trace (best-so-far
cost against cumulative evaluations). Every optimizer returns an :class:`OptimResult`.

Objective forms: an objective may return, instead of the bare costs, a result with ``cost``
and ``objective`` arrays (:class:`~penaltyrun.problems.base.BatchEvaluation`). The optimizer
then sees ``objective`` (e.g. −1/J, whose scale drives a stall test), while the best, the
trace and the result keep ``cost``; the two must order converged candidates alike.
Thresholds are in the optimizer's units (the objective converts them).

Exact cutoff: an objective with the attribute ``accepts_thresholds = True`` is called as
``func(Z, thresholds)`` when the optimizer hands thresholds (one per candidate, ``inf``: none)
to :meth:`CountingObjective.__call__`; it may then return, for a candidate whose cost exceeds
its threshold, any value above the threshold and not above the cost (see
:mod:`penaltyrun.problems.base`). Optimizers pass as threshold the value a candidate must beat
to change their state, so a run is the same with and without the cutoff: PSO (``pso``,
``pso_matlab``) the particle's personal best, DE the cost of the member the trial would
replace. CMA-ES and the grid rank every candidate and pass none. The best-so-far and the
anytime trace are never touched by a cut candidate: its value is above a cost already
evaluated.
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.typed import is_int, is_number

logger = logging.getLogger(__name__)

BatchObjective = Callable[[np.ndarray], np.ndarray]

#: Local-search methods of ``scipy.optimize.minimize`` that accept box bounds.
#: Bounded ``scipy.optimize.minimize`` methods of the local searches (:mod:`.polish`).
LOCAL_METHODS = ("L-BFGS-B", "Nelder-Mead", "Powell", "TNC", "SLSQP")
POLISH_METHODS = ("none", *LOCAL_METHODS, "gradient", "pattern")


@contextlib.contextmanager
def global_rng_kept() -> Iterator[None]:
    """Restore ``np.random``'s global state when the block ends.

    pyswarms draws from the global numpy generator (seeded by the PSO adapter); an
    optimizer run inside this block seeds and uses it freely, and the caller's state is as
    it was afterwards (a library call must not move its caller's random numbers).
    """
    state = np.random.get_state()  # noqa: NPY002  (saved for the caller, never drawn from)
    try:
        yield
    finally:
        np.random.set_state(state)  # noqa: NPY002


def missing_gradient_charge(problem: str | None = None) -> ConfigError:
    """The refusal of a run that uses exact gradients when neither ``optimizer.grad_cost``
    nor the problem (``problem``: its name, if known) says what one gradient costs."""
    who = f"problem {problem!r}" if problem else "the problem"
    return ConfigError("optimizer.grad_cost", f"{who} does not declare what one exact "
                       "gradient costs in evaluations (its gradient_cost hook); set "
                       "optimizer.grad_cost to the CPU time of one gradient over that of "
                       "one evaluation")


def require_int(key: str, value: object, least: int, allow_none: bool = False) -> None:
    """Raise :class:`ConfigError` naming ``optimizer.<key>`` unless ``value`` is an integer
    ≥ ``least`` (or ``None`` where allowed)."""
    if value is None and allow_none:
        return
    if not is_int(value) or value < least:
        what = "a positive integer" if least == 1 else f"an integer ≥ {least}"
        raise ConfigError(f"optimizer.{key}", f"must be {what}"
                          f"{' or null' if allow_none else ''}, got {value!r}")


class BudgetExhaustedError(Exception):
    """Raised by :class:`CountingObjective` once ``max_evals`` evaluations are spent."""


@dataclass(frozen=True)
class CommonSettings:
    """Settings shared by every search optimizer (the first fields of each settings class).

    Attributes
    ----------
    max_evals : int or None
        Hard cap on objective evaluations of one start (``None``: only the optimizer's own
        iteration limit and stall rule). Every job records ``n_evals ≤ max_evals``.
    polish : str
        Bounded local search from the optimizer's best, inside the same budget: ``none``,
        a ``scipy.optimize.minimize`` method (``L-BFGS-B``, ``Nelder-Mead``, ``Powell``,
        ``TNC``, ``SLSQP``; gradients by forward differences), ``gradient`` (L-BFGS-B
        with the problem's exact gradient, each gradient charged as evaluations like
        ``optimizer=lbfgs``) or ``pattern`` (compass search, no gradient: it ends where no
        single-variable step of 1e-6 of its range lowers the cost, also next to a jump of
        the criterion; :mod:`penaltyrun.optim.pattern`).
    polish_share : float
        Share of ``max_evals`` kept for the polish (the search stops earlier to leave it).
        Without ``max_evals`` the polish runs until the local method's own tolerance.
    grad_cost : float or None
        Evaluations charged per exact gradient by ``optimizer=lbfgs`` and
        ``polish=gradient``; ``None``: what the problem declares one gradient to cost (its
        measured CPU time over that of one evaluation). Presets other than ``lbfgs`` do not
        list it: set it with ``+optimizer.grad_cost=...``.
    """

    max_evals: int | None = None
    polish: str = "none"
    polish_share: float = 0.1
    grad_cost: float | None = None

    @property
    def uses_gradient(self) -> bool:
        """Whether the run calls the problem's exact gradient (and charges it)."""
        return self.polish == "gradient"

    def validate(self) -> None:
        """Check the shared fields.

        Raises
        ------
        ConfigError
            Naming the key.
        """
        require_int("max_evals", self.max_evals, 1, allow_none=True)
        if self.polish not in POLISH_METHODS:
            raise ConfigError("optimizer.polish", f"unknown local search {self.polish!r}",
                              allowed=POLISH_METHODS)
        if not 0.0 < float(self.polish_share) < 1.0:
            raise ConfigError("optimizer.polish_share", f"must be in (0, 1), got "
                              f"{self.polish_share!r}")
        cost = self.grad_cost
        if cost is not None and not (is_number(cost) and 0.0 < cost < 1e6):
            raise ConfigError("optimizer.grad_cost", f"must be a positive number (evaluations "
                              f"per gradient, below 1e6) or null, got {cost!r}")
        if cost is not None and not self.uses_gradient:
            raise ConfigError("optimizer.grad_cost", "only optimizer=lbfgs and "
                              "optimizer.polish=gradient charge gradients; drop it or set "
                              "polish=gradient")

    def batch_size(self, dim: int) -> int:
        """Candidates the optimizer passes to the objective per call on ``dim`` variables
        (what the forecast times one evaluation of): 1 unless the optimizer evaluates a
        population (its settings class then overrides this)."""
        return 1

    def search_evals(self, dim: int) -> int | None:
        """Most evaluations the search itself can spend on ``dim`` variables (its own
        iteration limits, before ``max_evals`` and the polish); ``None`` if it has none.
        Each optimizer's settings class overrides this."""
        return None


@dataclass
class OptimResult:
    """Outcome of one optimization run.

    Attributes
    ----------
    best_cost : float
        Lowest objective value evaluated.
    best_z : ndarray, shape (dim,)
        Decision vector achieving it.
    history : list of float
        Best cost after each iteration (generation) of the main search.
    n_evals : int
        Objective evaluations (candidates, not batches), polish included.
    n_iters : int
        Iterations (generations) performed.
    stop_reason : str
        ``"ftol"`` (stall rule), ``"iters"`` (iteration limit), ``"max_evals"`` (evaluation
        budget spent) or optimizer-specific text; after a polish ``"+polish"`` (it ended
        on its own criteria), ``"+polish:no_gradient"`` or ``"+polish:max_evals"``.
    n_nonfinite : int
        Evaluations that returned a non-finite cost (replaced by the penalty).
    trace_evals, trace_best : list
        Anytime trace: after ``trace_evals[k]`` evaluations the best cost so far was
        ``trace_best[k]``. A point is stored at every improvement and at the end, so the
        step function best-so-far(n) is exact.
    trace_cpu_s : list of float
        CPU seconds (``time.process_time`` of this process, every thread) from the start of
        the search to each trace point: the work of this process only (evaluations farmed
        out to other processes are not in it).
    n_gradients : int
        Exact gradients charged in ``n_evals`` (``optimizer=lbfgs``, ``polish=gradient``).
    grad_cost : float or None
        Evaluations charged per gradient; ``None`` when no gradient was charged.
    polish_evals : int
        Evaluations (evaluation-equivalents) of ``n_evals`` spent by the polish
        (``optimizer.polish``); 0 without one.
    """

    best_cost: float
    best_z: np.ndarray
    history: list[float] = field(default_factory=list)
    n_evals: int = 0
    n_iters: int = 0
    stop_reason: str = ""
    n_nonfinite: int = 0
    trace_evals: list[int] = field(default_factory=list)
    trace_best: list[float] = field(default_factory=list)
    trace_cpu_s: list[float] = field(default_factory=list)
    n_gradients: int = 0
    grad_cost: float | None = None
    polish_evals: int = 0


class CountingObjective:
    """Wrap a batched objective: count, cap, trace, keep the best, replace non-finite costs.

    Parameters
    ----------
    func : callable
        Batched objective Z (B, dim) → (B,).
    nonfinite_cost : float
        Value substituted for NaN / inf costs (these are counted and logged, never
        silently passed to the optimizer).
    max_evals : int, optional
        Hard cap on evaluations. A batch that would cross it is cut to the evaluations
        left, and :class:`BudgetExhaustedError` is raised after the allowed part is recorded.
    """

    def __init__(self, func: BatchObjective, nonfinite_cost: float = 1e12,
                 max_evals: int | None = None) -> None:
        self.func = func
        self.nonfinite_cost = float(nonfinite_cost)
        self.max_evals = max_evals
        self.limit = max_evals
        self.n_evals = 0
        self.n_nonfinite = 0
        self.best_cost = float("inf")
        self.best_z: np.ndarray | None = None
        self.trace_evals: list[int] = []
        self.trace_best: list[float] = []
        self.trace_cpu_s: list[float] = []
        self.cpu_start = time.process_time()  # the search starts with its objective
        self.transformed = False  # objective values differ from the costs
        self.best_value = float("inf")
        self.value_costs: dict[float, float] = {}  # each new best value → its cost
        self.charged = 0.0  # evaluation-equivalents charged for gradients, not yet counted
        self.n_gradients = 0
        self.grad_cost: float | None = None

    @property
    def remaining(self) -> float:
        """Evaluations left under the current limit (``inf`` without a cap)."""
        return float("inf") if self.limit is None else self.limit - self.n_evals

    @property
    def cutoff(self) -> bool:
        """Whether thresholds reach the objective (``func.accepts_thresholds``)."""
        return bool(getattr(self.func, "accepts_thresholds", False))

    def __call__(self, Z: np.ndarray, thresholds: np.ndarray | None = None) -> np.ndarray:
        """Values of the batch ``Z`` (B, dim) for the optimizer, shape (B,) (fewer if the
        budget cuts it): the costs, or the objective's ``objective`` values when it returns
        a result carrying them (a problem's objective form; the best and the trace keep
        the costs).

        ``thresholds`` (shape (B,), optional) are passed on when the objective accepts them
        (:attr:`cutoff`) and dropped otherwise.
        """
        Z = np.atleast_2d(np.asarray(Z, float))
        left = self.remaining
        if left <= 0:
            raise BudgetExhaustedError
        cut = Z.shape[0] > left
        if cut:
            Z = Z[:int(left)]
        if thresholds is not None and self.cutoff:
            thr = np.asarray(thresholds, dtype=float).reshape(-1)[:Z.shape[0]]
            out = self.func(Z, thr)
        else:
            out = self.func(Z)
        value = getattr(out, "objective", None)
        cost = np.asarray(getattr(out, "cost", out), dtype=float).reshape(Z.shape[0])
        if value is None:
            value = cost
        else:
            value = np.asarray(value, float).reshape(Z.shape[0])
            self.transformed = True
        bad = ~(np.isfinite(cost) & np.isfinite(value))
        if bad.any():
            self.n_nonfinite += int(bad.sum())
            logger.warning("%d non-finite costs replaced by %g", int(bad.sum()),
                           self.nonfinite_cost)
            cost = np.where(bad, self.nonfinite_cost, cost)
            value = np.where(bad, self.nonfinite_cost, value)
        self.n_evals += Z.shape[0]
        j = int(np.argmin(value))
        if value[j] < self.best_value:
            self.best_value = float(value[j])
            self.value_costs[self.best_value] = float(cost[j])
        i = int(np.argmin(cost))
        if cost[i] < self.best_cost:
            self.best_cost = float(cost[i])
            self.best_z = Z[i].copy()
            self.trace_evals.append(self.n_evals)
            self.trace_best.append(self.best_cost)
            self.trace_cpu_s.append(self.cpu_seconds())
        if cut:
            raise BudgetExhaustedError
        return value

    def cpu_seconds(self) -> float:
        """CPU seconds of this process since the objective was made (the search began)."""
        return time.process_time() - self.cpu_start

    def charge(self, evaluations: float) -> None:
        """Count ``evaluations`` evaluation-equivalents (e.g. the CPU of an exact gradient
        in evaluations; fractions carry over to the next charge).

        Raises
        ------
        BudgetExhaustedError
            When the charge does not fit in the budget left (nothing is charged: the work
            it pays for must not be done).
        """
        if self.limit is not None and self.n_evals + self.charged + evaluations > self.limit:
            raise BudgetExhaustedError
        self.charged += float(evaluations)
        whole = int(self.charged)
        self.n_evals += whole
        self.charged -= whole

    def charge_gradient(self, evaluations: float) -> None:
        """Count one exact gradient as ``evaluations`` evaluation-equivalents
        (:meth:`charge`; the result reports the gradients and the charge per gradient).

        Raises
        ------
        BudgetExhaustedError
            When the charge does not fit in the budget left (the gradient must not be made).
        """
        self.charge(evaluations)
        self.n_gradients += 1
        self.grad_cost = float(evaluations)

    def scalar(self, z: np.ndarray) -> float:
        """Value of one decision vector as the optimizer sees it (for scipy local
        searches)."""
        return float(self(np.asarray(z, float)[None, :])[0])

    def result(self, history: list[float], n_iters: int, stop_reason: str) -> OptimResult:
        """The run's :class:`OptimResult`: best evaluated candidate, counts and trace.

        ``history`` may hold the optimizer's own best values: with an objective form they
        are mapped back to the costs of the candidates that set them."""
        if self.best_z is None:
            raise RuntimeError("no candidate was evaluated")
        if self.transformed:
            history = [self.value_costs.get(float(h), h) for h in history]
        trace_evals, trace_best = list(self.trace_evals), list(self.trace_best)
        trace_cpu = list(self.trace_cpu_s)
        if trace_evals[-1] != self.n_evals:  # close the step function at the last evaluation
            trace_evals.append(self.n_evals)
            trace_best.append(self.best_cost)
            trace_cpu.append(self.cpu_seconds())
        return OptimResult(best_cost=self.best_cost, best_z=self.best_z.copy(),
                           history=[float(h) for h in history], n_evals=self.n_evals,
                           n_iters=int(n_iters), stop_reason=stop_reason,
                           n_nonfinite=self.n_nonfinite, trace_evals=trace_evals,
                           trace_best=trace_best, trace_cpu_s=trace_cpu,
                           n_gradients=self.n_gradients, grad_cost=self.grad_cost)


def as_counting(objective: BatchObjective, max_evals: int | None = None) -> CountingObjective:
    """``objective`` itself if it already counts, else a new :class:`CountingObjective`."""
    if isinstance(objective, CountingObjective):
        return objective
    return CountingObjective(objective, max_evals=max_evals)


def main_budget(settings: CommonSettings) -> int | None:
    """Evaluations the main search may spend (``max_evals`` minus the polish share)."""
    if settings.max_evals is None:
        return None
    return main_budget_of(settings.max_evals, settings.polish, settings.polish_share)


def main_budget_of(max_evals: int, polish: str, polish_share: float) -> int:
    """:func:`main_budget` of a budget ``max_evals`` and the settings ``polish`` and
    ``polish_share`` (e.g. as a results record stores them)."""
    if polish == "none":
        return max_evals
    return max(1, max_evals - int(polish_share * max_evals))


def planned_evals(settings: CommonSettings, dim: int) -> int | None:
    """Most evaluations one start of ``settings`` can spend on ``dim`` variables.

    The search's own limit (:meth:`CommonSettings.search_evals`: swarm × iterations,
    population × generations, ...), plus an uncapped polish, all bounded by ``max_evals``.
    A stall rule may stop the search earlier, so this is an upper bound.

    Returns
    -------
    int or None
        ``None`` when nothing bounds the run (no ``max_evals`` and a search or polish
        without its own limit, e.g. CMA-ES restarts or a polish after DE).
    """
    if not isinstance(settings, CommonSettings):
        return 1  # the baseline evaluates its one point
    search = settings.search_evals(dim)
    total = search if settings.polish == "none" else None
    if settings.max_evals is None:
        return total
    return settings.max_evals if total is None else min(total, settings.max_evals)


def uniform_box(rng: np.random.Generator, lb: np.ndarray, ub: np.ndarray, n: int
                ) -> np.ndarray:
    """``n`` points uniform in the box [lb, ub], shape (n, dim)."""
    lb, ub = np.asarray(lb, float), np.asarray(ub, float)
    return lb + rng.random((n, lb.size)) * (ub - lb)
