"""Clohessy–Wiltshire model of the rendezvous MPC and its discrete Riccati equation.

State s = (x, y, z, ẋ, ẏ, ż) in the target's LVLH frame (m, m/s; x radial outward, y
along-track, z orbit normal), input u = commanded acceleration (m/s²) per axis:
ẍ = 3n²x + 2nẏ + u_x, ÿ = −2nẋ + u_y, z̈ = −n²z + u_z, with the mean motion n = √(μ/a³)
of the target's circular orbit. The discrete model s_{k+1} = A_d s_k + B_d u_k is the exact
zero-order hold (matrix exponential of the augmented matrix [[A, B], [0, 0]]).

The terminal weight P solves the discrete algebraic Riccati equation (DARE)
P = AᵀPA − AᵀPB (R + BᵀPB)⁻¹ BᵀPA + Q for a batch of (Q, R) at once, by the structured
doubling algorithm (SDA; Chu, Fan, Lin & Wang 2004), which converges quadratically for a
stabilizable (A, B) and PD Q (:func:`penaltyrun.dynamics.riccati.doubling_solutions`, the
iteration the discrete plants of ``problem=lqr`` use too); candidates whose relative
residual is not small are re-solved with :func:`scipy.linalg.solve_discrete_are`, and those
still without a stabilizing solution are reported as failed.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from penaltyrun.dynamics.riccati import doubling_solutions

logger = logging.getLogger(__name__)

#: Relative DARE residual below which a solution is accepted.
DARE_RESIDUAL_TOL = 1e-9
#: Doubling steps at most (each squares the closed-loop contraction).
SDA_MAX_STEPS = 80
#: The doubling stops once no candidate's solution moves by more than this, relative.
SDA_STEP_RTOL = 1e-15
#: A solution counts as stabilizing when the closed-loop spectral radius is below this.
STABLE_RADIUS = 1.0 - 1e-12


def mean_motion(orbit_radius_m: float, mu_m3_s2: float) -> float:
    """Mean motion n = √(μ / a³) (rad/s) of a circular orbit of radius ``orbit_radius_m``."""
    return float(np.sqrt(mu_m3_s2 / orbit_radius_m ** 3))


def cw_continuous(n: float) -> tuple[np.ndarray, np.ndarray]:
    """Continuous Clohessy–Wiltshire matrices.

    Parameters
    ----------
    n : float
        Mean motion (rad/s).

    Returns
    -------
    A : ndarray, shape (6, 6)
    B : ndarray, shape (6, 3)
    """
    A = np.zeros((6, 6))
    A[:3, 3:] = np.eye(3)
    A[3, 0] = 3.0 * n * n
    A[3, 4] = 2.0 * n
    A[4, 3] = -2.0 * n
    A[5, 2] = -n * n
    B = np.zeros((6, 3))
    B[3:, :] = np.eye(3)
    return A, B


def zoh(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretization (expm of [[A, B], [0, 0]]·dt).

    Returns
    -------
    Ad : ndarray, shape (n, n)
    Bd : ndarray, shape (n, m)
    """
    from scipy.linalg import expm

    nx, nu = B.shape
    M = np.zeros((nx + nu, nx + nu))
    M[:nx, :nx] = A
    M[:nx, nx:] = B
    E = expm(M * dt)
    return E[:nx, :nx].copy(), E[:nx, nx:].copy()


def dare_residual(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray,
                  P: np.ndarray) -> np.ndarray:
    """Relative DARE residual ‖AᵀPA − P − AᵀPB(R + BᵀPB)⁻¹BᵀPA + Q‖ / (‖Q‖ + ‖P‖), (batch,).

    Parameters
    ----------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, m)
    Q : ndarray, shape (batch, n, n)
    R : ndarray, shape (batch, m, m)
    P : ndarray, shape (batch, n, n)
    """
    PB = P @ B
    S = R + B.T @ PB
    AtPB = A.T @ PB
    with np.errstate(all="ignore"):
        res = A.T @ P @ A - P - AtPB @ np.linalg.solve(S, np.swapaxes(AtPB, 1, 2)) + Q
        scale = np.linalg.norm(Q, axis=(1, 2)) + np.linalg.norm(P, axis=(1, 2))
        return np.linalg.norm(res, axis=(1, 2)) / np.maximum(scale, 1e-300)


def _stabilizing(A: np.ndarray, B: np.ndarray, R: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Whether A − B K with K = (R + BᵀPB)⁻¹BᵀPA is Schur stable, per batch entry."""
    with np.errstate(all="ignore"):
        K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
        rho = np.max(np.abs(np.linalg.eigvals(A - B @ K)), axis=-1)
    return rho < STABLE_RADIUS


def solve_dare_batch(A: np.ndarray, B: np.ndarray, Q: Any, R: Any
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Stabilizing DARE solutions for a batch of weights.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        Discrete state matrix.
    B : ndarray, shape (n, m)
        Discrete input matrix.
    Q : array_like, shape (batch, n, n)
        State weights (symmetric PD).
    R : array_like, shape (batch, m, m)
        Input weights (symmetric PD).

    Returns
    -------
    P : ndarray, shape (batch, n, n)
        Solutions (zero where ``ok`` is False).
    ok : ndarray of bool, shape (batch,)
        Whether a stabilizing solution with a small residual was found.
    """
    from scipy.linalg import solve_discrete_are

    Q = np.asarray(Q, dtype=float)
    R = np.asarray(R, dtype=float)
    P, ok = doubling_solutions(A, B, Q, R, SDA_MAX_STEPS, SDA_STEP_RTOL)
    try:
        ok &= dare_residual(A, B, Q, R, P) < DARE_RESIDUAL_TOL
    except np.linalg.LinAlgError:
        P, ok = np.zeros_like(P), np.zeros_like(ok)
    for b in np.flatnonzero(~ok):
        try:
            P[b] = solve_discrete_are(A, B, Q[b], R[b])
            ok[b] = bool(np.all(np.isfinite(P[b]))
                         and dare_residual(A, B, Q[b:b + 1], R[b:b + 1], P[b:b + 1])[0]
                         < DARE_RESIDUAL_TOL)
        except (np.linalg.LinAlgError, ValueError):
            logger.debug("no DARE solution for candidate %d", b)
            ok[b] = False
    ok &= _stabilizing(A, B, R, P)
    P[~ok] = 0.0
    return P, ok


__all__ = ["DARE_RESIDUAL_TOL", "cw_continuous", "dare_residual", "mean_motion",
           "solve_dare_batch", "zoh"]
