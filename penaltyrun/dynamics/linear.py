"""Exact quadratic cost of linear closed loops ẋ = A_cl x over a finite horizon.

For a closed loop ẋ = A_cl x from x0 and a weight W (symmetric), the cost over [0, T] is
the quadratic form

    ∫₀ᵀ x(t)ᵀ W x(t) dt = x0ᵀ M(T) x0,   M(T) = ∫₀ᵀ e^{A_clᵀ t} W e^{A_cl t} dt.

With a Hurwitz A_cl, M(T) = S − e^{A_clᵀ T} S e^{A_cl T} where S solves the Lyapunov
equation A_clᵀ S + S A_cl + W = 0. Two routes compute it:

* batched eigendecomposition (the fast path): with A_cl = V D V⁻¹ and G = Vᵀ W V,
  M(T) = V⁻ᵀ [G_ij (e^{(λ_i+λ_j)T} − 1) / (λ_i + λ_j)] V⁻¹ (``expm1`` keeps the small
  exponents exact), and x(T) = V e^{DT} V⁻¹ x0. Its round-off grows with the condition
  number of V, so candidates whose eigenvector matrix is worse conditioned than
  :data:`COND_MAX` take the second route;
* :func:`loop_solution`: S by Bartels–Stewart on a real Schur decomposition of A_cl, and
  ``scipy.linalg.expm`` (a loop that is not Hurwitz: the exponential of the lifted linear
  system of x xᵀ and J).

One Hurwitz loop alone (a gradient search asks for one candidate, then its gradient) takes
:func:`loop_solution` directly: the exact gradient's adjoint Lyapunov equations reuse its
Schur decomposition, S and e^{A_cl T} (:class:`LoopSolution`).

No time stepping: both routes are exact up to round-off (tests compare them with each other
and with ``solve_ivp``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from penaltyrun.dynamics.lyapunov import SchurLyapunov

#: Largest condition number of the eigenvector matrix accepted on the eigendecomposition path.
COND_MAX = 1e4
#: Loops of at most this many states take the eigendecomposition route in one compiled call
#: (:func:`penaltyrun.dynamics.small_linear.quadratic_eig`), larger ones in batched numpy
#: calls (:func:`_eig_batch`): for a few states the numpy calls cost more than their
#: arithmetic.
COMPILED_MAX_STATES = 8


def _eig_route(lam: np.ndarray, V: np.ndarray, W: np.ndarray, X0: np.ndarray, t_max: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """Eigen-route of :func:`quadratic_cost`; ``lam`` (B, n), ``V`` (B, n, n) of A_cl."""
    Y = np.linalg.solve(V, np.swapaxes(X0, 1, 2).astype(complex))  # (B, n, k) = V⁻¹ x0
    G = np.swapaxes(V, 1, 2) @ W @ V                  # Vᵀ W V
    s = lam[:, :, None] + lam[:, None, :]
    small = np.abs(s * t_max) < 1e-12
    safe = np.where(small, 1.0, s)
    factor = np.where(small, t_max, np.expm1(s * t_max) / safe)
    Mt = G * factor
    cost = np.einsum("bik,bij,bjk->bk", Y, Mt, Y).real
    xT = (V @ (np.exp(lam * t_max)[:, :, None] * Y)).real
    return cost, np.swapaxes(xT, 1, 2)


def _scipy_route(A_cl: np.ndarray, W: np.ndarray, X0: np.ndarray, t_max: float
                 ) -> tuple[np.ndarray, np.ndarray]:
    if np.max(np.linalg.eigvals(A_cl).real) < 0.0:
        return loop_solution(A_cl, W, t_max).cost(X0)
    # not Hurwitz: lift to X = x xᵀ, Ẋ = A X + X Aᵀ, J̇ = tr(W X) (linear, n² + 1)
    n = A_cl.shape[0]
    L = np.zeros((n * n + 1, n * n + 1))
    L[:-1, :-1] = np.kron(A_cl, np.eye(n)) + np.kron(np.eye(n), A_cl)
    L[-1, :-1] = W.reshape(-1)
    M = expm(L * t_max)[-1, :-1].reshape(n, n)
    M = 0.5 * (M + M.T)
    return np.einsum("ki,ij,kj->k", X0, M, X0), X0 @ expm(A_cl * t_max).T


def _eig_batch(A_cl: np.ndarray, W: np.ndarray, X0: np.ndarray, t_max: float,
               cost: np.ndarray, x_final: np.ndarray) -> np.ndarray:
    """The eigendecomposition route for the whole batch in numpy calls: fills ``cost`` and
    ``x_final`` of the loops it takes; returns which (the others take the second route)."""
    with np.errstate(all="ignore"):
        try:
            lam, V = np.linalg.eig(A_cl)
            cond = np.linalg.cond(V)
            good = np.isfinite(cond) & (cond < COND_MAX) & np.all(np.isfinite(lam), axis=1)
        except np.linalg.LinAlgError:
            good = np.zeros(A_cl.shape[0], dtype=bool)
    idx = np.flatnonzero(good)
    if idx.size:
        c, xf = _eig_route(lam[idx], V[idx], W[idx], X0[idx], t_max)
        cost[idx], x_final[idx] = c, xf
    return good


@dataclass(frozen=True)
class LoopSolution:
    """The cost matrices of one Hurwitz loop ẋ = A_cl x with weight W over [0, T].

    Attributes
    ----------
    lyapunov : SchurLyapunov
        Lyapunov solver of A_cl (its real Schur decomposition).
    S : ndarray, shape (n, n)
        Solution of A_clᵀ S + S A_cl + W = 0 (symmetrized).
    E : ndarray, shape (n, n)
        e^{A_cl T}.
    """

    lyapunov: SchurLyapunov
    S: np.ndarray
    E: np.ndarray

    def cost(self, X0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x0ᵀ (S − Eᵀ S E) x0 and x(T) = E x0 of the starts ``X0`` (k, n): shapes (k,),
        (k, n)."""
        X0 = np.asarray(X0, dtype=float)
        XT = X0 @ self.E.T
        return (np.einsum("ki,ij,kj->k", X0, self.S, X0)
                - np.einsum("ki,ij,kj->k", XT, self.S, XT)), XT


def loop_solution(A_cl: np.ndarray, W: np.ndarray, t_max: float) -> LoopSolution:
    """:class:`LoopSolution` of one Hurwitz loop.

    Parameters
    ----------
    A_cl : ndarray, shape (n, n)
        Hurwitz closed-loop matrix (1/time unit); the caller checks stability.
    W : ndarray, shape (n, n)
        Symmetric weight.
    t_max : float
        Horizon T (time unit of A_cl).

    Returns
    -------
    LoopSolution
    """
    A_cl = np.asarray(A_cl, dtype=float)
    lyapunov = SchurLyapunov(A_cl)
    S = lyapunov.solve(-np.asarray(W, dtype=float), transpose=True)
    return LoopSolution(lyapunov, 0.5 * (S + S.T), expm(A_cl * float(t_max)))


def quadratic_cost(A_cl: np.ndarray, W: np.ndarray, X0: np.ndarray, t_max: float
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Cost ∫₀ᵀ xᵀ W x dt and final state of ẋ = A_cl x for a batch of loops and starts.

    Parameters
    ----------
    A_cl : ndarray, shape (B, n, n)
        Closed-loop matrices (1/time unit).
    W : ndarray, shape (B, n, n)
        Symmetric weights of each loop (e.g. W_x + Kᵀ W_u K).
    X0 : ndarray, shape (B, k, n) or (k, n)
        Initial states (the same k starts for every loop when 2-D).
    t_max : float
        Horizon T (time unit of A_cl).

    Returns
    -------
    cost : ndarray, shape (B, k)
        x0ᵀ M(T) x0 (weight unit × state unit² × time unit).
    x_final : ndarray, shape (B, k, n)
        x(T) = e^{A_cl T} x0.
    """
    A_cl = np.asarray(A_cl, dtype=float)
    W = np.asarray(W, dtype=float)
    n_b = A_cl.shape[0]
    X0 = np.asarray(X0, dtype=float)
    if X0.ndim == 2:
        X0 = np.broadcast_to(X0, (n_b, *X0.shape))
    cost = np.empty(X0.shape[:2])
    x_final = np.empty(X0.shape)
    if n_b == 0:
        return cost, x_final
    if A_cl.shape[1] <= COMPILED_MAX_STATES:
        from penaltyrun.dynamics.small_linear import quadratic_eig

        try:
            cost, x_final, good = quadratic_eig(A_cl, np.ascontiguousarray(W),
                                                np.ascontiguousarray(X0), float(t_max),
                                                COND_MAX)
        except np.linalg.LinAlgError:  # an SVD or solve that failed: the numpy batch
            good = _eig_batch(A_cl, W, X0, float(t_max), cost, x_final)
    else:
        good = _eig_batch(A_cl, W, X0, float(t_max), cost, x_final)
    for b in np.flatnonzero(~good):
        cost[b], x_final[b] = _scipy_route(A_cl[b], W[b], X0[b], float(t_max))
    return cost, x_final


def sampled_loop(A_cl: np.ndarray, X0: np.ndarray, t: np.ndarray, W: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray | None]:
    """States of ẋ = A_cl x at uniform times ``t`` and, with ``W``, the running cost
    ∫₀ᵗ x(s)ᵀ W x(s) ds at each of them, exact up to round-off: x(t_{j+1}) = e^{A_cl h} x(t_j)
    and J(t_{j+1}) − J(t_j) = x(t_j)ᵀ G x(t_j) with G = ∫₀ʰ e^{A_clᵀs} W e^{A_cl s} ds from one
    exponential of Van Loan's block matrix [[−A_clᵀ, W], [0, A_cl]] h (G = F₂₂ᵀ F₁₂).

    Parameters
    ----------
    A_cl : ndarray, shape (C, n, n)
        Closed-loop matrices of C candidates.
    X0 : ndarray, shape (k, n)
        Start states.
    t : ndarray, shape (N,)
        Uniform times, t[0] = 0, N ≥ 2.
    W : ndarray, shape (C, n, n), optional
        Symmetric weights of the running cost.

    Returns
    -------
    x : ndarray, shape (C, k, N, n)
    J : ndarray, shape (C, k, N), or None without ``W``
    """
    h = float(t[1] - t[0])
    E = expm(A_cl * h)
    x = np.empty((A_cl.shape[0], X0.shape[0], t.shape[0], X0.shape[1]))
    X = np.broadcast_to(X0, (A_cl.shape[0],) + X0.shape).copy()
    for j in range(t.shape[0]):
        x[:, :, j] = X
        X = X @ np.swapaxes(E, 1, 2)
    if W is None:
        return x, None
    n = A_cl.shape[1]
    block = np.zeros((A_cl.shape[0], 2 * n, 2 * n))
    block[:, :n, :n] = -np.swapaxes(A_cl, 1, 2)
    block[:, :n, n:] = W
    block[:, n:, n:] = A_cl
    F = expm(block * h)
    G = np.swapaxes(F[:, n:, n:], 1, 2) @ F[:, :n, n:]
    G = 0.5 * (G + np.swapaxes(G, 1, 2))
    steps = np.einsum("ckji,cil,ckjl->ckj", x[:, :, :-1], G, x[:, :, :-1])
    J = np.concatenate([np.zeros(steps.shape[:2] + (1,)), np.cumsum(steps, axis=2)], axis=2)
    return x, J


__all__ = ["COMPILED_MAX_STATES", "COND_MAX", "LoopSolution", "loop_solution", "quadratic_cost",
           "sampled_loop"]
