"""Particle swarm optimization through pyswarms' ``GlobalBestPSO`` (the only pyswarms user).

Traps handled here (docs: explanation/pso-matlab.md):

* pyswarms draws from the global ``np.random`` state: it is seeded right before the
  optimizer is built, and the caller's state is put back when the run ends
  (:func:`~penaltyrun.optim.base.global_rng_kept`), so a library caller's random numbers
  do not move;
* out-of-bound particles are clamped (``bh_strategy='nearest'``, ≈ MATLAB), not wrapped;
* the whole swarm is evaluated as one batch; ``n_processes`` is never used (the runner
  already runs one job per worker);
* pyswarms' reporter would reconfigure the root logger and write ``report.log`` in the
  working directory: its logger set-up is disabled and its loggers quietened (pyswarms is
  imported at the first run, so the command line's checks do not pay for its imports);
* exact cutoff: each particle's threshold is its personal best before the evaluation
  (``swarm.pbest_cost``, ``inf`` on the first iteration). pyswarms replaces a personal best
  only by a strictly lower cost and derives everything else (global best, velocities, stall
  rule) from personal bests, so a cut value (above the personal best) changes nothing.
"""

from __future__ import annotations

import functools
import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from penaltyrun.optim.base import (
    BatchObjective,
    BudgetExhaustedError,
    CommonSettings,
    OptimResult,
    as_counting,
    global_rng_kept,
    main_budget,
    require_int,
)
from penaltyrun.optim.checks import check_choice, check_range

logger = logging.getLogger(__name__)
_NOOP_LOGGING = str(Path(__file__).with_name("pyswarms_logging.yaml"))


@functools.cache
def load_pyswarms():  # noqa: ANN202
    """pyswarms, imported at the first run (0.4 s of scipy imports the command line's
    checks do not need) with its import-time logging set-up pointed at a no-op config, and
    its later reporters kept from configuring logging or writing ``report.log``."""
    previous = os.environ.get("LOG_CFG")
    os.environ["LOG_CFG"] = _NOOP_LOGGING
    try:
        import pyswarms
        from pyswarms.utils.reporter import reporter
    finally:
        if previous is None:
            del os.environ["LOG_CFG"]
        else:
            os.environ["LOG_CFG"] = previous
    reporter.Reporter._setup_logger = lambda self, path=None: None
    for name in ("pyswarms", "pyswarms.single.global_best", reporter.__name__):
        logging.getLogger(name).setLevel(logging.WARNING)
    return pyswarms


BH_STRATEGIES = ("nearest", "random", "shrink", "reflective", "intermediate", "periodic")
VH_STRATEGIES = ("unmodified", "adjust", "invert", "zero")


@dataclass(frozen=True)
class PSOSettings(CommonSettings):
    """Settings of a global-best PSO run (plus :class:`CommonSettings`: ``max_evals``,
    ``polish``, ``polish_share``).

    Attributes
    ----------
    n_particles : int
        Swarm size.
    iters : int
        Maximum iterations.
    c1, c2 : float
        Cognitive and social coefficients (MATLAB default 1.49).
    w : float
        Inertia weight.
    ftol : float
        Relative stall tolerance: stop when the best cost changes by less than
        ``ftol · (1 + |best|)`` for ``ftol_iter`` consecutive iterations; 0 turns the
        stall rule off.
    ftol_iter : int
        Stall window (MATLAB's MaxStallIterations = 20).
    bh_strategy : str
        pyswarms boundary handling; ``nearest`` clamps to the bound.
    vh_strategy : str
        pyswarms velocity handling for out-of-bound particles.
    """

    n_particles: int = 30
    iters: int = 100
    c1: float = 1.49
    c2: float = 1.49
    w: float = 0.72
    ftol: float = 1e-6
    ftol_iter: int = 20
    bh_strategy: str = "nearest"
    vh_strategy: str = "unmodified"

    def batch_size(self, dim: int) -> int:
        """Candidates the optimizer passes to the objective per call on ``dim`` variables
        (what the forecast times one evaluation of): the swarm, ``n_particles``."""
        return int(self.n_particles)

    def validate(self) -> None:
        """Check ranges and strategy names (and the shared fields).

        Raises
        ------
        ConfigError
            Naming the option (``optimizer.<field>``) and what it must be.
        """
        super().validate()
        for key in ("n_particles", "iters", "ftol_iter"):
            require_int(key, getattr(self, key), 1)
        for key in ("c1", "c2", "w", "ftol"):
            check_range(f"optimizer.{key}", getattr(self, key), 0.0)
        check_choice("optimizer.bh_strategy", self.bh_strategy, BH_STRATEGIES)
        check_choice("optimizer.vh_strategy", self.vh_strategy, VH_STRATEGIES)

    def search_evals(self, dim: int) -> int:
        """At most ``n_particles · iters`` (one swarm per iteration, stall rule aside)."""
        return self.n_particles * self.iters


def run_pso(objective: BatchObjective, lb: np.ndarray, ub: np.ndarray, settings: PSOSettings,
            seed: int, x0: np.ndarray | None = None) -> OptimResult:
    """Minimize ``objective`` over the box [lb, ub] with pyswarms' GlobalBestPSO.

    Parameters
    ----------
    objective : callable
        Batched objective Z (n_particles, dim) → (n_particles,), or a
        :class:`~penaltyrun.optim.base.CountingObjective` already carrying the budget.
    lb, ub : ndarray, shape (dim,)
        Box bounds.
    settings : PSOSettings
    seed : int
        Seed of the global numpy state used by pyswarms.
    x0 : ndarray, shape (dim,), optional
        A known good point (warm start): it replaces the first particle of the uniform
        initial swarm.

    Returns
    -------
    OptimResult
        Stops on the stall rule (``ftol``), the iteration limit (``iters``) or the
        evaluation budget (``max_evals``, the last swarm possibly evaluated in part).
    """
    with global_rng_kept():
        return _run_pso(objective, lb, ub, settings, seed, x0)


def _run_pso(objective: BatchObjective, lb: np.ndarray, ub: np.ndarray, settings: PSOSettings,
             seed: int, x0: np.ndarray | None) -> OptimResult:
    counted = as_counting(objective, main_budget(settings))
    lb, ub = np.asarray(lb, float), np.asarray(ub, float)
    np.random.seed(seed % 2**32)  # noqa: NPY002  (pyswarms draws from the global state)
    init_pos = None
    if x0 is not None:
        init_pos = lb + np.random.random_sample((settings.n_particles, lb.size)) * (ub - lb)  # noqa: NPY002
        init_pos[0] = np.clip(np.asarray(x0, float), lb, ub)
    opt = load_pyswarms().single.GlobalBestPSO(
        n_particles=settings.n_particles,
        dimensions=len(lb),
        options={"c1": settings.c1, "c2": settings.c2, "w": settings.w},
        bounds=(lb, ub),
        bh_strategy=settings.bh_strategy,
        vh_strategy=settings.vh_strategy,
        # ftol 0 (rule off) goes to pyswarms as its own "off", -inf: pyswarms multiplies ftol
        # by 1 + |best so far|, which is inf before the first iteration, and 0 · inf is NaN
        # (a RuntimeWarning per start); no relative change is ever below either value.
        ftol=settings.ftol if settings.ftol > 0 else -np.inf,
        ftol_iter=settings.ftol_iter,
        init_pos=init_pos,
    )

    def objective(positions: np.ndarray) -> np.ndarray:
        # pbest_cost is read before pyswarms updates it with these positions' costs.
        return counted(positions, np.array(opt.swarm.pbest_cost, dtype=float))

    try:
        opt.optimize(objective, iters=settings.iters, verbose=False)
        history = [float(c) for c in opt.cost_history]
        stop = "iters" if len(history) >= settings.iters else "ftol"
    except BudgetExhaustedError:
        history = [float(c) for c in opt.cost_history] + [counted.best_cost]
        stop = "max_evals"
    logger.debug("PSO stopped after %d iterations (%s), best %.6g", len(history), stop,
                 counted.best_cost)
    return counted.result(history, len(history), stop)
