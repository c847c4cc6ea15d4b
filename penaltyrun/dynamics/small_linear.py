"""Compiled candidate loops for small linear-quadratic batches (a few states).

For plants of a few states a batch of LQR candidates costs tens of microseconds of LAPACK
but several hundred of numpy calls on arrays of a few numbers, each paying Python's and
numpy's per-call cost. :func:`care_hamiltonian` does the arithmetic of the batched
Hamiltonian Riccati solve of :func:`penaltyrun.problems.lqr.riccati.hamiltonian_solutions`
candidate by candidate in one compiled call, with the same LAPACK routines (``dgeev`` through
:mod:`penaltyrun.dynamics.lapack`; LU inverse and SVD through numba), so the results agree
with the numpy path to round-off (the tests compare them on random candidates).
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
        Closed-loop poles must have real part below −margin·max(1, ‖A‖_F).

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
    margin = stability_margin * max(1.0, norm_a)
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
        ok[c] = info == 0 and np.max(poles.real) < -margin
    return P, res, ok


__all__ = ["care_hamiltonian"]
