"""CMA-ES with IPOP restarts, from the ``cma`` package (Hansen's reference implementation).

The search runs in the unit cube: the box [lb, ub] is mapped to [0, 1]^dim, so ``sigma0`` is
a fraction of every side of the box (eigenvalues and angles have different ranges) and cma's
``BoundTransform`` keeps every candidate inside the box. Each restart doubles the
population (IPOP, ``incpopsize``) and starts from a fresh uniform point, until the evaluation
budget is spent or ``restarts`` restarts are done. cma draws from the global ``np.random``
state, seeded per restart from the job seed, so a seed gives one run.

No exact cutoff (:mod:`penaltyrun.optim.base`): CMA-ES sorts every candidate of a generation
and its update uses the ranks of all of them (cma's default active covariance update gives
the worst candidates negative weights), so there is no threshold below which a candidate's
exact cost stops mattering; a bound in place of a cost would change the ranks and the run.
"""

from __future__ import annotations

import logging
import math
import warnings
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
        Population λ of the first run (``None``: cma's default 4 + ⌊3 ln dim⌋).
    incpopsize : float
        Population factor per restart (IPOP: 2).
    restarts : int
        Maximum number of restarts after the first run (the budget usually ends it first).
    tolfun, tolx : float
        cma's stopping tolerances of one run (function values, step sizes).
    """

    sigma0: float = 0.3
    popsize: int | None = None
    incpopsize: float = 2.0
    restarts: int = 9
    tolfun: float = 1e-11
    tolx: float = 1e-11

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
        """``None``: each run ends on cma's own tolerances, so only ``max_evals`` bounds
        the restarts."""
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
        Job seed; each restart's cma seed and start point derive from it.
    x0 : ndarray, shape (dim,), optional
        Mean of the first run (warm start); default uniform in the box.

    Returns
    -------
    OptimResult
        ``stop_reason``: ``max_evals`` (budget spent) or ``restarts`` (all runs ended on
        cma's own criteria). ``history`` has the best cost after every generation.
    """
    import cma  # 0.7 s of imports (scipy.stats, matplotlib): only when CMA-ES runs

    counted = as_counting(objective, main_budget(settings))
    lb, ub = np.asarray(lb, float), np.asarray(ub, float)
    width = ub - lb
    dim = lb.size
    rng = np.random.default_rng(seed)
    popsize = settings.popsize or 4 + int(3 * math.log(dim))
    mean = rng.random(dim) if x0 is None else np.clip((np.asarray(x0, float) - lb) / width,
                                                      0.0, 1.0)
    history: list[float] = []
    stop = "restarts"
    try:
        for restart in range(settings.restarts + 1):
            opts = {"bounds": [0.0, 1.0], "popsize": popsize,
                    "seed": int(rng.integers(1, 2**31 - 1)), "verbose": -9, "verb_log": 0,
                    "verb_disp": 0, "tolfun": settings.tolfun, "tolx": settings.tolx}
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # cma warns about flat fitness, etc.
                es = cma.CMAEvolutionStrategy(mean.tolist(), settings.sigma0, opts)
                while not es.stop():
                    U = np.asarray(es.ask(), float)
                    cost = counted(lb + np.clip(U, 0.0, 1.0) * width)
                    es.tell(list(U), cost.tolist())
                    history.append(counted.best_cost)
            logger.debug("CMA-ES run %d (λ = %d) stopped on %s; best %.6g", restart, popsize,
                         dict(es.stop()), counted.best_cost)
            popsize = int(round(popsize * settings.incpopsize))
            mean = rng.random(dim)
    except BudgetExhaustedError:
        stop = "max_evals"
        history.append(counted.best_cost)
    return counted.result(history, len(history), stop)
