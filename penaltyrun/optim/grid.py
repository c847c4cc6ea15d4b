"""Exhaustive grid over the box, then a bounded local search from the best grid minima.

For low dimension only (≤ :data:`MAX_DIM`): it answers "is this the global optimum?" for
the two-variable diagonal and three-variable full Zermelo problems. The grid includes both
ends of every side (``points_per_dim`` points each). A grid point is a *grid minimum* when
no neighbour (3^dim − 1 of them) is lower; the ``n_local`` best grid minima are each
polished with a bounded ``scipy.optimize.minimize`` (``local_method``).

No exact cutoff: finding grid minima compares every grid point with its neighbours, and the
local searches need exact values.
"""

from __future__ import annotations

import itertools
import logging
from dataclasses import dataclass

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.optim.base import (
    LOCAL_METHODS,
    BatchObjective,
    BudgetExhaustedError,
    CommonSettings,
    OptimResult,
    as_counting,
    main_budget,
    require_int,
)
from penaltyrun.optim.polish import local_search

logger = logging.getLogger(__name__)

#: Largest dimension the grid accepts.
MAX_DIM = 4
#: Most points a grid may have (its cost array: 8 bytes a point, plus its coordinates).
MAX_GRID_POINTS = 20_000_000


@dataclass(frozen=True)
class GridSettings(CommonSettings):
    """Settings of the grid search (plus :class:`CommonSettings`).

    Attributes
    ----------
    points_per_dim : int
        Grid points per side, both ends included (grid size points_per_dim^dim).
    n_local : int
        Grid minima polished by the local search.
    local_method : str
        Bounded ``scipy.optimize.minimize`` method of the local searches.
    local_max_evals : int
        Evaluations each local search may spend.
    batch : int
        Grid points evaluated per objective call.
    """

    points_per_dim: int = 41
    n_local: int = 5
    local_method: str = "L-BFGS-B"
    local_max_evals: int = 2000
    batch: int = 4096

    def validate(self) -> None:
        """Check ranges (and the shared fields)."""
        super().validate()
        for key in ("points_per_dim", "n_local", "local_max_evals", "batch"):
            require_int(key, getattr(self, key), 2 if key == "points_per_dim" else 1)
        if self.local_method not in LOCAL_METHODS:
            raise ConfigError("optimizer.local_method", f"unknown local search "
                              f"{self.local_method!r}", allowed=LOCAL_METHODS)

    def check_dimension(self, dim: int) -> None:
        """Refuse a box the grid cannot cover.

        Raises
        ------
        ConfigError
            Dimension above :data:`MAX_DIM`, or a ``max_evals`` smaller than the grid.
        """
        if dim > MAX_DIM:
            raise ConfigError("optimizer", f"grid search is for at most {MAX_DIM} decision "
                              f"variables; this problem and map have {dim} (use pso, de or "
                              f"cmaes)")
        size = self.points_per_dim ** dim
        if size > MAX_GRID_POINTS:
            raise ConfigError("optimizer.points_per_dim", f"a grid of {self.points_per_dim}^"
                              f"{dim} = {size:.3g} points is more than {MAX_GRID_POINTS:.0e} "
                              "(its costs alone would not fit in memory); use fewer points "
                              "per side")
        budget = main_budget(self)
        if budget is not None and budget < size:
            raise ConfigError("optimizer.max_evals", f"the grid needs {size} evaluations "
                              f"({self.points_per_dim}^{dim}) before its local searches; "
                              f"budget {budget}")


    def search_evals(self, dim: int) -> int:
        """The grid (points_per_dim^dim) plus ``n_local`` local searches of at most
        ``local_max_evals`` each."""
        return self.points_per_dim ** dim + self.n_local * self.local_max_evals


def grid_minima(cost: np.ndarray) -> np.ndarray:
    """Flat indices of the grid points no neighbour undercuts, best first.

    Parameters
    ----------
    cost : ndarray, shape (p,) * dim
        Costs on the grid.
    """
    padded = np.pad(cost, 1, mode="constant", constant_values=np.inf)
    is_min = np.ones(cost.shape, bool)
    centre = tuple(slice(1, -1) for _ in range(cost.ndim))
    for shift in itertools.product((-1, 0, 1), repeat=cost.ndim):
        if any(shift):
            window = tuple(slice(1 + s, padded.shape[d] - 1 + s) for d, s in enumerate(shift))
            is_min &= padded[centre] <= padded[window]
    flat = np.flatnonzero(is_min.ravel())
    return flat[np.argsort(cost.ravel()[flat], kind="stable")]


def run_grid(objective: BatchObjective, lb: np.ndarray, ub: np.ndarray,
             settings: GridSettings, seed: int, x0: np.ndarray | None = None) -> OptimResult:
    """Evaluate the whole grid, then polish its best minima (``seed``, ``x0`` unused).

    Returns
    -------
    OptimResult
        ``history``: best cost after the grid, then after each local search;
        ``stop_reason``: ``grid+local`` or ``max_evals``.
    """
    lb, ub = np.asarray(lb, float), np.asarray(ub, float)
    settings.check_dimension(lb.size)
    counted = as_counting(objective, main_budget(settings))
    axes = [np.linspace(lo, hi, settings.points_per_dim) for lo, hi in zip(lb, ub)]
    points = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, lb.size)
    history: list[float] = []
    stop = "grid+local"
    try:
        cost = np.concatenate([counted(points[i:i + settings.batch])
                               for i in range(0, len(points), settings.batch)])
        history.append(counted.best_cost)
        starts = grid_minima(cost.reshape((settings.points_per_dim,) * lb.size))
        logger.debug("grid: %d points, %d grid minima, best %.6g", len(points), len(starts),
                     counted.best_cost)
        for index in starts[:settings.n_local]:
            if local_search(counted, points[index], lb, ub, settings.local_method,
                            settings.local_max_evals) == "max_evals":
                stop = "max_evals"
                break
            history.append(counted.best_cost)
    except BudgetExhaustedError:
        stop = "max_evals"
    return counted.result(history, len(history), stop)
