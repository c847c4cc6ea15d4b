"""The former CMA-ES path: IPOP restarts around the ``cma`` package (pycma), kept callable
for ``bench_cmaes.py`` and ``cmaes_quality.py`` (penaltyrun's ``cmaes`` optimizer before it
became :mod:`penaltyrun.optim.cma_core`). Same settings class and result; needs the dev
extra (``cma``)."""

from __future__ import annotations

import logging
import math
import warnings

import numpy as np

from penaltyrun.optim.base import (
    BatchObjective,
    BudgetExhaustedError,
    OptimResult,
    as_counting,
    main_budget,
)
from penaltyrun.optim.cmaes import CMAESSettings

logger = logging.getLogger(__name__)


def run_pycma(objective: BatchObjective, lb: np.ndarray, ub: np.ndarray,
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
