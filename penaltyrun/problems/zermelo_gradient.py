"""Exact gradient of the Zermelo cost d J / d K (:meth:`Zermelo.gradient`).

The cost of a converged gain is J(K) = ∫₀^T ½|U|² dt with T the event time; it is a smooth
function of K there, and :func:`penaltyrun.dynamics.zermelo_sens.cost_gradient` gives its
gradient from the closed form (Fréchet derivative of e^{−Kt}, the event time by the implicit
function theorem, the quadrature differentiated under the integral sign).

A gain whose event does not fire before ``t_max`` (status ``horizon``) costs the graded
penalty J(t_max) + failure_penalty · (1 + ‖X(t_max)‖ / ‖X0‖), also a smooth function of K
away from the status change: its gradient is that of J at the fixed horizon plus
failure_penalty / ‖X0‖ · d‖X(t_max)‖/dK. It is what lets a gradient method that strays
onto a failing gain (an L-BFGS-B line search at the box's edge) come back.

Where the gradient does not exist the result carries the reason instead of a number:

* the status changes next to this gain: the event fires within :data:`SLACK_TOL` · t_max of
  ``t_max``, or misses it by less than :data:`SLACK_TOL` · event_radius (the cost jumps
  between J and the graded penalty there), or the graded penalty is at its ceiling;
* a tangential event (‖X‖ not decreasing at T, rate below :data:`TANGENT_TOL` · λ_max):
  dT/dK is unbounded;
* a gain the closed form does not cover (not symmetric positive definite, a start inside the
  event radius): its cost is integrated, not differentiated;
* a quadrature that does not settle, or disagrees with the cost's own quadrature.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from penaltyrun.dynamics.zermelo_sens import cost_gradient
from penaltyrun.problems.base import CostGradient
from penaltyrun.problems.zermelo import GRADED_CEILING

if TYPE_CHECKING:
    from penaltyrun.problems.zermelo import Zermelo

#: Relative slack t_max − T the event must keep before the deadline for a gradient.
SLACK_TOL = 1e-9
#: Smallest event rate X(T)ᵀKX(T) / ‖X(T)‖², relative to λ_max(K), of a transversal event.
TANGENT_TOL = 1e-12
#: Largest relative difference between the gradient's quadrature of J and the cost's.
COST_AGREEMENT = 1e-8


def zermelo_gradient(problem: Zermelo, K: np.ndarray) -> CostGradient:
    """d J / d K of one validated gain K (2, 2) at the training start, or the reason there
    is none (module docstring)."""
    p = problem.params
    x0 = np.asarray(p.x0, dtype=float)
    d0 = float(np.hypot(*x0))
    t_end, energy, dist, status = problem._run(K[None])
    batch = problem._graded(t_end, energy, dist, status, d0)  # as evaluate_batch
    cost, name = float(batch.cost[0]), str(batch.status[0])

    def none(reason: str) -> CostGradient:
        return CostGradient(cost, name, None, {}, reason)

    lam = np.linalg.eigvalsh(0.5 * (K + K.T))
    if not (lam[0] > 0.0 and d0 > p.event_radius):
        return none("the closed form does not cover this gain (its cost is integrated): "
                    "no exact gradient")
    T = float(t_end[0])
    if batch.converged[0]:
        if not p.t_max - T > SLACK_TOL * p.t_max:
            return none("the event fires at t_max to round-off: the cost jumps to the graded "
                        "penalty next to this gain (no gradient)")
        sens = cost_gradient(K, x0, T, event=True)
        if not sens.event_rate > TANGENT_TOL * lam[-1]:
            return none("the event is tangential (‖X‖ does not decrease at the event "
                        "time): dT/dK is unbounded")
        grad = sens.grad
    else:
        if name != "horizon" or not cost < GRADED_CEILING:
            return none(f"status {name}: the cost is a flat failure value (no gradient)")
        sens = cost_gradient(K, x0, p.t_max, event=False)
        if not sens.dist > p.event_radius * (1.0 + SLACK_TOL):
            return none("the event misses t_max by round-off: the cost jumps from the graded "
                        "penalty to J next to this gain (no gradient)")
        grad = sens.grad + p.failure_penalty / d0 * sens.dist_grad
    if not (sens.settled and np.all(np.isfinite(grad))
            and abs(sens.cost - energy[0]) <= COST_AGREEMENT * abs(energy[0])):
        return none("the gradient's quadrature did not settle (or disagrees with the cost)")
    return CostGradient(cost, name, {"K": grad}, {}, "")


__all__ = ["COST_AGREEMENT", "SLACK_TOL", "TANGENT_TOL", "zermelo_gradient"]
