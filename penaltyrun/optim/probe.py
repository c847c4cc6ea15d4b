"""Probe a tuned point for cliffs: how much the cost changes when one decision variable
moves by a small fraction of its range.

An optimizer's best point can sit next to a discontinuity of the criterion: a deadline the
run just meets, or (under a free final time) an approach that only just enters the target's
tolerance set, so that a slightly different gain misses it and arrives one oscillation
later. There no gradient describes the cost, a local refinement cannot certify anything,
and a search keeps creeping along the edge. The probe measures it directly: for each
variable i, each side s ∈ {−, +} and each step h of a ladder (fractions of the variable's
range ub − lb), it evaluates

    Δ(h, i, s) = (J(z + s · h · (ub_i − lb_i) · e_i) − J(z)) / |J(z)|

in one batch. A smooth cost changes by about |∂J/∂z_i| · h · width (or by h² at an interior
minimum), so the largest |Δ| falls by a factor of 10 to 100 per rung of a ladder of
decades; a cliff within reach of a step shows a change that does not shrink with the step.
Steps that would leave the box are not taken (NaN).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: Default ladder of steps, as fractions of each variable's range.
STEPS = (1e-6, 1e-5, 1e-4, 1e-3)
#: A relative cost change from one step this large or larger is called a cliff.
CLIFF = 0.01
#: A relative fall smaller than this is taken as the cost's numerical noise (integration
#: tolerances of 1e-10 and rounding), not as a step that lowers the cost.
NOISE = 1e-8


@dataclass(frozen=True)
class CliffProbe:
    """What :func:`probe` measured around one point.

    Attributes
    ----------
    steps : ndarray, shape (K,)
        The ladder of steps, fractions of each variable's range (increasing).
    cost : float
        J(z), the cost at the point.
    converged : bool
        Whether the point's run met its terminal condition.
    change : ndarray, shape (K, n, 2)
        Relative cost change Δ(h, i, s), side 0 the step down and side 1 the step up;
        NaN where the step leaves the box.
    status_change : ndarray of bool, shape (K, n, 2)
        Where the stepped run's ``converged`` differs from the point's.
    """

    steps: np.ndarray
    cost: float
    converged: bool
    change: np.ndarray
    status_change: np.ndarray

    def largest(self) -> np.ndarray:
        """Largest |Δ| over variables and sides at each step, shape (K,); NaN where no step
        of that size stays in the box."""
        a = np.abs(self.change).reshape(len(self.steps), -1)
        taken = np.isfinite(a)
        return np.where(taken.any(axis=1), np.where(taken, a, -np.inf).max(axis=1), np.nan)

    def worst_variable(self) -> np.ndarray:
        """Index of the variable with the largest |Δ| at each step, shape (K,) (−1 where no
        step was taken)."""
        a = np.abs(self.change)
        a = np.where(np.isfinite(a), a, -np.inf).max(axis=2)
        return np.where(np.isfinite(a).any(axis=1), a.argmax(axis=1), -1)

    def lowest(self) -> tuple[float, float]:
        """The most negative Δ of the probe and its step, (Δ, h); (0, NaN) when no step
        lowered the cost by more than :data:`NOISE`. A step that lowers the cost shows that
        the point is not a local minimum along that variable at that scale."""
        a = np.where(np.isfinite(self.change), self.change, np.inf)
        k, i, s = np.unravel_index(np.argmin(a), a.shape)
        low = float(a[k, i, s])
        return (low, float(self.steps[k])) if low < -NOISE else (0.0, float("nan"))

    def smallest_cliff_step(self, threshold: float = CLIFF) -> float:
        """The smallest step of the ladder at which some variable's |Δ| reaches
        ``threshold`` or the run's convergence changes; NaN where none does."""
        a = np.abs(self.change)
        hit = ((a >= threshold) & np.isfinite(a)) | self.status_change
        rungs = np.flatnonzero(hit.reshape(len(self.steps), -1).any(axis=1))
        return float(self.steps[rungs[0]]) if rungs.size else float("nan")


def probe(cost_batch: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
          z: np.ndarray, lb: np.ndarray, ub: np.ndarray,
          steps: tuple[float, ...] = STEPS) -> CliffProbe:
    """Evaluate the one-variable steps of the ladder around ``z`` in one batch.

    Parameters
    ----------
    cost_batch : callable
        ``cost_batch(Z)`` with Z of shape (B, n) returns (cost (B,), converged (B,) bool).
    z : ndarray, shape (n,)
        The point (inside the box).
    lb, ub : ndarray, shape (n,)
        The box.
    steps : tuple of float
        Increasing positive fractions of each variable's range.

    Returns
    -------
    CliffProbe

    Raises
    ------
    ValueError
        ``z`` outside the box, a non-increasing or non-positive ladder, or a zero cost
        (relative changes are undefined).
    """
    z, lb, ub = (np.asarray(v, float) for v in (z, lb, ub))
    h = np.asarray(steps, float)
    if h.ndim != 1 or not h.size or (h <= 0).any() or (np.diff(h) <= 0).any():
        raise ValueError(f"steps must be increasing positive fractions, got {steps}")
    if not ((lb <= z) & (z <= ub)).all():
        raise ValueError("z lies outside the box")
    n, k = z.size, h.size
    delta = h[:, None, None] * (ub - lb)[None, :, None] * np.array([-1.0, 1.0])[None, None]
    moved = z[None, :, None] + delta  # (K, n, 2): the stepped variable's new value
    inside = (moved >= lb[None, :, None]) & (moved <= ub[None, :, None])
    where = np.argwhere(inside)
    batch = np.repeat(z[None], len(where) + 1, axis=0)
    batch[np.arange(1, len(where) + 1), where[:, 1]] = moved[inside]
    cost, converged = cost_batch(batch)
    cost, converged = np.asarray(cost, float), np.asarray(converged, bool)
    j0 = float(cost[0])
    if j0 == 0.0:
        raise ValueError("the cost at z is 0: relative changes are undefined")
    change = np.full((k, n, 2), np.nan)
    status = np.zeros((k, n, 2), bool)
    change[inside] = (cost[1:] - j0) / abs(j0)
    status[inside] = converged[1:] != converged[0]
    return CliffProbe(h, j0, bool(converged[0]), change, status)
