"""CMA-ES with IPOP restarts (:mod:`penaltyrun.optim.cma_core`: Hansen's update with active
covariance adaptation, pycma's box transformation and default stopping rules).

The search runs in the unit cube: the box [lb, ub] is mapped to [0, 1]^dim, so ``sigma0`` is
a fraction of every side of the box (eigenvalues and angles have different ranges), and
pycma's linear-quadratic transformation maps every candidate into the box. Each restart
multiplies the population by ``incpopsize`` (IPOP) and starts from a fresh uniform point,
until the evaluation budget is spent or ``restarts`` restarts are done. Every random number
(start points and samples) comes from one ``numpy.random.Generator`` seeded with the job
seed, so a seed gives one run and the global ``np.random`` state is never touched.

The population is sampled and updated as whole arrays, so the optimizer's own work per
generation is a few dozen numpy calls (the ``cma`` package, which this module used before,
does per-candidate Python bookkeeping that cost more than the attitude kernels' evaluation
of the population; ``bench/bench_cmaes.py`` measures both).

No exact cutoff (:mod:`penaltyrun.optim.base`): CMA-ES sorts every candidate of a generation
and its update uses the ranks of all of them (the active covariance update gives the worst
candidates negative weights), so there is no threshold below which a candidate's exact cost
stops mattering; a bound in place of a cost would change the ranks and the run.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.optim.base import (
    BatchObjective,
    BudgetExhaustedError,
    CommonSettings,
    OptimResult,
    as_counting,
    main_budget,
    require_int,
)

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class CMAESSettings(CommonSettings):
    """Settings of CMA-ES with IPOP restarts (plus :class:`CommonSettings`).

    Attributes
    ----------
    sigma0 : float
        Initial step size as a fraction of the box side (the search runs in [0, 1]^dim).
    popsize : int or None
        Population λ of the first run (``None``: the default 4 + ⌊3 ln dim⌋).
    incpopsize : float
        Population factor per restart (IPOP: 2).
    restarts : int
        Maximum number of restarts after the first run (the budget usually ends it first).
    tolfun, tolx : float
        Stopping tolerances of one run: function values (the range of a generation and of
        the recent best values) and step sizes (σ √C_ii and σ p_c in every coordinate of
        the unit cube); every stopping rule of a run: docs/explanation/cmaes.md.
    """

    sigma0: float = 0.3
    popsize: int | None = None
    incpopsize: float = 2.0
    restarts: int = 9
    tolfun: float = 1e-11
    tolx: float = 1e-11

    def batch_size(self, dim: int) -> int:
        """Candidates the optimizer passes to the objective per call on ``dim`` variables
        (what the forecast times one evaluation of): the population λ, ``popsize``
        (default 4 + ⌊3 ln dim⌋)."""
        return int(self.popsize or 4 + int(3 * math.log(dim)))

    def validate(self) -> None:
        """Check ranges (and the shared fields)."""
        super().validate()
        if not 0.0 < self.sigma0 <= 1.0:
            raise ConfigError("optimizer.sigma0", f"must be in (0, 1] (a fraction of the "
                              f"box), got {self.sigma0!r}")
        require_int("popsize", self.popsize, 2, allow_none=True)
        if self.incpopsize < 1.0:
            raise ConfigError("optimizer.incpopsize", f"must be ≥ 1, got {self.incpopsize!r}")
        require_int("restarts", self.restarts, 0)
        for key in ("tolfun", "tolx"):
            if not getattr(self, key) > 0:
                raise ConfigError(f"optimizer.{key}", f"must be positive, got "
                                  f"{getattr(self, key)!r}")

    def search_evals(self, dim: int) -> None:
        """``None``: each run ends on its stopping rules, so only ``max_evals`` bounds the
        restarts."""
        return None


def run_cmaes(objective: BatchObjective, lb: np.ndarray, ub: np.ndarray,
              settings: CMAESSettings, seed: int, x0: np.ndarray | None = None
              ) -> OptimResult:
    """Minimize ``objective`` over [lb, ub] with IPOP-CMA-ES.

    Parameters
    ----------
    objective : callable
        Batched objective Z (λ, dim) → (λ,), or a counting objective carrying the budget.
    lb, ub : ndarray, shape (dim,)
    settings : CMAESSettings
    seed : int
        Job seed: the generator of every start point and sample.
    x0 : ndarray, shape (dim,), optional
        Mean of the first run (warm start); default uniform in the box.

    Returns
    -------
    OptimResult
        ``stop_reason``: ``max_evals`` (budget spent) or ``restarts`` (all runs ended on
        their stopping rules). ``history`` has the best cost after every generation.
    """
    from penaltyrun.optim.cma_core import CMARun, from_box, to_box  # numba: load on use

    counted = as_counting(objective, main_budget(settings))
    lb, ub = np.asarray(lb, float), np.asarray(ub, float)
    width = ub - lb
    dim = lb.size
    rng = np.random.default_rng(seed)
    popsize = settings.popsize or 4 + int(3 * math.log(dim))
    mean = rng.random(dim) if x0 is None else (np.asarray(x0, float) - lb) / width
    history: list[float] = []
    stop = "restarts"
    try:
        for restart in range(settings.restarts + 1):
            es = CMARun(from_box(mean), settings.sigma0, popsize, rng, settings.tolfun,
                        settings.tolx)
            reasons: list[str] = []
            while not reasons:
                X = es.ask()
                es.tell(X, counted(lb + to_box(X) * width))
                history.append(counted.best_cost)
                reasons = es.stop()
            logger.debug("CMA-ES run %d (λ = %d) stopped on %s; best %.6g", restart, popsize,
                         ", ".join(reasons), counted.best_cost)
            popsize = int(round(popsize * settings.incpopsize))
            mean = rng.random(dim)
    except BudgetExhaustedError:
        stop = "max_evals"
        history.append(counted.best_cost)
    return counted.result(history, len(history), stop)
