"""Compiled candidate loops for small linear-quadratic batches (a few states).

For plants of a few states a batch of LQR candidates costs tens of microseconds of LAPACK
but several hundred of numpy calls on arrays of a few numbers, each paying Python's and
numpy's per-call cost. Each function here does the arithmetic of a batched numpy path
candidate by candidate in one compiled call, with the same LAPACK routines (``dgeev``
through :mod:`penaltyrun.dynamics.lapack`; LU and SVD through numba), so the results agree
with the numpy path to round-off (the tests compare them on random candidates):

* :func:`care_hamiltonian`: the Hamiltonian Riccati solve of
  :func:`penaltyrun.dynamics.riccati.hamiltonian_solutions`;
* :func:`quadratic_eig`: the eigendecomposition route of
  :func:`penaltyrun.dynamics.linear.quadratic_cost`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from penaltyrun.dynamics.lapack import geev, geev_workspace


@njit(cache=True)
def _frobenius(M):
    total = 0.0
    for i in range(M.shape[0]):
        for j in range(M.shape[1]):
            total += M[i, j] * M[i, j]
    return np.sqrt(total)


@njit(cache=True)
def care_hamiltonian(A, S, Q, cond_max, residual_tol, stability_margin):
    """Stabilizing solutions of AᵀP + PA − PSP + Q = 0 for a batch of (S, Q), from the
    stable invariant subspace [X1; X2] of H = [[A, −S], [−Q, −Aᵀ]]: P = X2 X1⁻¹.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        Plant matrix (1/time unit).
    S : ndarray, shape (C, n, n)
        B R⁻¹ Bᵀ of each candidate.
    Q : ndarray, shape (C, n, n)
        State penalties.
    cond_max : float
        Largest condition number of X1 accepted.
    residual_tol : float
        Relative residual below which a solution is accepted.
    stability_margin : float
        Closed-loop poles must have real part below −stability_margin (1/time unit; see
        :func:`penaltyrun.dynamics.riccati.margin`).

    Returns
    -------
    P : ndarray, shape (C, n, n)
        Symmetrized X2 X1⁻¹ (zero where no finite, well-conditioned solution was found).
    res : ndarray, shape (C,)
        Relative residual ‖AᵀP + PA − PSP + Q‖ / (‖Q‖ + ‖P‖(2‖A‖ + ‖S‖‖P‖)) (``inf``
        where none was found).
    ok : ndarray of bool, shape (C,)
        Residual below ``residual_tol`` and A − SP Hurwitz with the margin.
    """
    n_c = Q.shape[0]
    n = A.shape[0]
    P = np.zeros((n_c, n, n))
    ok = np.zeros(n_c, dtype=np.bool_)
    res = np.full(n_c, np.inf)
    norm_a = _frobenius(A)
    H = np.empty((2 * n, 2 * n))
    work_h = np.empty(geev_workspace(2 * n, True))
    work_a = np.empty(geev_workspace(n, False))
    X1 = np.empty((n, n), dtype=np.complex128)
    X2 = np.empty((n, n), dtype=np.complex128)
    for c in range(n_c):
        finite = True
        for i in range(n):
            for j in range(n):
                H[i, j] = A[i, j]
                H[i, n + j] = -S[c, i, j]
                H[n + i, j] = -Q[c, i, j]
                H[n + i, n + j] = -A[j, i]
                finite = finite and np.isfinite(S[c, i, j]) and np.isfinite(Q[c, i, j])
        if not finite:
            continue
        lam, V, info = geev(H, work_h, True)
        if info != 0:
            continue
        order = np.argsort(lam.real)[:n]
        stable = True
        for k in range(n):
            stable = stable and lam[order[k]].real < 0.0
            for i in range(n):
                X1[i, k] = V[i, order[k]]
                X2[i, k] = V[n + i, order[k]]
        if not stable:
            continue
        sv = np.linalg.svd(X1)[1]
        if not (sv[n - 1] > 0.0 and sv[0] / sv[n - 1] < cond_max):
            continue
        Pc = (X2 @ np.linalg.inv(X1)).real
        Pc = 0.5 * (Pc + Pc.T)
        if not np.all(np.isfinite(Pc)):
            continue
        P[c] = Pc
        Sc = np.ascontiguousarray(S[c])
        Qc = np.ascontiguousarray(Q[c])
        R = A.T @ Pc + Pc @ A - Pc @ Sc @ Pc + Qc
        norm_p = _frobenius(Pc)
        scale = _frobenius(Qc) + norm_p * (2.0 * norm_a + _frobenius(Sc) * norm_p)
        res[c] = _frobenius(R) / max(scale, 1e-300)
        if not res[c] < residual_tol:
            continue
        poles, _, info = geev(A - Sc @ Pc, work_a, False)
        ok[c] = info == 0 and np.max(poles.real) < -stability_margin
    return P, res, ok


@njit(cache=True)
def _expm1(z):
    """expm1 of a complex number, by numpy's formula (the same bits as ``numpy.expm1``)."""
    a = np.sin(z.imag / 2.0)
    return complex(np.expm1(z.real) * np.cos(z.imag) - 2.0 * a * a,
                   np.exp(z.real) * np.sin(z.imag))


@njit(cache=True)
def quadratic_eig(A_cl, W, X0, t_max, cond_max):
    """Cost ∫₀ᵀ xᵀ W x dt and x(T) of ẋ = A_cl x by the eigendecomposition A_cl = V D V⁻¹:
    x0ᵀ V⁻ᵀ [G_ij (e^{(λ_i+λ_j)T} − 1) / (λ_i + λ_j)] V⁻¹ x0 with G = Vᵀ W V.

    Parameters
    ----------
    A_cl : ndarray, shape (B, n, n)
        Closed-loop matrices (1/time unit).
    W : ndarray, shape (B, n, n)
        Symmetric weights.
    X0 : ndarray, shape (B, k, n)
        Initial states.
    t_max : float
        Horizon T (time unit of A_cl).
    cond_max : float
        Largest condition number of V accepted.

    Returns
    -------
    cost : ndarray, shape (B, k)
    x_final : ndarray, shape (B, k, n)
    good : ndarray of bool, shape (B,)
        The loops computed here (finite spectrum, V conditioned below ``cond_max``); the
        others are left to the Lyapunov / ``expm`` route.
    """
    n_b, n = A_cl.shape[0], A_cl.shape[1]
    n_k = X0.shape[1]
    cost = np.zeros((n_b, n_k))
    x_final = np.zeros((n_b, n_k, n))
    good = np.zeros(n_b, dtype=np.bool_)
    work = np.empty(geev_workspace(n, True))
    factor = np.empty((n, n), dtype=np.complex128)
    for b in range(n_b):
        if not np.all(np.isfinite(A_cl[b])):
            continue
        lam, V, info = geev(A_cl[b], work, True)
        if info != 0 or not np.all(np.isfinite(lam.real) & np.isfinite(lam.imag)):
            continue
        sv = np.linalg.svd(V)[1]
        if not (sv[n - 1] > 0.0 and sv[0] / sv[n - 1] < cond_max):
            continue
        good[b] = True
        Y = np.linalg.solve(V, np.ascontiguousarray(X0[b].T).astype(np.complex128))
        G = np.ascontiguousarray(V.T) @ W[b].astype(np.complex128) @ V
        for i in range(n):
            for j in range(n):
                st = (lam[i] + lam[j]) * t_max
                factor[i, j] = t_max if abs(st) < 1e-12 else _expm1(st) / (lam[i] + lam[j])
        Mt = G * factor
        decay = np.exp(lam * t_max)
        for q in range(n_k):
            total = 0.0 + 0.0j
            for i in range(n):
                for j in range(n):
                    total += Y[i, q] * Mt[i, j] * Y[j, q]
            cost[b, q] = total.real
            for i in range(n):
                x = 0.0 + 0.0j
                for j in range(n):
                    x += V[i, j] * (decay[j] * Y[j, q])
                x_final[b, q, i] = x.real
    return cost, x_final, good


__all__ = ["care_hamiltonian", "quadratic_eig"]
