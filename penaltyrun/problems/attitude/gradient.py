"""Exact gradient of the attitude cost with respect to the tuned matrices, on the well-posed
criteria.

Both laws feed the nonlinear rigid body through one gain G (3 × 6), u = −G x with
x = (q_v, ω), so the gradient has two stages:

1. **Cost → G** by forward sensitivities (:mod:`penaltyrun.dynamics.attitude_sens`): the
   closed loop and Y = ∂y/∂g, e = ∂E/∂g (g = vec(G), 18 entries) integrated together.

   * ``terminal``: J = E(T) + x(T)ᵀ S x(T) with T fixed, so
     ∂J/∂g = e(T) + 2 x(T)ᵀ S Y_x(T) (Y_x the rows of Y for x).
   * ``time_energy``: J = E(t_f) + ρ t_f with t_f the first time the weighted distance
     d(y) = ‖(w_q0 (q0 − 1), w_qv q_v, w_ω ω)‖ falls to ``tol``. The implicit function
     theorem on d(y(t_f; g)) = tol gives dt_f/dg = −(∂d/∂y · Y(t_f)) / ḋ(t_f), with
     ḋ = ∂d/∂y · f the slope of the distance at arrival, and
     dJ/dg = e(t_f) + (½ uᵀu(t_f) + ρ) dt_f/dg.

2. **G → matrices**: the PD law G = [K_p, K_d] takes the two 3 × 3 blocks of ∂J/∂G
   (symmetrized: the matrices are symmetric); the LQR law G = R⁻¹BᵀP pulls ∂J/∂G back
   through the continuous algebraic Riccati equation by one adjoint Lyapunov solve
   (:func:`penaltyrun.problems.lqr.gradient.riccati_adjoint`).

Where there is no gradient the result is ``None`` with the reason:

* ``deadline`` (the paper's criterion): its optima sit where the run arrives just before
  the deadline, on the edge where the cost jumps to the failure penalty;
* a status other than ``converged`` (a graded penalty, a Riccati failure);
* a torque limit reached on the way (the torque has a kink there);
* ``time_energy``: an arrival that is not transversal (ḋ(t_f) within round-off of 0), or an
  earlier local minimum of d within :data:`GRAZE_TOL` of ``tol`` (the arrival time jumps
  there); the production kernel and the sensitivity run disagreeing on the arrival time by
  more than :data:`ARRIVAL_RTOL` (a dip one of them stepped over).

The cost reported is the production kernel's (:meth:`AttitudeProblem.evaluate_batch`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from penaltyrun.dynamics import attitude_sens as sens
from penaltyrun.problems import criteria
from penaltyrun.problems.attitude import criteria as attitude_criteria
from penaltyrun.problems.attitude.reference import reference_max_step
from penaltyrun.problems.base import CostGradient

if TYPE_CHECKING:
    from penaltyrun.problems.attitude.common import AttitudeProblem

#: An earlier local minimum of the distance closer than this (relative) to ``tol`` makes
#: the arrival time jump under a perturbation of that size: no gradient is reported.
GRAZE_TOL = 1e-6
#: The arrival slope −ḋ(t_f)·t_f/tol below which the crossing counts as tangent.
TRANSVERSAL_TOL = 1e-6
#: Largest difference of the kernel's and the sensitivity run's arrival times, relative to
#: max(1 s, t_f). A dip one of them steps over moves the arrival by a good part of an
#: oscillation; both runs locate a crossing to about 1e-6 s at their tolerances, so
#: 1e-4 leaves a wide margin for round-off and none for a skipped dip.
ARRIVAL_RTOL = 1e-4
#: Reason given under the paper's criterion.
DEADLINE_REASON = ("criterion deadline has no gradient at its optima: they arrive just "
                   "before t_max, where the cost jumps to the failure penalty; use "
                   "criterion=terminal or criterion=time_energy")


def _sym(X: np.ndarray) -> np.ndarray:
    return 0.5 * (X + X.T)


def gain_sensitivity(problem: AttitudeProblem, G: np.ndarray, t_final: float
                     ) -> tuple[np.ndarray | None, str, float]:
    """∂J/∂G (3 × 6) of one gain under the problem's well-posed criterion.

    Parameters
    ----------
    problem : AttitudeProblem
        With ``criterion`` ``terminal`` or ``time_energy``.
    G : ndarray, shape (3, 6)
        The gain.
    t_final : float
        The production kernel's end time (s), checked against the sensitivity run.

    Returns
    -------
    grad : ndarray, shape (3, 6), or None
    reason : str
        Why there is no gradient (empty when there is one).
    cost : float
        The criterion value of the sensitivity run (N²·m²·s).
    """
    p = problem.params
    weights = p.event_weights()
    terminal = p.criterion == criteria.TERMINAL
    # the step bound keeps a short dip under tol (or a short touch of u_max) from being
    # stepped over; a fixed horizon without a torque limit has neither
    bounded = not terminal or np.isfinite(p.saturation())
    run = sens.sensitivity_run(
        G, problem.y0, problem.inertia, float(p.t_max if terminal else p.free_time_cap),
        weights, None if terminal else float(p.tol), p.saturation(),
        rtol=min(float(p.rtol), 1e-10), atol=min(float(p.atol), 1e-10),
        max_step=reference_max_step(p) if bounded else np.inf,
        event_spacing=float(p.event_spacing), n_samples=int(p.n_event_samples),
        max_steps=int(p.max_steps))
    if run.status == "saturated":
        return None, "the torque reaches u_max on the way (a kink of the cost)", float("nan")
    if run.status == "failed":
        return None, f"the sensitivity integration failed ({run.message})", float("nan")
    if terminal:
        if run.status != "horizon":
            return None, "the sensitivity run did not reach t_max", float("nan")
        S = attitude_criteria.terminal_weight(p)
        x = run.y[1:7]
        grad = run.e + 2.0 * (x @ S) @ run.Y[1:7]
        return grad.reshape(3, 6), "", run.energy + float(x @ S @ x)
    if run.status != "arrived":
        return None, "the sensitivity run did not arrive by free_time_cap", float("nan")
    tol = float(p.tol)
    if abs(run.t_end - t_final) > ARRIVAL_RTOL * max(1.0, t_final):
        return None, (f"the arrival time of the kernel ({t_final:.9g} s) and of the "
                      f"sensitivity run ({run.t_end:.9g} s) differ: a dip of the distance "
                      "near tol"), float("nan")
    if run.dips.size and float(np.min(run.dips)) <= tol * (1.0 + GRAZE_TOL):
        return None, ("an earlier local minimum of the distance touches tol (the arrival "
                      "time jumps there)"), float("nan")
    d_y = sens.distance_gradient(run.y, weights)
    slope = float(d_y @ run.f[:7])
    if not slope < -TRANSVERSAL_TOL * tol / max(run.t_end, 1e-300):
        return None, ("the distance does not cross tol transversally at arrival (no "
                      "implicit-function derivative of the arrival time)"), float("nan")
    dt_dg = -(d_y @ run.Y) / slope
    grad = run.e + (run.f[7] + float(p.rho)) * dt_dg
    return grad.reshape(3, 6), "", run.energy + float(p.rho) * run.t_end


def lqr_pullback(problem: AttitudeProblem, Q: np.ndarray, R: np.ndarray, K: np.ndarray,
                 G_K: np.ndarray) -> dict[str, np.ndarray]:
    """∂J/∂Q (6 × 6) and ∂J/∂R (3 × 3) from ∂J/∂K through the Riccati equation of the
    linearized model (A, B) (:func:`penaltyrun.problems.lqr.gradient.riccati_adjoint`)."""
    from penaltyrun.problems.attitude.lqr import linear_model
    from penaltyrun.problems.lqr.gradient import riccati_adjoint

    A, B = linear_model(problem.inertia)
    G_Q, G_R = riccati_adjoint(A, B, R, K, Q, G_K, discrete=False)
    return {"Q": G_Q, "R": G_R}


def attitude_gradient(problem: AttitudeProblem, mats: Mapping[str, Any]) -> CostGradient:
    """:meth:`AttitudeProblem.gradient` of one candidate ``mats`` (validated here)."""
    checked = problem._check(mats)
    G, ok = problem.gains({k: v[None] for k, v in checked.items()})
    res = problem._finish(G, ok, None, problem.d0)
    cost, status = float(res["cost"][0]), str(res["status"][0])
    crit = problem.params.criterion
    if crit == criteria.DEADLINE:
        return CostGradient(cost, status, None, {}, DEADLINE_REASON)
    if status != "converged":
        return CostGradient(cost, status, None, {},
                            f"status {status}: the cost carries a graded penalty there (no "
                            "gradient)")
    grad, reason, _ = gain_sensitivity(problem, G[0], float(res["t_final"][0]))
    if grad is None:
        return CostGradient(cost, status, None, {}, reason)
    if set(checked) == {"Kp", "Kd"}:
        out = {"Kp": _sym(grad[:, :3]), "Kd": _sym(grad[:, 3:])}
    else:
        out = lqr_pullback(problem, checked["Q"], checked["R"], G[0], grad)
    if not all(np.all(np.isfinite(v)) for v in out.values()):
        return CostGradient(cost, status, None, {}, "non-finite sensitivities")
    return CostGradient(cost, status, out, {}, "")


__all__ = ["ARRIVAL_RTOL", "DEADLINE_REASON", "GRAZE_TOL", "TRANSVERSAL_TOL",
           "attitude_gradient", "gain_sensitivity", "lqr_pullback"]
