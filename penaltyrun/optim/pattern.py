"""Compass search from the optimizer's best: a derivative-free polish whose end is a
checkable certificate even where the criterion jumps (``optimizer.polish: pattern``).

A gradient polish cannot finish next to a jump of the criterion (a deadline met just in
time, a target set an approach only grazes): there is no gradient on the jump's side, and on
the other it certifies one smooth piece only. Compass search (coordinate pattern search;
Kolda, Lewis and Torczon, *SIAM Review* 45(3), 2003) needs no gradient. From the point x it
polls the 2n points x ± h · (ub_i − lb_i) · e_i, a step that would leave the box cut at
its face (so a variable whose best value is a bound ends on it), in one batch of the
problem's kernel; it moves to the best of them when that lowers the cost by more than
:data:`~penaltyrun.optim.probe.NOISE` of it, and otherwise shrinks h tenfold, down the
ladder of :data:`~penaltyrun.optim.probe.STEPS` (1e-3 to 1e-6 of each variable's range).
It ends ``converged`` when a poll at the smallest step fails: no single-variable step of
1e-6 of its range (or to its bound) lowers the cost by more than 1e-8 of it, which is
what the cliff probe checks at its smallest step. The coordinate directions follow the
box's faces, so the search also handles the bounds (Lewis and Torczon, *SIAM J. Optim.*
9(4), 1999).

A compass search is a local method: along a narrow valley it moves by coordinate steps and
can take many polls (the run's budget then ends it, recorded as ``max_evals``).

Why not a library: SciPy has no pattern search, and pymoo's Hooke–Jeeves explores one
coordinate after another, one evaluation at a time; the batched kernels are fastest when a
whole poll is one call.
"""

from __future__ import annotations

import logging

import numpy as np

from penaltyrun.jobrecord import POLISH_CONVERGED
from penaltyrun.optim.base import BudgetExhaustedError, CountingObjective
from penaltyrun.optim.probe import NOISE, STEPS

logger = logging.getLogger(__name__)


def compass_search(counted: CountingObjective, x0: np.ndarray, lb: np.ndarray,
                   ub: np.ndarray, steps: tuple[float, ...] = STEPS) -> str:
    """Polish from ``x0`` by compass search inside [lb, ub] (module docstring).

    Parameters
    ----------
    counted : CountingObjective
        The run's objective; its best candidate and trace are updated as it evaluates.
    x0 : ndarray, shape (dim,)
        Start point (clipped into the box).
    lb, ub : ndarray, shape (dim,)
        Box bounds.
    steps : tuple of float
        Increasing step sizes as fractions of each variable's range; the search starts at
        the largest and ends after a failed poll at the smallest.

    Returns
    -------
    str
        :data:`~penaltyrun.jobrecord.POLISH_CONVERGED` (a poll at the smallest step
        failed) or ``"max_evals"`` (the run's budget ran out first).
    """
    lb, ub = np.asarray(lb, float), np.asarray(ub, float)
    width = ub - lb
    x = np.clip(np.asarray(x0, float), lb, ub)
    start, polls, moves = counted.n_evals, 0, 0
    try:
        fx = float(counted(x[None])[0])
        for step in sorted(steps, reverse=True):
            while True:
                delta = np.diag(step * width)
                poll = np.clip(np.vstack([x + delta, x - delta]), lb, ub)
                poll = poll[(poll != x).any(axis=1)]  # a step from a face onto itself
                if not len(poll):
                    break
                values = counted(poll)
                polls += 1
                j = int(np.argmin(values))
                improved = values[j] < fx - NOISE * abs(fx)
                if improved:
                    x, fx, moves = poll[j].copy(), float(values[j]), moves + 1
                if len(values) < len(poll):  # the budget cut this poll: it is spent
                    raise BudgetExhaustedError
                if not improved:
                    break
        outcome = POLISH_CONVERGED
    except BudgetExhaustedError:
        outcome = "max_evals"
    logger.debug("compass search from the best: %d polls, %d moves, %d evaluations, %s",
                 polls, moves, counted.n_evals - start, outcome)
    return outcome
