"""Exact gradient of the ``problem=lqr`` cost with respect to the tuned Q̃ and R.

The cost of a converged candidate is J = tr(Σ M) with Σ = mean over the starts of x0 x0ᵀ
and M the finite-horizon cost matrix of the closed loop A_cl = A − B K, W = W_x + Kᵀ W_u K:

* continuous time: M = ∫₀ᵀ e^{A_clᵀt} W e^{A_cl t} dt = S − Eᵀ S E, E = e^{A_cl T},
  A_clᵀ S + S A_cl + W = 0;
* discrete time: M = Σ_{k<N} (A_clᵀ)^k W A_cl^k = S − Eᵀ S E, E = A_cl^N,
  S = A_clᵀ S A_cl + W.

Reverse mode, in three steps (every step an exact identity, no differences):

1. **Cost → (A_cl, W)** (:func:`loop_sensitivity`): with Y = Σ − E Σ Eᵀ, the adjoint
   Lyapunov (Stein) equation A_cl Λ + Λ A_clᵀ + Y = 0 (Λ = A_cl Λ A_clᵀ + Y) gives
   ∂J/∂W = Λ and ∂J/∂A_cl = 2 S Λ (continuous) or 2 S A_cl Λ (discrete), minus the
   horizon term 2 L*(S E Σ) where L* is the adjoint of the derivative of E: T L(A_clᵀ T, ·)
   (the Fréchet derivative of the matrix exponential, :func:`scipy.linalg.expm_frechet`),
   or Σ_{j<N} (A_clᵀ)^j · (A_clᵀ)^{N−1−j} (the (1, 2) block of a block matrix power).
2. **(A_cl, W) → K**: G_K = W_u K (Λ + Λᵀ) − Bᵀ ∂J/∂A_cl.
3. **K → (Q, R) through the Riccati equation** (:func:`riccati_adjoint`): differentiating
   the Riccati equation gives A_clᵀ dP + dP A_cl + dQ + Kᵀ dR K = 0 (discrete:
   dP = A_clᵀ dP A_cl + dQ + Kᵀ dR K) and dK = R⁻¹(Bᵀ dP − dR K) (discrete:
   (R + BᵀPB)⁻¹(Bᵀ dP A_cl − dR K)); one more adjoint Lyapunov (Stein) solve with the
   symmetric part of G_Kᵀ R⁻¹ Bᵀ (discrete: A_cl G_Kᵀ (R + BᵀPB)⁻¹ Bᵀ) gives
   ∂J/∂Q = Λ_P and ∂J/∂R = sym(K Λ_P Kᵀ − R⁻¹ G_K Kᵀ). A structured Q = C_qᵀ Q̃ C_q + Q₀
   gives ∂J/∂Q̃ = C_q Λ_P C_qᵀ.

The gradient exists where the cost is this smooth function: a linear plant without input
limits (closed form or a discrete loop), a stabilizing Riccati solution and every start
``converged`` with slack in the constraints set (``settle_tol``, ``disk_margin_min`` and the
margins it implies). Elsewhere :meth:`LQRProblem.gradient` returns the reason: a simulated
cost (input limits, nonlinear dynamics) is not differentiated, a status other than
``converged`` carries a graded penalty whose kinks and jumps have no gradient, and the
settling-time and overshoot constraints are measured on sampled responses (piecewise).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.linalg import expm, expm_frechet, solve_discrete_lyapunov

from penaltyrun.dynamics.linear import LoopSolution
from penaltyrun.dynamics.lyapunov import SchurLyapunov
from penaltyrun.problems.base import CostGradient

if TYPE_CHECKING:
    from penaltyrun.problems.lqr.problem import LQRProblem

#: Relative slack a constraint must keep for the gradient to be reported (below it the cost
#: is within round-off of its penalty switch).
SLACK_TOL = 1e-9


def _sym(X: np.ndarray) -> np.ndarray:
    return 0.5 * (X + X.T)


def loop_sensitivity(A_cl: np.ndarray, W: np.ndarray, Sigma: np.ndarray, horizon: float,
                     discrete: bool, lyapunov: SchurLyapunov | None = None,
                     solved: LoopSolution | None = None
                     ) -> tuple[float, np.ndarray, np.ndarray]:
    """Cost tr(Σ M) of a stable loop and its gradients with respect to A_cl and W.

    Parameters
    ----------
    A_cl : ndarray, shape (n, n)
        Hurwitz (continuous) or Schur (discrete) closed-loop matrix.
    W : ndarray, shape (n, n)
        Symmetric stage weight.
    Sigma : ndarray, shape (n, n)
        Second moment of the starts, mean x0 x0ᵀ.
    horizon : float
        T (time unit) or, when ``discrete``, the number of steps N.
    discrete : bool
    lyapunov : SchurLyapunov, optional
        Continuous time: the Lyapunov solver of A_cl (one Schur decomposition shared with
        the Riccati adjoint); made here when not given.
    solved : LoopSolution, optional
        Continuous time: the loop's S and e^{A_cl T} as the evaluation computed them (with
        their Schur decomposition, which then replaces ``lyapunov``); computed here when
        not given.

    Returns
    -------
    cost : float
    G_A : ndarray, shape (n, n)
        ∂J/∂A_cl (dJ = Σ_ij G_ij dA_ij).
    G_W : ndarray, shape (n, n)
        ∂J/∂W (symmetric).
    """
    n = A_cl.shape[0]
    if discrete:
        steps = int(horizon)
        S = solve_discrete_lyapunov(A_cl.T, W)
        E = np.linalg.matrix_power(A_cl, steps)
    elif solved is not None:
        lyapunov, S, E = solved.lyapunov, solved.S, solved.E
    else:
        lyapunov = lyapunov or SchurLyapunov(A_cl)
        S = lyapunov.solve(-W, transpose=True)
        E = expm(A_cl * horizon)
    S = _sym(S)
    Y = _sym(Sigma - E @ Sigma @ E.T)
    if discrete:
        Lam = _sym(solve_discrete_lyapunov(A_cl, Y))
        G_A = 2.0 * S @ A_cl @ Lam
        block = np.zeros((2 * n, 2 * n))
        block[:n, :n] = block[n:, n:] = A_cl.T
        block[:n, n:] = S @ E @ Sigma
        G_A -= 2.0 * np.linalg.matrix_power(block, steps)[:n, n:] if steps else 0.0
    else:
        Lam = _sym(lyapunov.solve(-Y))
        G_A = 2.0 * S @ Lam
        G_A -= 2.0 * horizon * expm_frechet(A_cl.T * horizon, S @ E @ Sigma,
                                            compute_expm=False)
    cost = float(np.trace(Sigma @ (S - E.T @ S @ E)))
    return cost, G_A, Lam


def riccati_adjoint(A: np.ndarray, B: np.ndarray, R: np.ndarray, K: np.ndarray,
                    Q_ric: np.ndarray, G_K: np.ndarray, discrete: bool,
                    lyapunov: SchurLyapunov | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Pull ∂J/∂K back through the Riccati equation to ∂J/∂Q and ∂J/∂R.

    Parameters
    ----------
    A, B : ndarray, shapes (n, n), (n, m)
    R : ndarray, shape (m, m)
    K : ndarray, shape (m, n)
        The stabilizing LQR gain of (A, B, Q_ric, R).
    Q_ric : ndarray, shape (n, n)
        The Riccati equation's state penalty.
    G_K : ndarray, shape (m, n)
        ∂J/∂K.
    discrete : bool
    lyapunov : SchurLyapunov, optional
        Continuous time: the Lyapunov solver of A − B K (made here when not given).

    Returns
    -------
    G_Q : ndarray, shape (n, n)
        ∂J/∂Q_ric (symmetric).
    G_R : ndarray, shape (m, m)
        ∂J/∂R (symmetric).
    """
    A_cl = A - B @ K
    if discrete:
        P = _sym(solve_discrete_lyapunov(A_cl.T, Q_ric + K.T @ R @ K))
        M_inv = np.linalg.inv(R + B.T @ P @ B)
        N = _sym(A_cl @ G_K.T @ M_inv @ B.T)
        Lam = _sym(solve_discrete_lyapunov(A_cl, N))
    else:
        M_inv = np.linalg.inv(R)
        N = _sym(G_K.T @ M_inv @ B.T)
        Lam = _sym((lyapunov or SchurLyapunov(A_cl)).solve(-N))
    return Lam, _sym(K @ Lam @ K.T - M_inv @ G_K @ K.T)


def gain_gradient(problem: LQRProblem, Q: np.ndarray, R: np.ndarray, K: np.ndarray,
                  solved: LoopSolution | None = None) -> tuple[float, np.ndarray, np.ndarray]:
    """Cost of one stabilizing gain and d cost / d (Q̃, R) (steps 1–3 of the module
    docstring); Q̃ (p, p), R (m, m), K (m, n) its LQR gain; ``solved`` the loop of K as
    the evaluation solved it (continuous time; solved here when not given)."""
    A, B = problem.plant.A, problem.plant.B
    X0 = problem.x0
    Sigma = X0.T @ X0 / X0.shape[0]
    A_cl = A - B @ K
    W = problem.Wx + K.T @ problem.Wu @ K
    discrete = problem.dt is not None
    if discrete:
        from penaltyrun.problems.lqr.discrete import n_steps

        horizon: float = n_steps(problem.t_max, float(problem.dt))
    else:
        horizon = problem.t_max
    if discrete:
        lyapunov = None
    else:
        lyapunov = solved.lyapunov if solved is not None else SchurLyapunov(A_cl)
    cost, G_A, G_W = loop_sensitivity(A_cl, W, Sigma, horizon, discrete, lyapunov, solved)
    G_K = problem.Wu @ K @ (G_W + G_W.T) - B.T @ G_A
    Q_ric = problem.state_penalty(Q[None])[0]
    G_Qric, G_R = riccati_adjoint(A, B, R, K, Q_ric, G_K, discrete, lyapunov)
    C = problem.q_output
    return cost, _sym(C @ G_Qric @ C.T), G_R


def no_gradient_reason(problem: LQRProblem, res: dict[str, Any]) -> str:
    """Why the cost of the single candidate in ``res`` (:meth:`LQRProblem.rows`) has no
    gradient; empty when it has one."""
    if not (problem.plant.linear and problem.u_max is None):
        return ("the cost is simulated (input limits u_max or nonlinear dynamics): no exact "
                "gradient")
    lim = problem.limits
    if lim.settling_time_max is not None or lim.overshoot_max is not None:
        return ("settling_time_max / overshoot_max are measured on sampled responses "
                "(piecewise): no exact gradient")
    if not res["ok"][0]:
        return "status care_failure: no stabilizing Riccati solution (graded penalty)"
    statuses = sorted({str(s) for s in res["status"][0]})
    if statuses != ["converged"]:
        return (f"status {', '.join(statuses)}: the cost carries a graded penalty there (no "
                "gradient)")
    if lim.disk_margin_min is not None:
        slack = (res["disk_margin"][0] - lim.disk_margin_min) / lim.disk_margin_min
        if not slack > SLACK_TOL:
            return "the disk-margin constraint is active (a kink of the cost)"
    tol = problem.params.settle_tol
    if tol is not None:
        ratio = np.linalg.norm(res["x_final"][0], axis=1) / np.linalg.norm(problem.x0, axis=1)
        if not np.all(ratio < tol * (1.0 - SLACK_TOL)):
            return "settle_tol is active (a kink of the cost)"
    return ""


def lqr_gradient(problem: LQRProblem, Q: np.ndarray, R: np.ndarray) -> CostGradient:
    """:meth:`LQRProblem.gradient` of validated Q̃ (p, p), R (m, m)."""
    res = problem.rows(Q[None], R[None], problem.x0)
    cost, _, status = problem._aggregate(res)
    reason = no_gradient_reason(problem, res)
    if reason:
        return CostGradient(float(cost[0]), str(status[0]), None, {}, reason)
    _, G_Q, G_R = gain_gradient(problem, Q, R, res["K"][0], res.get("loop"))
    if not (np.all(np.isfinite(G_Q)) and np.all(np.isfinite(G_R))):
        return CostGradient(float(cost[0]), str(status[0]), None, {},
                            "the adjoint Lyapunov solves did not give finite values")
    return CostGradient(float(cost[0]), str(status[0]), {"Q": G_Q, "R": G_R}, {}, "")


__all__ = ["SLACK_TOL", "gain_gradient", "loop_sensitivity", "lqr_gradient",
           "no_gradient_reason", "riccati_adjoint"]
