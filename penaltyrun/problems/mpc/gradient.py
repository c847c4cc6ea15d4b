"""Exact gradient of the rendezvous MPC cost with respect to the tuned Q and R, where the
QP's active set is fixed along the trajectory.

At step k the controller solves min ½ŨᵀHŨ + (F s_k)ᵀŨ subject to |Ũ_j| ≤ 1 (H, F the
input-scaled condensed data of :func:`~penaltyrun.problems.mpc.controller.qp_matrices`) and
applies u_k = u_max ∘ Ũ_{0:3}. On an active set A (Ũ_A = σ_A = ±1) with free set F the
minimizer is the solution of the KKT system

    H_FF Ũ_F = −(H_FA σ_A + F_F s_k),

a smooth function of (H, F, s_k) while the active set does not change: every free entry
strictly inside its bound and every active bound with a strictly positive multiplier
μ_j = −σ_j (H Ũ + F s_k)_j (strict complementarity). The closed loop
s_{k+1} = A s_k + B u_k is then a smooth recurrence, and the cost a smooth function of the
weights while the arrival step is fixed (strict slack in the convergence test at every
step) and, under ``deadline``, no applied input is zero (‖u‖ has a kink there).

A run that does not arrive (status ``horizon``) costs its criterion's value plus the graded
penalty failure_penalty · (1 + e(s_N) / e0), e(s) = max(‖r‖/pos_tol, ‖v‖/vel_tol): smooth
as well while no state comes within the tolerance and the two parts of e(s_N) differ, and
its gradient is given (so a gradient method that strays onto a failing candidate can come
back).

Reverse mode (one backward sweep over the applied steps, exact identities only): with the
adjoint λ_k of s_k (λ_N = 2 S s_N under ``terminal``, the penalty's failure_penalty / e0 ·
∂e/∂s_N for a run that does not arrive, else 0) and ū_k = ∂φ/∂u_k + Bᵀλ_{k+1}
(φ = Tₛ‖u‖ under ``deadline``, ½Tₛ‖u‖² otherwise), w = H_FF⁻¹ (u_max ∘ ū_k)_F gives

    H̄_{F,:} −= w Ũᵀ,   F̄_F −= w s_kᵀ,   λ_k = Aᵀλ_{k+1} − F_Fᵀ w.

H and F are linear in (Q_p, R_p, P) (Q_p, R_p the physical weights): Q̄_p = Σ_{i<N} Γ_i H̄ Γ_iᵀ
+ Γ_i F̄ Φ_iᵀ, P̄ = Γ_N H̄ Γ_Nᵀ + Γ_N F̄ Φ_Nᵀ, R̄_p = Σ_i H̄_ii (diagonal blocks; each scaled by
diag(u_max)). The terminal weight P solves the DARE of (A_d, B_d, Q_p, R_p); differentiating
it gives dP = A_clᵀ dP A_cl + dQ_p + Kᵀ dR_p K, so one Stein solve Λ = A_cl Λ A_clᵀ + P̄ adds
Λ to Q̄_p and K Λ Kᵀ to R̄_p. Finally Q̄ = diag(1/σ_s) Q̄_p diag(1/σ_s) (and R̄ likewise).

Where the gradient does not exist the result carries the reason: no stabilizing Riccati
solution or a flat failure cost, the Keplerian plant (its relative motion is simulated by
the compiled RK4, not differentiated), a bound of some step's QP within :data:`SWITCH_TOL`
of becoming active or inactive (a free entry within it of its bound, or a bound's
multiplier below it relative to the QP's gradient scale), an arrival step within
:data:`ARRIVAL_TOL` of changing, equal parts of a failed run's final error, or a zero
input under ``deadline``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_discrete_lyapunov

from penaltyrun.problems import criteria
from penaltyrun.problems.base import CostGradient
from penaltyrun.problems.mpc import controller as ctl
from penaltyrun.problems.mpc import criteria as mpc_criteria
from penaltyrun.problems.mpc import scenarios as scen
from penaltyrun.problems.mpc.rendezvous import DARE_FAILURE, HARD_FAILURE_FACTOR

if TYPE_CHECKING:
    from penaltyrun.problems.mpc.rendezvous import RendezvousMPC

#: Distance (in the scaled box, |Ũ| ≤ 1) and multiplier (relative to the QP's gradient
#: scale) below which a bound counts as about to switch.
SWITCH_TOL = 1e-7
#: Distance to its bound (scaled box) within which the solver's entry is on the bound.
ACTIVE_TOL = 1e-9
#: Relative slack the convergence test must keep at every step (arrival step fixed).
ARRIVAL_TOL = 1e-9
#: Largest difference between the active-set solve and the solver's minimizer (scaled box).
REPRODUCE_TOL = 1e-7


def _sym(X: np.ndarray) -> np.ndarray:
    return 0.5 * (X + X.T)


def _qp_solutions(problem: RendezvousMPC, H: np.ndarray, F: np.ndarray,
                  states: np.ndarray) -> np.ndarray:
    """The solver's minimizers Ũ (steps, 3N) at the recorded states, with the same calls
    (set-up, then warm-started updates) as the closed loop."""
    import daqp

    mn = H.shape[0]
    ones = np.ones(mn)
    model = daqp.Model()
    model.setup(H, F @ states[0], np.zeros((0, mn)), ones, -ones)
    model.settings = problem.params.daqp_settings()
    out = np.empty((len(states), mn))
    for k, s in enumerate(states):
        if k:
            model.update(f=F @ s)
        x, _, flag, _ = model.solve()
        if flag != ctl.DAQP_OPTIMAL:
            raise ValueError(f"the QP of step {k} is not solved on re-solving")
        out[k] = x
    return out


def _arrival_reason(problem: RendezvousMPC, states: np.ndarray, arrived: bool) -> str:
    """Why the arrival step is not fixed (empty when every step keeps its slack): the
    convergence test on its boundary at some step (``arrived``: the last state inside the
    tolerance, every earlier one outside; otherwise every state outside)."""
    p = problem.params
    if p.criterion == criteria.TERMINAL:
        return ""
    e = np.maximum(np.linalg.norm(states[:, :3], axis=1) / p.pos_tol_m,
                   np.linalg.norm(states[:, 3:], axis=1) / p.vel_tol_m_s)
    outside = e[:-1] if arrived else e
    if not (np.all(outside > 1.0 + ARRIVAL_TOL) and (not arrived or e[-1] < 1.0 - ARRIVAL_TOL)):
        return ("the arrival step is within round-off of changing (the convergence test is "
                "on its boundary): the cost jumps there (no gradient)")
    return ""


def _terminal_adjoint(problem: RendezvousMPC, s_end: np.ndarray, s0: Any, arrived: bool
                      ) -> np.ndarray | str:
    """∂cost/∂s_N (6,): 2 S s_N under ``terminal``; the graded penalty's
    failure_penalty / e0 · ∂e(s_N)/∂s_N for a run that does not arrive (or why e, a
    maximum of two norms, has a kink there); zero otherwise."""
    p = problem.params
    if p.criterion == criteria.TERMINAL:
        return 2.0 * mpc_criteria.terminal_weight(p) @ s_end
    out = np.zeros(6)
    if arrived:
        return out
    a = float(np.linalg.norm(s_end[:3])) / p.pos_tol_m
    b = float(np.linalg.norm(s_end[3:])) / p.vel_tol_m_s
    if not abs(a - b) > ARRIVAL_TOL * max(a, b):
        return ("the final error's position and velocity parts are equal: the graded "
                "penalty max(‖r‖/pos_tol, ‖v‖/vel_tol) has a kink there (no gradient)")
    if a > b:
        out[:3] = s_end[:3] / (a * p.pos_tol_m ** 2)
    else:
        out[3:] = s_end[3:] / (b * p.vel_tol_m_s ** 2)
    return float(p.failure_penalty) / max(problem.error(s0), 1.0) * out


def mpc_gradient(problem: RendezvousMPC, Q: np.ndarray, R: np.ndarray) -> CostGradient:
    """d cost / d (Q, R) of validated tuned weights Q (6, 6), R (3, 3), or the reason there
    is none (module docstring)."""
    p = problem.params
    sc = scen.training(p)
    Hn, Fn, P, ok = problem.controllers(Q[None], R[None])
    if not ok[0]:
        return CostGradient(HARD_FAILURE_FACTOR * float(p.failure_penalty), DARE_FAILURE,
                            None, {},
                            "status dare_failure: no stabilizing Riccati solution (graded "
                            "penalty)")
    res = problem.run(Hn[0], Fn[0], sc, record=True)
    cost, status = problem.graded(res, sc.s0), str(res.status)  # as evaluate_batch

    def none(reason: str) -> CostGradient:
        return CostGradient(cost, status, None, {}, reason)

    if sc.plant != "cw":
        return none("the Keplerian plant is simulated (compiled RK4), not differentiated: "
                    "no exact gradient")
    arrived = status == ctl.CONVERGED
    fp = float(p.failure_penalty)
    if not (arrived or (status == ctl.HORIZON and cost < HARD_FAILURE_FACTOR * fp)):
        return none(f"status {status}: the cost is a flat failure value (no gradient)")
    states, inputs = res.states, res.inputs
    reason = _arrival_reason(problem, states, arrived)
    if reason:
        return none(reason)
    steps = inputs.shape[0]
    try:
        X = _qp_solutions(problem, Hn[0], Fn[0], states[:steps])
    except ValueError as exc:
        return none(str(exc))
    Qp, Rp = problem.physical_weights(Q[None], R[None])
    H, F = ctl.qp_matrices(problem.Phi, problem.Gam, Qp, Rp, P, problem.u_max,
                           normalize=False)
    H, F = H[0], F[0]
    plant = problem.plant_for(sc)
    fixed = _fixed_active_sets(H, F, X, states)
    if isinstance(fixed, str):
        return none(fixed)
    terminal = _terminal_adjoint(problem, states[steps], sc.s0, arrived)
    if isinstance(terminal, str):
        return none(terminal)
    swept = _backward(H, F, plant.Ad, plant.Bd, problem.u_max, float(p.sample_time_s),
                      p.criterion == criteria.DEADLINE, fixed, states, inputs, terminal)
    if isinstance(swept, str):
        return none(swept)
    Hbar, Fbar = swept
    GQp, GRp = _pull_back(problem, Qp[0], Rp[0], P[0], Hbar, Fbar)
    ds, du = problem.state_weight_scale, problem.input_weight_scale
    GQ = _sym(ds[:, None] * GQp * ds[None, :])
    GR = _sym(du[:, None] * GRp * du[None, :])
    if not (np.all(np.isfinite(GQ)) and np.all(np.isfinite(GR))):
        return none("the adjoint sweep did not give finite values")
    return CostGradient(cost, status, {"Q": GQ, "R": GR}, {}, "")


def _fixed_active_sets(H: np.ndarray, F: np.ndarray, X: np.ndarray, states: np.ndarray
                       ) -> list[tuple[np.ndarray, Any, np.ndarray]] | str:
    """Per step: the free indices, the Cholesky factor of H_FF (shared by the steps with
    the same free set) and the minimizer on its active set; or why the active sets are
    not fixed (a bound within :data:`SWITCH_TOL` of switching, a solve that does not
    reproduce the solver's minimizer)."""
    factors: dict[bytes, Any] = {}
    out = []
    scale_h = float(np.max(np.abs(H)))
    for k, (x, s) in enumerate(zip(X, states)):
        grad = H @ x + F @ s
        free = np.abs(x) < 1.0 - SWITCH_TOL
        act = np.abs(x) >= 1.0 - ACTIVE_TOL
        scale = max(float(np.max(np.abs(grad))), scale_h, 1e-300)
        mu = -np.sign(x[act]) * grad[act]
        if not (np.all(free | act) and np.all(mu > SWITCH_TOL * scale)):
            return (f"the QP's active set is within tolerance of switching at step {k} (a "
                    "bound about to become active or inactive): no gradient")
        fi = np.flatnonzero(free)
        key = free.tobytes()
        if key not in factors:
            factors[key] = cho_factor(H[np.ix_(fi, fi)]) if fi.size else None
        sol = x.copy()
        sol[act] = np.sign(x[act])
        if fi.size:
            sol[fi] = -cho_solve(factors[key], H[fi][:, act] @ sol[act] + F[fi] @ s)
        if np.max(np.abs(sol - x)) > REPRODUCE_TOL:
            return f"the active-set solve does not reproduce the QP solution at step {k}"
        out.append((fi, factors[key], sol))
    return out


def _backward(H: np.ndarray, F: np.ndarray, A: np.ndarray, B: np.ndarray, umax: np.ndarray,
              dt: float, deadline: bool, fixed: list, states: np.ndarray, inputs: np.ndarray,
              terminal: np.ndarray) -> tuple[np.ndarray, np.ndarray] | str:
    """The adjoint sweep (module docstring): H̄ (3N, 3N) and F̄ (3N, 6) of the input-scaled
    QP data, from the terminal adjoint ``terminal`` (6,); or why Δv has a kink."""
    mn = H.shape[0]
    Hbar = np.zeros((mn, mn))
    Fbar = np.zeros((mn, 6))
    lam = terminal
    for k in range(len(fixed) - 1, -1, -1):
        u = inputs[k]
        if deadline:
            nu = float(np.linalg.norm(u))
            if not nu > 0.0:
                return f"the input of step {k} is zero: Δv = Σ Tₛ‖u‖ has a kink there"
            ubar = dt * u / nu
        else:
            ubar = dt * u
        ubar = ubar + B.T @ lam
        lam = A.T @ lam
        fi, factor, x = fixed[k]
        if fi.size:
            xbar = np.zeros(mn)
            xbar[:3] = umax * ubar
            w = cho_solve(factor, xbar[fi])
            Hbar[fi] -= np.outer(w, x)
            Fbar[fi] -= np.outer(w, states[k])
            lam = lam - F[fi].T @ w
    return Hbar, Fbar


def _pull_back(problem: RendezvousMPC, Qp: np.ndarray, Rp: np.ndarray, P: np.ndarray,
               Hbar: np.ndarray, Fbar: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """∂cost/∂(Q_p, R_p) from the adjoints of the input-scaled H, F (module docstring)."""
    Phi, Gam = problem.Phi, problem.Gam
    N = Gam.shape[0] - 1
    scale = np.tile(problem.u_max, N)
    Hb = scale[:, None] * Hbar * scale[None, :]
    Fb = scale[:, None] * Fbar
    GQ = np.einsum("ian,ibn->ab", Gam[1:N] @ Hb, Gam[1:N]) \
        + np.einsum("iac,ibc->ab", Gam[1:N] @ Fb, Phi[1:N])
    GP = Gam[N] @ Hb @ Gam[N].T + Gam[N] @ Fb @ Phi[N].T
    nu = Rp.shape[0]
    GR = sum(Hb[nu * i:nu * (i + 1), nu * i:nu * (i + 1)] for i in range(N))
    A, B = problem.Ad, problem.Bd
    K = np.linalg.solve(Rp + B.T @ P @ B, B.T @ P @ A)
    Acl = A - B @ K
    Lam = _sym(solve_discrete_lyapunov(Acl, _sym(GP)))
    return _sym(GQ) + Lam, _sym(GR) + K @ Lam @ K.T


__all__ = ["ACTIVE_TOL", "ARRIVAL_TOL", "REPRODUCE_TOL", "SWITCH_TOL", "mpc_gradient"]
