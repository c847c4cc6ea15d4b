"""Batched LQR gains: continuous time K = R⁻¹ Bᵀ P, P from the algebraic Riccati equation
AᵀP + PA − P B R⁻¹ Bᵀ P + Q = 0 (:func:`lqr_gains`), and discrete time
K = (R + BᵀPB)⁻¹ BᵀPA, P from AᵀPA − P − AᵀPB (R + BᵀPB)⁻¹ BᵀPA + Q = 0
(:func:`dlqr_gains`).

Q may be positive semi-definite: the stabilizing solution exists when (A, B) is
stabilizable and (A, Q^½) detectable, which the problem checks once for the structure of Q.

The batch path takes the stable invariant subspace of the Hamiltonian matrix
H = [[A, −S], [−Q, −Aᵀ]] (S = B R⁻¹ Bᵀ) by one batched eigendecomposition: with the n
stable eigenvectors stacked as [X1; X2], P = X2 X1⁻¹ (Laub 1979). Candidates whose relative
residual exceeds :data:`RESIDUAL_TOL`, or whose loop A − SP is not Hurwitz, are solved again
with :func:`scipy.linalg.solve_continuous_are` (ordered QZ on the extended pencil). A
candidate that still fails gets ``ok = False`` and a failure size (its relative residual,
``inf`` when no finite solution exists), which the problem turns into a graded penalty.
"""

from __future__ import annotations

import logging

import numpy as np

logger = logging.getLogger(__name__)

#: Relative Riccati residual above which a batched solution is re-solved by scipy.
RESIDUAL_TOL = 1e-10
#: Closed-loop poles must have real part below −STABILITY_MARGIN·max(1, ‖A‖) (1/time unit).
STABILITY_MARGIN = 1e-9
#: Largest condition number of the stable eigenvector block X1 of the Hamiltonian accepted.
COND_MAX = 1e12
#: Plants of at most this many states (integrators included) take the compiled candidate
#: loop (:func:`hamiltonian_compiled`), larger ones the batched numpy path
#: (:func:`hamiltonian_solutions`).
COMPILED_MAX_STATES = 8


def residual(A: np.ndarray, S: np.ndarray, Q: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Relative residual ‖AᵀP + PA − PSP + Q‖ / (‖Q‖ + ‖P‖(2‖A‖ + ‖S‖‖P‖)), shape (B,)."""
    res = np.swapaxes(A, -1, -2) @ P + P @ A - P @ S @ P + Q
    nP = np.linalg.norm(P, axis=(-2, -1))
    scale = (np.linalg.norm(Q, axis=(-2, -1))
             + nP * (2.0 * np.linalg.norm(A) + np.linalg.norm(S, axis=(-2, -1)) * nP))
    return np.linalg.norm(res, axis=(-2, -1)) / np.maximum(scale, 1e-300)


def _stabilizing(A: np.ndarray, S: np.ndarray, P: np.ndarray) -> np.ndarray:
    margin = STABILITY_MARGIN * max(1.0, float(np.linalg.norm(A)))
    return np.max(np.linalg.eigvals(A - S @ P).real, axis=-1) < -margin


def hamiltonian_solutions(A: np.ndarray, S: np.ndarray, Q: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Riccati solutions of a batch from the stable invariant subspace of the Hamiltonian,
    by one batched eigendecomposition (see the module docstring).

    Parameters
    ----------
    A : ndarray, shape (n, n)
    S : ndarray, shape (C, n, n)
        B R⁻¹ Bᵀ of each candidate.
    Q : ndarray, shape (C, n, n)

    Returns
    -------
    P : ndarray, shape (C, n, n)
        Symmetrized X2 X1⁻¹ (zero where no finite, well-conditioned solution was found).
    res : ndarray, shape (C,)
        Relative residual (``inf`` where none was found).
    ok : ndarray of bool, shape (C,)
        Residual below :data:`RESIDUAL_TOL` and A − SP Hurwitz.
    """
    n_c, n = Q.shape[0], A.shape[0]
    H = np.zeros((n_c, 2 * n, 2 * n))
    H[:, :n, :n] = A
    H[:, :n, n:] = -S
    H[:, n:, :n] = -Q
    H[:, n:, n:] = -A.T
    P = np.zeros((n_c, n, n))
    ok = np.zeros(n_c, dtype=bool)
    res = np.full(n_c, np.inf)
    with np.errstate(all="ignore"):
        try:
            lam, V = np.linalg.eig(H)
            order = np.argsort(lam.real, axis=1)[:, :n]
            stable = np.take_along_axis(lam.real, order, axis=1) < 0.0
            X = np.take_along_axis(V, order[:, None, :], axis=2)
            X1, X2 = X[:, :n, :], X[:, n:, :]
            cond = np.linalg.cond(X1)
            good = stable.all(axis=1) & np.isfinite(cond) & (cond < COND_MAX)
            X1[~good] = np.eye(n)
            P = np.real(X2 @ np.linalg.inv(X1))
            P = 0.5 * (P + np.swapaxes(P, 1, 2))
            good &= np.all(np.isfinite(P), axis=(1, 2))
            P = np.where(good[:, None, None], P, 0.0)
            res = np.where(good, residual(A, S, Q, P), np.inf)
            ok = good & (res < RESIDUAL_TOL) & _stabilizing(A, S, P)
        except np.linalg.LinAlgError:
            ok[:] = False
    return P, res, ok


def hamiltonian_compiled(A: np.ndarray, S: np.ndarray, Q: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`hamiltonian_solutions` in one compiled call, candidate by candidate, with the
    same LAPACK routines (:func:`penaltyrun.dynamics.small_linear.care_hamiltonian`): for
    small plants, whose numpy batch costs more in per-call overhead than in arithmetic.
    A candidate with non-finite entries fails alone here (numpy's batch sends them all to
    the fallback)."""
    from penaltyrun.dynamics.small_linear import care_hamiltonian

    try:
        return care_hamiltonian(np.ascontiguousarray(A, dtype=float),
                                np.ascontiguousarray(S, dtype=float),
                                np.ascontiguousarray(Q, dtype=float), COND_MAX, RESIDUAL_TOL,
                                STABILITY_MARGIN)
    except np.linalg.LinAlgError:  # an SVD or LU that did not converge: the numpy batch
        return hamiltonian_solutions(A, S, Q)


def lqr_gains(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """LQR gains of one plant for a batch of penalties.

    Parameters
    ----------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, m)
    Q : ndarray, shape (C, n, n)
        State penalties (symmetric positive definite).
    R : ndarray, shape (C, m, m)
        Input penalties (symmetric positive definite).

    Returns
    -------
    K : ndarray, shape (C, m, n)
        Gains u = −K x (zero where ``ok`` is False).
    ok : ndarray of bool, shape (C,)
        A stabilizing solution was found.
    failure : ndarray, shape (C,)
        0 where ``ok``; else the relative residual of the best solution found (``inf``
        when none is finite).
    """
    from scipy.linalg import solve_continuous_are

    Q = np.asarray(Q, dtype=float)
    R = np.asarray(R, dtype=float)
    R_inv = np.linalg.inv(R)
    S = B @ R_inv @ B.T
    solve = hamiltonian_compiled if A.shape[0] <= COMPILED_MAX_STATES else \
        hamiltonian_solutions
    with np.errstate(all="ignore"):
        P, res, ok = solve(A, S, Q)
        for c in np.flatnonzero(~ok):
            try:
                Pc = solve_continuous_are(A, B, Q[c], R[c])
            except (np.linalg.LinAlgError, ValueError):
                logger.debug("no Riccati solution for candidate %d", c)
                continue
            if not np.all(np.isfinite(Pc)):
                continue
            rc = float(residual(A, S[c], Q[c], Pc))
            res[c] = min(res[c], rc)
            if _stabilizing(A, S[c], Pc) and rc < 1e3 * RESIDUAL_TOL:
                P[c], ok[c], res[c] = Pc, True, rc
    K = R_inv @ B.T @ P
    K[~ok] = 0.0
    return K, ok, np.where(ok, 0.0, res)


def discrete_residual(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray,
                      P: np.ndarray) -> np.ndarray:
    """Relative residual of the discrete Riccati equation, shape (C,):
    ‖AᵀPA − P − AᵀPB (R + BᵀPB)⁻¹ BᵀPA + Q‖ / (‖Q‖ + ‖P‖ (1 + ‖A‖²))."""
    At = A.T
    PB = P @ B
    M = R + B.T @ PB
    res = At @ P @ A - P - At @ PB @ np.linalg.solve(M, np.swapaxes(PB, -1, -2) @ A) + Q
    nP = np.linalg.norm(P, axis=(-2, -1))
    scale = np.linalg.norm(Q, axis=(-2, -1)) + nP * (1.0 + np.linalg.norm(A) ** 2)
    return np.linalg.norm(res, axis=(-2, -1)) / np.maximum(scale, 1e-300)


def _discrete_gain(A: np.ndarray, B: np.ndarray, R: np.ndarray, P: np.ndarray) -> np.ndarray:
    PB = P @ B
    return np.linalg.solve(R + B.T @ PB, np.swapaxes(PB, -1, -2) @ A)


def _schur_stable(A: np.ndarray, B: np.ndarray, K: np.ndarray) -> np.ndarray:
    margin = STABILITY_MARGIN * max(1.0, float(np.linalg.norm(A)))
    return np.max(np.abs(np.linalg.eigvals(A - B @ K)), axis=-1) < 1.0 - margin


def dlqr_gains(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray,
               max_iter: int = 80) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Discrete-time LQR gains of one plant for a batch of penalties.

    The batch runs the structure-preserving doubling algorithm (Chu, Fan, Lin & Wang 2004;
    no inverse of A needed): A₀ = A, G₀ = B R⁻¹ Bᵀ, H₀ = Q and
    W = I + G H, A ← A W⁻¹ A, G ← G + A W⁻¹ G Aᵀ, H ← H + Aᵀ H W⁻¹ A, with H → P
    quadratically. Candidates whose relative residual exceeds :data:`RESIDUAL_TOL` or
    whose loop A − BK is not Schur (spectral radius ≥ 1) are solved again with
    :func:`scipy.linalg.solve_discrete_are`.

    Parameters and returns as :func:`lqr_gains` (u[k] = −K x[k]).
    """
    from scipy.linalg import solve_discrete_are

    Q = np.asarray(Q, dtype=float)
    R = np.asarray(R, dtype=float)
    n_c, n = Q.shape[0], A.shape[0]
    eye = np.eye(n)
    Ak = np.broadcast_to(A, (n_c, n, n)).copy()
    G = B @ np.linalg.inv(R) @ B.T
    H = Q.copy()
    with np.errstate(all="ignore"):
        try:
            for _ in range(max_iter):
                W = eye + G @ H
                WA = np.linalg.solve(W, Ak)
                WG = np.linalg.solve(W, G)
                H_new = H + np.swapaxes(Ak, 1, 2) @ H @ WA
                G = G + Ak @ WG @ np.swapaxes(Ak, 1, 2)
                Ak = Ak @ WA
                step = np.linalg.norm(H_new - H, axis=(1, 2))
                H = H_new
                if np.all(~np.isfinite(step) | (step <= 1e-14 * np.linalg.norm(H, axis=(1, 2)))):
                    break
            P = 0.5 * (H + np.swapaxes(H, 1, 2))
            good = np.all(np.isfinite(P), axis=(1, 2))
            P = np.where(good[:, None, None], P, 0.0)
            K = _discrete_gain(A, B, R, P)
            res = discrete_residual(A, B, Q, R, P)
            res = np.where(good & np.isfinite(res), res, np.inf)
            ok = good & (res < RESIDUAL_TOL) & _schur_stable(A, B, K)
        except np.linalg.LinAlgError:
            P = np.zeros((n_c, n, n))
            res = np.full(n_c, np.inf)
            ok = np.zeros(n_c, dtype=bool)
        for c in np.flatnonzero(~ok):
            try:
                Pc = solve_discrete_are(A, B, Q[c], R[c])
            except (np.linalg.LinAlgError, ValueError):
                logger.debug("no discrete Riccati solution for candidate %d", c)
                continue
            if not np.all(np.isfinite(Pc)):
                continue
            rc = float(discrete_residual(A, B, Q[c], R[c], Pc))
            res[c] = min(res[c], rc)
            if rc < 1e3 * RESIDUAL_TOL and _schur_stable(A, B, _discrete_gain(A, B, R[c], Pc)):
                P[c], ok[c], res[c] = Pc, True, rc
        K = _discrete_gain(A, B, R, P)
    K[~ok] = 0.0
    return K, ok, np.where(ok, 0.0, res)


__all__ = ["COMPILED_MAX_STATES", "COND_MAX", "RESIDUAL_TOL", "STABILITY_MARGIN",
           "discrete_residual", "dlqr_gains", "hamiltonian_compiled", "hamiltonian_solutions",
           "lqr_gains", "residual"]
