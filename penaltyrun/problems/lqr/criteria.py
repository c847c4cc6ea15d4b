"""The well-posed criteria in ``problem=lqr`` terms (see :mod:`penaltyrun.problems.criteria`).

The problem's own cost is already a fixed-horizon quadratic performance cost,
J = mean over x0 of ∫₀ᵀ (xᵀW_x x + uᵀW_u u) dt (a sum over steps for a sampled plant),
and with W_x > 0 it is not ill-posed the way a minimum-energy deadline is. The two
criteria mean here:

``terminal``
    The same J plus a terminal penalty per start, J + x(T)ᵀ S x(T), T = ``t_max``. The
    default S is P*, the stabilizing Riccati solution of (A, B, W_x, W_u) on the linear
    model (continuous, or discrete with ``dt``): x(T)ᵀP*x(T) is the least cost the best
    linear controller would still need after T, so J + x(T)ᵀP*x(T) approximates the
    infinite-horizon cost without integrating further. S is in cost units per squared
    state unit (for a sampled plant: per step sum). Every path (closed form, integrated,
    sampled) supports it.
``time_energy``
    Time to settle plus the performance cost: J = ∫₀^{t_s} (xᵀW_x x + uᵀW_u u + ρ) dt, t_s
    the first time ‖x(t)‖ ≤ ``settle_tol`` · ‖x0‖ (``settle_tol`` defaults to 0.01 under
    this criterion), searched up to ``free_time_cap`` (default 1 000 time units). ρ is in
    cost units per time unit (default 0.01). A start that has not settled by the cap costs
    J(cap) + ρ · cap + P (1 + r / (1 + r)), r = ‖x(cap)‖ / ‖x0‖ (``not_settled``, the
    problem's graded penalty). Sampled plant: J = Σ_{k < k_s} (x_kᵀW_x x_k + u_kᵀW_u u_k)
    + ρ k_s dt, k_s the first settled sample. Continuous linear plants without input
    limits: exact propagation by matrix exponentials (the settling time is found
    with steps no longer than the time ‖x‖ needs to reach the level at the fastest rate
    ‖A − BK‖₂ allows, at least 0.05 / ‖A − BK‖₂ — a dip under the level between two
    steps that short is never deeper than 5 % — then safeguarded Newton to 1e-13 of the
    step). Saturated or nonlinear continuous loops: the vectorized Dormand–Prince
    integrator (:mod:`penaltyrun.dynamics.linear_feedback`) with its settling event,
    checked at the end of every accepted step and located inside it by bisection; a start
    that diverges or fails there is graded as in the deadline criterion.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.problems import criteria

#: Default ``settle_tol`` of ``time_energy`` (‖x(t_s)‖ = 1 % of ‖x0‖).
DEFAULT_SETTLE = 0.01
#: Default ρ of ``time_energy`` (cost units per time unit).
DEFAULT_RHO = 0.01
#: Shortest search step, in units of 1 / ‖A − BK‖₂ (continuous settling search).
MIN_STEP = 0.05
#: Largest number of search steps per start before the search gives up (not settled).
MAX_SEARCH = 100_000


def settle_level(params: Any) -> float:
    """Relative settling level of ``time_energy`` (``settle_tol`` or 0.01)."""
    return DEFAULT_SETTLE if params.settle_tol is None else float(params.settle_tol)


def terminal_weight(problem: Any) -> np.ndarray:
    """S (n × n, n the loop's state size) of ``terminal``: ``terminal_weight`` or P*.

    Raises
    ------
    ConfigError
        A bad ``terminal_weight``, or none given and no stabilizing Riccati solution of
        (A, B, W_x, W_u).
    """
    p = problem.params
    n = problem.plant.n_states
    key = "problem.params.terminal_weight"
    if p.terminal_weight is not None:
        return criteria.terminal_matrix(p.terminal_weight, n, key)
    from scipy.linalg import solve_continuous_are, solve_discrete_are

    solve = solve_continuous_are if problem.dt is None else solve_discrete_are
    try:
        S = solve(problem.plant.A, problem.plant.B, problem.Wx, problem.Wu)
    except (np.linalg.LinAlgError, ValueError):
        S = None
    if S is None or not np.all(np.isfinite(S)):
        raise ConfigError(key, "no default: the Riccati equation of (state_weight, "
                          "input_weight) has no stabilizing solution; give S")
    return 0.5 * (S + S.T)


def _expm(M: np.ndarray) -> np.ndarray:
    from scipy.linalg import expm

    return expm(M)


def _running_cost(A_cl: np.ndarray, W: np.ndarray, X0: np.ndarray, t: np.ndarray
                  ) -> np.ndarray:
    """x0ᵀ (∫₀ᵗ e^{A_clᵀs} W e^{A_cl s} ds) x0 per (candidate, start) by Van Loan's block
    exponential; A_cl, W (C, n, n), X0 (k, n), t (C, k) → (C, k)."""
    n_c, n = A_cl.shape[0], A_cl.shape[1]
    block = np.zeros((n_c, 2 * n, 2 * n))
    block[:, :n, :n] = -np.swapaxes(A_cl, 1, 2)
    block[:, :n, n:] = W
    block[:, n:, n:] = A_cl
    E = _expm(block[:, None] * t[:, :, None, None])
    M = np.swapaxes(E[..., n:, n:], -1, -2) @ E[..., :n, n:]
    return np.einsum("ki,ckij,kj->ck", X0, M, X0)


class _Flow:
    """x(t) = e^{A t} x0 for rows of (A, x0): modal form V e^{Λt} V⁻¹ x0 where the
    eigenvectors are well conditioned (as :func:`penaltyrun.dynamics.linear.quadratic_cost`),
    scipy's ``expm`` elsewhere."""

    def __init__(self, A: np.ndarray, x0: np.ndarray) -> None:
        from penaltyrun.dynamics.linear import COND_MAX

        self.A, self.x0 = A, x0
        with np.errstate(all="ignore"):
            try:
                lam, V = np.linalg.eig(A)
                cond = np.linalg.cond(V)
                good = np.isfinite(cond) & (cond < COND_MAX) & np.all(np.isfinite(lam), 1)
            except np.linalg.LinAlgError:
                lam, V, good = None, None, np.zeros(A.shape[0], dtype=bool)
        self.good = good
        if good.any():
            self.lam, self.V = lam, V
            self.c = np.zeros(lam.shape, dtype=complex)
            self.c[good] = np.linalg.solve(V[good], x0[good].astype(complex)[..., None])[..., 0]

    def cost(self, W: np.ndarray, t: np.ndarray) -> np.ndarray:
        """∫₀ᵗ xᵀ W x ds per row (W (R, n, n), t (R,)): modal sums
        Σ_ij c̄_i c_j (VᴴWV)_ij (e^{(λ̄_i+λ_j)t} − 1) / (λ̄_i + λ_j), Van Loan's block
        exponential where the modal form is not used."""
        out = np.empty(t.shape)
        g = np.flatnonzero(self.good)
        if g.size:
            V, lam, c = self.V[g], self.lam[g], self.c[g]
            G = np.swapaxes(V.conj(), 1, 2) @ W[g] @ V
            s = lam.conj()[:, :, None] + lam[:, None, :]
            tt = t[g][:, None, None]
            with np.errstate(all="ignore"):
                small = np.abs(s * tt) < 1e-8
                factor = np.where(small, tt * (1.0 + 0.5 * s * tt),
                                  np.expm1(s * tt) / np.where(small, 1.0, s))
            out[g] = np.einsum("ri,rij,rj->r", c.conj(), G * factor, c).real
        for i in np.flatnonzero(~self.good):
            out[i] = _running_cost(self.A[i][None], W[i][None], self.x0[i][None],
                                   t[i].reshape(1, 1))[0, 0]
        return out

    def at(self, rows: np.ndarray, t: np.ndarray) -> np.ndarray:
        """States of ``rows`` at times ``t`` (len(rows),) → (len(rows), n)."""
        out = np.empty((rows.size, self.x0.shape[1]))
        modal = self.good[rows]
        if modal.any():
            r = rows[modal]
            z = np.exp(self.lam[r] * t[modal][:, None]) * self.c[r]
            out[modal] = np.einsum("rij,rj->ri", self.V[r], z).real
        for i in np.flatnonzero(~modal):
            out[i] = _expm(self.A[rows[i]] * t[i]) @ self.x0[rows[i]]
        return out


def _crossing(flow: _Flow, rows: np.ndarray, lo: np.ndarray, hi: np.ndarray,
              target: np.ndarray) -> np.ndarray:
    """Time s ∈ (lo, hi] where ‖x(s)‖ falls to ``target`` per row, given ‖x(lo)‖ > target
    ≥ ‖x(hi)‖: safeguarded Newton on ‖x(s)‖² − target² (bisection when a Newton step
    leaves the bracket), until the bracket is 1e-13 of the time."""
    lo, hi = lo.copy(), hi.copy()
    s = hi.copy()
    A = flow.A[rows]
    for _ in range(200):
        xs = flow.at(rows, s)
        g = np.einsum("ri,ri->r", xs, xs) - target ** 2
        slope = 2.0 * np.einsum("ri,rij,rj->r", xs, A, xs)
        lo = np.where(g > 0.0, s, lo)
        hi = np.where(g <= 0.0, s, hi)
        if np.all(hi - lo <= 1e-13 * np.maximum(hi, 1e-300)):
            break
        with np.errstate(all="ignore"):
            newton = s - g / slope
        inside = np.isfinite(newton) & (newton > lo) & (newton < hi)
        s = np.where(inside, newton, 0.5 * (lo + hi))
    return hi


def settle_continuous(A_cl: np.ndarray, W: np.ndarray, X0: np.ndarray, level: float,
                      cap: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """First time ‖x(t)‖ ≤ level · ‖x0‖ of ẋ = A_cl x (before ``cap``), its running cost
    and state (see the module docstring for the search).

    Parameters
    ----------
    A_cl, W : ndarray, shape (C, n, n)
    X0 : ndarray, shape (k, n)
    level : float
    cap : float

    Returns
    -------
    t_s : ndarray, shape (C, k)
        Settling time, or ``cap`` where not settled.
    cost : ndarray, shape (C, k)
        ∫₀^{t_s} xᵀ W x dt.
    x_end : ndarray, shape (C, k, n)
    settled : ndarray of bool, shape (C, k)
    """
    n_c, n_k, n = A_cl.shape[0], X0.shape[0], X0.shape[1]
    flow = _Flow(np.repeat(A_cl, n_k, axis=0), np.tile(X0, (n_c, 1)))
    norm_A = np.maximum(np.linalg.norm(flow.A, ord=2, axis=(1, 2)), 1e-300)
    x = flow.x0.copy()
    target = level * np.linalg.norm(x, axis=1)
    t = np.zeros(n_c * n_k)
    done = np.linalg.norm(x, axis=1) <= target
    with np.errstate(all="ignore"):
        for _ in range(MAX_SEARCH):
            live = np.flatnonzero(~done & (t < cap))
            if not live.size:
                break
            r = np.linalg.norm(x[live], axis=1)
            tau = np.maximum(np.log(r / target[live]), MIN_STEP) / norm_A[live]
            t_new = np.minimum(t[live] + tau, cap)
            x_new = flow.at(live, t_new)
            crossed = np.linalg.norm(x_new, axis=1) <= target[live]
            if crossed.any():
                rows = live[crossed]
                t_new[crossed] = _crossing(flow, rows, t[rows], t_new[crossed], target[rows])
                x_new[crossed] = flow.at(rows, t_new[crossed])
                done[rows] = True
            x[live], t[live] = x_new, t_new
    cost = flow.cost(np.repeat(W, n_k, axis=0), t)
    return (t.reshape(n_c, n_k), cost.reshape(n_c, n_k), x.reshape(n_c, n_k, n),
            done.reshape(n_c, n_k))


def settle_sampled(A: np.ndarray, B: np.ndarray, K: np.ndarray, X0: np.ndarray,
                   Wx: np.ndarray, Wu: np.ndarray, u_max: np.ndarray | None, level: float,
                   steps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First sample k_s with ‖x_k‖ ≤ level · ‖x0‖ of x_{k+1} = A x_k + B sat(−K x_k),
    at most ``steps``; the stage-cost sum over k < k_s and the state there.

    Returns
    -------
    k_s : ndarray of int, shape (C, k)
        First settled sample, or ``steps`` where not settled.
    cost : ndarray, shape (C, k)
    x_end : ndarray, shape (C, k, n)
    settled : ndarray of bool, shape (C, k)
    """
    n_c, n_k = K.shape[0], X0.shape[0]
    x = np.broadcast_to(X0, (n_c, n_k, X0.shape[1])).copy()
    target = level * np.linalg.norm(X0, axis=1)[None, :]
    cost = np.zeros((n_c, n_k))
    k_s = np.full((n_c, n_k), steps)
    settled = np.zeros((n_c, n_k), dtype=bool)
    with np.errstate(all="ignore"):
        for k in range(steps + 1):
            arrived = (np.linalg.norm(x, axis=2) <= target) & ~settled
            k_s = np.where(arrived, k, k_s)
            settled |= arrived
            live = ~settled
            if k == steps or not live.any():
                break
            u = -np.einsum("cij,ckj->cki", K, x)
            if u_max is not None:
                u = np.clip(u, -u_max, u_max)
            stage = np.einsum("cki,ij,ckj->ck", x, Wx, x) + np.einsum("cki,ij,ckj->ck", u,
                                                                        Wu, u)
            cost = cost + np.where(live, stage, 0.0)
            x = np.where(live[..., None], x @ A.T + u @ B.T, x)
    return k_s, cost, x, settled


def _integrated(problem: Any, K: np.ndarray, X0: np.ndarray, level: float, cap: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`free_time` of saturated or nonlinear continuous loops: the vectorized
    integrator with its settling event."""
    from penaltyrun.dynamics import linear_feedback as loop

    n_c, n_k = K.shape[0], X0.shape[0]
    starts = np.tile(X0, (n_c, 1))
    p = problem.params
    run = loop.simulate(problem.plant.f, np.repeat(K, n_k, axis=0), starts, problem.Wx,
                        problem.Wu, problem.u_max, cap, p.rtol, p.atol, p.max_steps,
                        problem._bound(X0), settle=level * np.linalg.norm(starts, axis=1))
    names = {loop.SETTLED: "converged", loop.HORIZON: "not_settled",
             loop.DIVERGED: "diverged", loop.STEP_FAILURE: "step_failure",
             loop.NONFINITE: "nonfinite"}
    status = np.asarray([names[int(c)] for c in run["status"]], dtype=object)
    t_end = run["t_end"].reshape(n_c, n_k)
    J = criteria.time_energy_cost(run["cost"].reshape(n_c, n_k), t_end, p.rho)
    return J, t_end, run["x_final"].reshape(n_c, n_k, -1), status.reshape(n_c, n_k)


def free_time(problem: Any, K: np.ndarray, X0: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``time_energy`` runs of gains K (C, m, n) from starts X0 (k, n).

    Returns
    -------
    J : ndarray, shape (C, k)
        Performance cost to settling (or to the cap) plus ρ times that time.
    t_end : ndarray, shape (C, k)
        Settling time, or the cap (time unit).
    x_end : ndarray, shape (C, k, n)
    status : ndarray of str, shape (C, k)
        ``converged`` (settled) or ``not_settled``.
    """
    p = problem.params
    level, cap = settle_level(p), float(p.free_time_cap)
    if problem.dt is None and not problem.closed_form:
        return _integrated(problem, K, X0, level, cap)
    if problem.dt is None:
        A_cl = problem.plant.A - problem.plant.B @ K
        W = problem.Wx + np.swapaxes(K, 1, 2) @ problem.Wu @ K
        t_end, J, x_end, settled = settle_continuous(A_cl, W, X0, level, cap)
    else:
        from penaltyrun.problems.lqr.discrete import n_steps

        k_s, J, x_end, settled = settle_sampled(
            problem.plant.A, problem.plant.B, K, X0, problem.Wx, problem.Wu, problem.u_max,
            level, n_steps(cap, problem.dt))
        t_end = k_s * float(problem.dt)
    status = np.where(settled, "converged", "not_settled").astype(object)
    return criteria.time_energy_cost(J, t_end, p.rho), t_end, x_end, status


__all__ = ["DEFAULT_RHO", "DEFAULT_SETTLE", "MAX_SEARCH", "MIN_STEP", "free_time",
           "settle_continuous", "settle_level", "settle_sampled", "terminal_weight"]
