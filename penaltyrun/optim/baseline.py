"""The standard-weights baseline: evaluate one given point (K = scale · I), no search.

Recorded like any optimizer run, so reports can put the baseline (e.g. the Q-law with
K = I) beside the tuned matrices from the same Parquet tables.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from penaltyrun.optim.base import BatchObjective, CountingObjective, OptimResult
from penaltyrun.optim.checks import check_range


@dataclass(frozen=True)
class BaselineSettings:
    """Settings of the baseline evaluation.

    Attributes
    ----------
    scale : float
        Every penalty matrix is ``scale · I`` (all eigenvalues equal ``scale``; the
        orthogonal part is then irrelevant, so every parameterization gives the same K).
    """

    scale: float = 1.0

    def batch_size(self, dim: int) -> int:
        """Candidates the optimizer passes to the objective per call on ``dim`` variables
        (what the forecast times one evaluation of): its one point."""
        return 1

    def validate(self) -> None:
        """Check that ``scale`` is a positive finite number (raises ConfigError)."""
        check_range("optimizer.scale", self.scale, 0.0, lo_open=True)


def run_baseline(objective: BatchObjective, x0: np.ndarray) -> OptimResult:
    """Evaluate the single point ``x0`` (dim,)."""
    counted = CountingObjective(objective)
    cost = float(counted(np.asarray(x0, float)[None, :])[0])
    return counted.result([cost], 1, "baseline")
