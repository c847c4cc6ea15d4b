"""Closed loops of discrete-time plants x[k+1] = A x[k] + B u[k], u[k] = sat(−K x[k]).

The cost of one start is the sum over the N = ceil(T / dt) steps k = 0 … N−1 of
x[k]ᵀ W_x x[k] + u[k]ᵀ W_u u[k], the cost whose infinite-horizon minimum over gains is
x0ᵀ P x0 with P from the discrete Riccati equation of (A, B, W_x, W_u) (python-control's
``dlqr`` cost; it is not multiplied by dt). Every trajectory is stepped exactly (no
integration error), all candidates and starts in one batch (:func:`simulate`); a linear loop
without input limits sums in closed form by doubling (:func:`linear_sum`).
"""

from __future__ import annotations

import math

import numpy as np

#: Status codes of :func:`simulate`.
HORIZON, DIVERGED, NONFINITE = 0, 1, 2


def n_steps(t_max: float, dt: float) -> int:
    """Steps N = ceil(T / dt) (at least 1; T a whole number of steps up to 1e-9)."""
    return max(1, math.ceil(t_max / dt - 1e-9))


def linear_sum(A_cl: np.ndarray, W: np.ndarray, X0: np.ndarray, steps: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """Cost and final state of unsaturated linear loops, x0ᵀ (Σ_{k<N} (A_clᵀ)^k W A_cl^k) x0
    and A_cl^N x0, by doubling (O(log N) batched products instead of N steps).

    Parameters
    ----------
    A_cl : ndarray, shape (C, n, n)
    W : ndarray, shape (C, n, n)
        Stage weight W_x + Kᵀ W_u K.
    X0 : ndarray, shape (k, n)
    steps : int

    Returns
    -------
    cost : ndarray, shape (C, k)
    x_final : ndarray, shape (C, k, n)
    """
    n_c, n = A_cl.shape[0], A_cl.shape[1]
    S_block, A_block = W.copy(), A_cl.copy()          # 2^j terms, A_cl^(2^j)
    S = np.zeros((n_c, n, n))
    P = np.broadcast_to(np.eye(n), (n_c, n, n)).copy()  # A_cl^(terms so far)
    remaining = steps
    with np.errstate(all="ignore"):
        while remaining:
            if remaining & 1:
                S = S + np.swapaxes(P, 1, 2) @ S_block @ P
                P = P @ A_block
            remaining >>= 1
            if remaining:
                S_block = S_block + np.swapaxes(A_block, 1, 2) @ S_block @ A_block
                A_block = A_block @ A_block
    cost = np.einsum("ki,cij,kj->ck", X0, S, X0)
    return cost, np.einsum("cij,kj->cki", P, X0)


def simulate(A: np.ndarray, B: np.ndarray, K: np.ndarray, X0: np.ndarray, Wx: np.ndarray,
             Wu: np.ndarray, u_max: np.ndarray | None, steps: int, bound: float,
             history: bool = False) -> dict[str, np.ndarray]:
    """Step M closed loops.

    Parameters
    ----------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, m)
    K : ndarray, shape (M, m, n)
        One gain per trajectory.
    X0 : ndarray, shape (M, n)
        Initial states.
    Wx, Wu : ndarray
        Stage weights (n × n, m × m).
    u_max : ndarray, shape (m,), or None
        Input limits |u_i| ≤ u_max_i.
    steps : int
        Number of steps N.
    bound : float
        ‖x‖ above which a trajectory has diverged (it stops there).
    history : bool
        Also return the states and inputs of every step.

    Returns
    -------
    dict
        ``cost`` (M,) the sum of the stage costs up to the end, ``status`` (M,) codes,
        ``k_end`` (M,) steps taken (N unless stopped), ``x_final`` (M, n); with
        ``history``: ``x`` (N+1, M, n) and ``u`` (N, M, m), NaN after a stop.
    """
    M, n = X0.shape
    X = np.array(X0, dtype=float)
    cost = np.zeros(M)
    status = np.full(M, HORIZON)
    k_end = np.full(M, steps)
    alive = np.ones(M, dtype=bool)
    xs = np.full((steps + 1, M, n), np.nan) if history else None
    us = np.full((steps, M, B.shape[1]), np.nan) if history else None
    if xs is not None:
        xs[0] = X
    with np.errstate(all="ignore"):
        for k in range(steps):
            U = -np.einsum("kmn,kn->km", K, X)
            if u_max is not None:
                U = np.clip(U, -u_max, u_max)
            stage = np.einsum("ki,ij,kj->k", X, Wx, X) + np.einsum("ki,ij,kj->k", U, Wu, U)
            cost = np.where(alive, cost + stage, cost)
            X_next = X @ A.T + U @ B.T
            if us is not None:
                us[k, alive] = U[alive]
            bad = alive & ~np.all(np.isfinite(X_next), axis=1)
            big = alive & ~bad & (np.linalg.norm(X_next, axis=1) > bound)
            status[bad], status[big] = NONFINITE, DIVERGED
            k_end[bad | big] = k + 1
            X = np.where(alive[:, None], X_next, X)
            alive &= ~(bad | big)
            if xs is not None:
                xs[k + 1, alive | big] = X[alive | big]
            if not alive.any():
                break
    out = {"cost": cost, "status": status, "k_end": k_end, "x_final": X}
    if history:
        out.update(x=xs, u=us)
    return out


def histories(A: np.ndarray, B: np.ndarray, K: np.ndarray, X0: np.ndarray, Wx: np.ndarray,
              Wu: np.ndarray, u_max: np.ndarray | None, t_max: float, dt: float,
              bound: float) -> dict[str, np.ndarray]:
    """Every step of one gain K (m × n) from every start X0 (k × n), for plots: ``t``
    (N+1,) = k dt, ``x`` (k, N+1, n), ``u`` (k, N+1, m) (the input held over its step, its
    last value repeated at T) and the running cost ``J`` (k, N+1)."""
    steps = n_steps(t_max, dt)
    run = simulate(A, B, np.repeat(K[None], len(X0), 0), X0, Wx, Wu, u_max, steps, bound,
                   history=True)
    x = np.swapaxes(run["x"], 0, 1)
    u = np.swapaxes(run["u"], 0, 1)
    u = np.concatenate([u, u[:, -1:]], axis=1)
    stage = (np.einsum("kti,ij,ktj->kt", x[:, :-1], Wx, x[:, :-1])
             + np.einsum("kti,ij,ktj->kt", u[:, :-1], Wu, u[:, :-1]))
    J = np.concatenate([np.zeros((len(X0), 1)), np.cumsum(stage, axis=1)], axis=1)
    return {"t": np.arange(steps + 1) * dt, "x": x, "u": u, "J": J}


__all__ = ["DIVERGED", "HORIZON", "NONFINITE", "histories", "linear_sum", "n_steps",
           "simulate"]
