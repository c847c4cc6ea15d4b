"""Optimizer contract: minimize a batched objective over a box.

An objective takes a batch Z of shape (B, dim) and returns B finite costs. Every
optimizer returns an :class:`OptimResult`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

logger = logging.getLogger(__name__)

BatchObjective = Callable[[np.ndarray], np.ndarray]


@dataclass
class OptimResult:
    """Outcome of one optimization run.

    Attributes
    ----------
    best_cost : float
        Lowest objective value found.
    best_z : ndarray, shape (dim,)
        Decision vector achieving it.
    history : list of float
        Best cost after each iteration (generation).
    n_evals : int
        Objective evaluations (candidates, not batches).
    n_iters : int
        Iterations (generations) performed.
    stop_reason : str
        ``"ftol"`` (stall rule), ``"iters"`` (budget exhausted) or optimizer-specific text.
    n_nonfinite : int
        Evaluations that returned a non-finite cost (replaced by the penalty).
    """

    best_cost: float
    best_z: np.ndarray
    history: list[float] = field(default_factory=list)
    n_evals: int = 0
    n_iters: int = 0
    stop_reason: str = ""
    n_nonfinite: int = 0


class CountingObjective:
    """Wrap a batched objective: count evaluations and replace non-finite costs.

    Parameters
    ----------
    func : callable
        Batched objective Z (B, dim) → (B,).
    nonfinite_cost : float
        Value substituted for NaN / inf costs (these are counted and logged, never
        silently passed to the optimizer).
    """

    def __init__(self, func: BatchObjective, nonfinite_cost: float = 1e12) -> None:
        self.func = func
        self.nonfinite_cost = float(nonfinite_cost)
        self.n_evals = 0
        self.n_nonfinite = 0

    def __call__(self, Z: np.ndarray) -> np.ndarray:
        Z = np.atleast_2d(Z)
        cost = np.asarray(self.func(Z), dtype=float).reshape(Z.shape[0])
        bad = ~np.isfinite(cost)
        if bad.any():
            self.n_nonfinite += int(bad.sum())
            logger.warning("%d non-finite costs replaced by %g", int(bad.sum()),
                           self.nonfinite_cost)
            cost = np.where(bad, self.nonfinite_cost, cost)
        self.n_evals += Z.shape[0]
        return cost
