"""Independent scipy references for ``problem=lqr`` (tests and ``bench/bench_lqr.py``).

Neither shares code with the production path: the gain comes from
:func:`scipy.linalg.solve_continuous_are`, the linear cost from the Lyapunov equation
(:func:`scipy.linalg.solve_continuous_lyapunov`) and :func:`scipy.linalg.expm` as
x0ᵀ (S − e^{A_clᵀT} S e^{A_cl T}) x0, and integrated loops from ``solve_ivp`` (DOP853).
Discrete time: :func:`scipy.linalg.solve_discrete_are` and the discrete Lyapunov equation
(:func:`scipy.linalg.solve_discrete_lyapunov`) with x0ᵀ (S − (A_clᵀ)^N S A_cl^N) x0.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def gain(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray) -> np.ndarray:
    """LQR gain K = R⁻¹BᵀP (m × n) by scipy's Riccati solver."""
    from scipy.linalg import solve_continuous_are

    P = solve_continuous_are(A, B, Q, R)
    return np.linalg.solve(R, B.T @ P)


def linear_cost(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray,
                Wx: np.ndarray, Wu: np.ndarray, X0: np.ndarray, t_max: float) -> np.ndarray:
    """Per-start cost of the unsaturated linear loop, closed form, shape (k,)."""
    from scipy.linalg import expm, solve_continuous_lyapunov

    K = gain(A, B, Q, R)
    A_cl = A - B @ K
    S = solve_continuous_lyapunov(A_cl.T, -(Wx + K.T @ Wu @ K))
    E = expm(A_cl * t_max)
    M = S - E.T @ S @ E
    return np.einsum("ki,ij,kj->k", X0, M, X0)


def integrated_cost(f: Callable[[np.ndarray, np.ndarray], np.ndarray], K: np.ndarray,
                    x0: np.ndarray, Wx: np.ndarray, Wu: np.ndarray, u_max: np.ndarray | None,
                    t_max: float, rtol: float = 1e-12, atol: float = 1e-14
                    ) -> tuple[float, np.ndarray]:
    """J and x(T) of one start of u = sat(−K x) on f by ``solve_ivp`` (DOP853).

    ``f`` is the vectorized plant (called with one row); returns (J, x(T)).
    """
    from scipy.integrate import solve_ivp

    n = x0.shape[0]

    def rhs(_t: float, y: np.ndarray) -> np.ndarray:
        x = y[:n]
        u = -K @ x
        if u_max is not None:
            u = np.minimum(np.maximum(u, -u_max), u_max)
        dx = np.asarray(f(x[None], u[None]), dtype=float)[0]
        return np.append(dx, x @ Wx @ x + u @ Wu @ u)

    sol = solve_ivp(rhs, (0.0, t_max), np.append(x0, 0.0), method="DOP853", rtol=rtol,
                    atol=atol)
    return float(sol.y[n, -1]), sol.y[:n, -1]


def discrete_gain(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Discrete LQR gain K = (R + BᵀPB)⁻¹BᵀPA by scipy's discrete Riccati solver."""
    from scipy.linalg import solve_discrete_are

    P = solve_discrete_are(A, B, Q, R)
    return np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)


def discrete_linear_cost(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray,
                         Wx: np.ndarray, Wu: np.ndarray, X0: np.ndarray, steps: int
                         ) -> np.ndarray:
    """Per-start sum over k < N of the stage cost of the unsaturated discrete loop, closed
    form, shape (k,)."""
    from scipy.linalg import solve_discrete_lyapunov

    K = discrete_gain(A, B, Q, R)
    A_cl = A - B @ K
    S = solve_discrete_lyapunov(A_cl.T, Wx + K.T @ Wu @ K)
    E = np.linalg.matrix_power(A_cl, steps)
    return np.einsum("ki,ij,kj->k", X0, S - E.T @ S @ E, X0)


__all__ = ["discrete_gain", "discrete_linear_cost", "gain", "integrated_cost", "linear_cost"]
