"""Independent dense reference of the rendezvous MPC closed loop (tests and benchmark).

Shares no code with the production path: the discrete model is the closed-form
Clohessy–Wiltshire state-transition matrix and its integral (not a matrix exponential), the
terminal weight comes from :func:`scipy.linalg.solve_discrete_are` (not the doubling
algorithm), the condensed QP is assembled from block matrices (not batched sums), unscaled,
and each QP is solved by scipy's bounded-variable least squares (BVLS, Stark & Parker 1995,
an exact primal active-set method) on ½UᵀHU + fᵀU = ½‖LᵀU + L⁻¹f‖² + const with H = LLᵀ.
Slow and plain on purpose.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def cw_discrete_closed_form(n: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form zero-order-hold CW model (Clohessy & Wiltshire 1960).

    Parameters
    ----------
    n : float
        Mean motion (rad/s).
    dt : float
        Sample time (s).

    Returns
    -------
    Ad : ndarray, shape (6, 6)
        State-transition matrix Φ(dt).
    Bd : ndarray, shape (6, 3)
        ∫₀^dt Φ(τ) B dτ for a constant acceleration.
    """
    c, s, nt = math.cos(n * dt), math.sin(n * dt), n * dt
    Ad = np.array([
        [4 - 3 * c, 0, 0, s / n, 2 * (1 - c) / n, 0],
        [6 * (s - nt), 1, 0, -2 * (1 - c) / n, (4 * s - 3 * nt) / n, 0],
        [0, 0, c, 0, 0, s / n],
        [3 * n * s, 0, 0, c, 2 * s, 0],
        [-6 * n * (1 - c), 0, 0, -2 * s, 4 * c - 3, 0],
        [0, 0, -n * s, 0, 0, c],
    ])
    Bd = np.array([
        [(1 - c) / n ** 2, 2 * (nt - s) / n ** 2, 0],
        [-2 * (nt - s) / n ** 2, 4 * (1 - c) / n ** 2 - 1.5 * dt ** 2, 0],
        [0, 0, (1 - c) / n ** 2],
        [s / n, 2 * (1 - c) / n, 0],
        [-2 * (1 - c) / n, 4 * s / n - 3 * dt, 0],
        [0, 0, s / n],
    ])
    return Ad, Bd


def dense_qp(Ad: np.ndarray, Bd: np.ndarray, Q: np.ndarray, R: np.ndarray, P: np.ndarray,
             horizon: int) -> tuple[np.ndarray, np.ndarray]:
    """Unscaled condensed QP: cost UᵀHU + 2 sᵀFᵀU, from block matrices.

    Returns
    -------
    H : ndarray, shape (3N, 3N)
    F : ndarray, shape (3N, 6)
    """
    from scipy.linalg import block_diag

    nx, nu = Bd.shape
    Sx = np.vstack([np.linalg.matrix_power(Ad, i) for i in range(1, horizon + 1)])
    Su = np.zeros((nx * horizon, nu * horizon))
    for i in range(horizon):
        for j in range(i + 1):
            Su[nx * i:nx * (i + 1), nu * j:nu * (j + 1)] = \
                np.linalg.matrix_power(Ad, i - j) @ Bd
    Qbar = block_diag(*([Q] * (horizon - 1) + [P]))
    Rbar = block_diag(*([R] * horizon))
    H = Su.T @ Qbar @ Su + Rbar
    return 0.5 * (H + H.T), Su.T @ Qbar @ Sx


def solve_box_qp(H: np.ndarray, f: np.ndarray, bound: np.ndarray) -> np.ndarray:
    """argmin ½UᵀHU + fᵀU subject to |U| ≤ bound, by BVLS (see the module docstring)."""
    from scipy.linalg import cholesky, solve_triangular
    from scipy.optimize import lsq_linear

    L = cholesky(H, lower=True)
    d = -solve_triangular(L, f, lower=True)
    res = lsq_linear(L.T, d, bounds=(-bound, bound), method="bvls", tol=1e-14,
                     max_iter=100 * H.shape[0])
    if res.status <= 0:
        raise RuntimeError(f"BVLS did not converge: {res.message}")
    return np.clip(res.x, -bound, bound)


def reference_run(Q: Any, R: Any, n: float, dt: float, horizon: int, u_max: float,
                  s0: Any, n_steps: int, pos_tol: float, vel_tol: float,
                  thrust_scale: float = 1.0) -> dict[str, Any]:
    """Reference closed loop on the CW plant (weights in SI units).

    Returns
    -------
    dict
        ``delta_v`` (m/s), ``converged``, ``t_final`` (s), ``steps``, ``states``
        (steps + 1, 6), ``inputs`` (steps, 3), ``P`` (6, 6).
    """
    from scipy.linalg import solve_discrete_are

    Q = np.asarray(Q, dtype=float)
    R = np.asarray(R, dtype=float)
    Ad, Bd = cw_discrete_closed_form(n, dt)
    P = solve_discrete_are(Ad, Bd, Q, R)
    H, F = dense_qp(Ad, Bd, Q, R, P, horizon)
    bound = np.full(H.shape[0], float(u_max))
    s = np.asarray(s0, dtype=float).copy()
    states, inputs, dv, converged, k = [s.copy()], [], 0.0, False, 0
    for k in range(n_steps + 1):
        if np.linalg.norm(s[:3]) <= pos_tol and np.linalg.norm(s[3:]) <= vel_tol:
            converged = True
            break
        if k == n_steps:
            break
        u = solve_box_qp(H, F @ s, bound)[:3]
        dv += dt * float(np.linalg.norm(u))
        s = Ad @ s + Bd @ (thrust_scale * u)
        states.append(s.copy())
        inputs.append(u)
    return {"delta_v": dv, "converged": converged, "t_final": k * dt, "steps": k,
            "states": np.asarray(states), "inputs": np.asarray(inputs).reshape(-1, 3), "P": P}


__all__ = ["cw_discrete_closed_form", "dense_qp", "reference_run", "solve_box_qp"]
