"""Batched LQR gains, the one Riccati solver of the package: continuous time
K = R⁻¹ Bᵀ P, P from the algebraic Riccati equation AᵀP + PA − P B R⁻¹ Bᵀ P + Q = 0
(:func:`lqr_gains`), and discrete time K = (R + BᵀPB)⁻¹ BᵀPA, P from
AᵀPA − P − AᵀPB (R + BᵀPB)⁻¹ BᵀPA + Q = 0 (:func:`dlqr_gains`). ``problem=lqr`` and
``problem=attitude_lqr`` both solve here.

Q may be positive semi-definite: the stabilizing solution exists when (A, B) is
stabilizable and (A, Q^½) detectable.

The batch path takes the stable invariant subspace of the Hamiltonian matrix
H = [[A, −S], [−Q, −Aᵀ]] (S = B R⁻¹ Bᵀ) by one batched eigendecomposition: with the n
stable eigenvectors stacked as [X1; X2], P = X2 X1⁻¹ (Laub 1979). Candidates whose relative
residual exceeds :data:`RESIDUAL_TOL`, or whose loop A − SP is not Hurwitz with the
stability margin, are solved again with :func:`scipy.linalg.solve_continuous_are` (ordered
QZ on the extended pencil). A candidate that still fails gets ``ok = False`` and a failure
size (its relative residual, ``inf`` when no finite solution exists), which the caller turns
into a graded penalty or a status.

The stability margin is the caller's: a solution counts as stabilizing when every
closed-loop pole has real part below −μ (continuous time) or modulus below 1 − μ (discrete
time), with μ = max(``margin_abs``, ``margin_rel``·max(1, ‖A‖_F)) (:func:`margin`). The
default is relative, :data:`STABILITY_MARGIN` times the plant's scale; a problem whose
plant has poles at 0 by construction and a known slowest true pole may give an absolute
one instead.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

import numpy as np

logger = logging.getLogger(__name__)

#: Relative Riccati residual above which a batched solution is re-solved by scipy.
RESIDUAL_TOL = 1e-10
#: Default relative stability margin: closed-loop poles must have real part below
#: −STABILITY_MARGIN·max(1, ‖A‖_F) (1/time unit).
STABILITY_MARGIN = 1e-9
#: Largest condition number of the stable eigenvector block X1 of the Hamiltonian accepted.
COND_MAX = 1e12
#: Plants of at most this many states (integrators included) take the compiled candidate
#: loop (:func:`hamiltonian_compiled`), larger ones the batched numpy path
#: (:func:`hamiltonian_solutions`).
COMPILED_MAX_STATES = 8


def margin(A: np.ndarray, margin_abs: float = 0.0, margin_rel: float = STABILITY_MARGIN
           ) -> float:
    """The stability margin μ = max(``margin_abs``, ``margin_rel``·max(1, ‖A‖_F)).

    Parameters
    ----------
    A : ndarray, shape (n, n)
        Plant matrix (1/time unit in continuous time).
    margin_abs : float
        Absolute margin (1/time unit; in discrete time, of the spectral radius).
    margin_rel : float
        Margin relative to the plant's scale max(1, ‖A‖_F).

    Returns
    -------
    float
        μ. Continuous time: poles must have real part below −μ; discrete time: modulus
        below 1 − μ.
    """
    return max(float(margin_abs), float(margin_rel) * max(1.0, float(np.linalg.norm(A))))


def residual(A: np.ndarray, S: np.ndarray, Q: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Relative residual ‖AᵀP + PA − PSP + Q‖ / (‖Q‖ + ‖P‖(2‖A‖ + ‖S‖‖P‖)), shape (B,)."""
    res = np.swapaxes(A, -1, -2) @ P + P @ A - P @ S @ P + Q
    nP = np.linalg.norm(P, axis=(-2, -1))
    scale = (np.linalg.norm(Q, axis=(-2, -1))
             + nP * (2.0 * np.linalg.norm(A) + np.linalg.norm(S, axis=(-2, -1)) * nP))
    return np.linalg.norm(res, axis=(-2, -1)) / np.maximum(scale, 1e-300)


def _stabilizing(A: np.ndarray, S: np.ndarray, P: np.ndarray, mu: float) -> np.ndarray:
    """Whether A − SP is Hurwitz with margin ``mu`` (1/time unit), per candidate."""
    return np.max(np.linalg.eigvals(A - S @ P).real, axis=-1) < -mu


def hamiltonian_solutions(A: np.ndarray, S: np.ndarray, Q: np.ndarray, mu: float | None = None
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Riccati solutions of a batch from the stable invariant subspace of the Hamiltonian,
    by one batched eigendecomposition (see the module docstring).

    Parameters
    ----------
    A : ndarray, shape (n, n)
    S : ndarray, shape (C, n, n)
        B R⁻¹ Bᵀ of each candidate.
    Q : ndarray, shape (C, n, n)
    mu : float, optional
        Stability margin (1/time unit, :func:`margin`); default the relative
        :data:`STABILITY_MARGIN`.

    Returns
    -------
    P : ndarray, shape (C, n, n)
        Symmetrized X2 X1⁻¹ (zero where no finite, well-conditioned solution was found).
    res : ndarray, shape (C,)
        Relative residual (``inf`` where none was found).
    ok : ndarray of bool, shape (C,)
        Residual below :data:`RESIDUAL_TOL` and every pole of A − SP below −mu.
    """
    mu = margin(A) if mu is None else mu
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
            ok = good & (res < RESIDUAL_TOL) & _stabilizing(A, S, P, mu)
        except np.linalg.LinAlgError:
            ok[:] = False
    return P, res, ok


def hamiltonian_compiled(A: np.ndarray, S: np.ndarray, Q: np.ndarray, mu: float | None = None
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`hamiltonian_solutions` in one compiled call, candidate by candidate, with the
    same LAPACK routines (:func:`penaltyrun.dynamics.small_linear.care_hamiltonian`): for
    small plants, whose numpy batch costs more in per-call overhead than in arithmetic.
    A candidate with non-finite entries fails alone here (numpy's batch sends them all to
    the fallback)."""
    from penaltyrun.dynamics.small_linear import care_hamiltonian

    mu = margin(A) if mu is None else mu
    try:
        return care_hamiltonian(np.ascontiguousarray(A, dtype=float),
                                np.ascontiguousarray(S, dtype=float),
                                np.ascontiguousarray(Q, dtype=float), COND_MAX, RESIDUAL_TOL,
                                mu)
    except np.linalg.LinAlgError:  # an SVD or LU that did not converge: the numpy batch
        return hamiltonian_solutions(A, S, Q, mu)


def _rescue(P: np.ndarray, ok: np.ndarray, res: np.ndarray, kind: str, *,
            solve: Callable[[int], np.ndarray],
            residual_of: Callable[[int, np.ndarray], Any],
            stabilizing: Callable[[int, np.ndarray], Any]) -> None:
    """Solve the candidates the batch could not (``~ok``) one at a time with scipy's
    Schur-method solver ``solve(c)``, in place.

    A finite solution whose relative residual is below 1e3 · :data:`RESIDUAL_TOL` and that
    is stabilizing with the margin replaces the batch's (``ok[c]`` set); otherwise ``res[c]``
    keeps the lower of the two residuals. ``kind`` (continuous, discrete) names the
    equation in the debug log of a candidate scipy cannot solve either.
    """
    for c in np.flatnonzero(~ok):
        try:
            Pc = solve(c)
        except (np.linalg.LinAlgError, ValueError):
            logger.debug("no %s Riccati solution for candidate %d", kind, c)
            continue
        if not np.all(np.isfinite(Pc)):
            continue
        rc = float(residual_of(c, Pc))
        res[c] = min(res[c], rc)
        if rc < 1e3 * RESIDUAL_TOL and bool(stabilizing(c, Pc)):
            P[c], ok[c], res[c] = Pc, True, rc


def lqr_gains(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, *,
              margin_abs: float = 0.0, margin_rel: float = STABILITY_MARGIN,
              compiled: bool | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """LQR gains of one plant for a batch of penalties.

    Parameters
    ----------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, m)
    Q : ndarray, shape (C, n, n)
        State penalties (symmetric positive definite).
    R : ndarray, shape (C, m, m)
        Input penalties (symmetric positive definite).
    margin_abs, margin_rel : float
        Stability margin, absolute (1/time unit) and relative to max(1, ‖A‖_F): the
        closed-loop poles must have real part below −max of the two (:func:`margin`).
    compiled : bool, optional
        Take the compiled candidate loop (:func:`hamiltonian_compiled`) or the numpy batch
        (:func:`hamiltonian_solutions`); default by size (:data:`COMPILED_MAX_STATES`). The
        two agree to round-off, not bit for bit.

    Returns
    -------
    K : ndarray, shape (C, m, n)
        Gains u = −K x (zero where ``ok`` is False).
    ok : ndarray of bool, shape (C,)
        A stabilizing solution (with the margin) was found.
    failure : ndarray, shape (C,)
        0 where ``ok``; else the relative residual of the best solution found (``inf``
        when none is finite).
    """
    from scipy.linalg import solve_continuous_are

    Q = np.asarray(Q, dtype=float)
    R = np.asarray(R, dtype=float)
    R_inv = np.linalg.inv(R)
    S = B @ R_inv @ B.T
    mu = margin(A, margin_abs, margin_rel)
    if compiled is None:
        compiled = A.shape[0] <= COMPILED_MAX_STATES
    solve = hamiltonian_compiled if compiled else hamiltonian_solutions
    with np.errstate(all="ignore"):
        P, res, ok = solve(A, S, Q, mu)
        _rescue(P, ok, res, "continuous",
                solve=lambda c: solve_continuous_are(A, B, Q[c], R[c]),
                residual_of=lambda c, Pc: residual(A, S[c], Q[c], Pc),
                stabilizing=lambda c, Pc: _stabilizing(A, S[c], Pc, mu))
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


def _schur_stable(A: np.ndarray, B: np.ndarray, K: np.ndarray, mu: float) -> np.ndarray:
    """Whether A − BK has spectral radius below 1 − ``mu``, per candidate."""
    return np.max(np.abs(np.linalg.eigvals(A - B @ K)), axis=-1) < 1.0 - mu


def doubling_solutions(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray,
                       max_iter: int = 80, step_rtol: float = 1e-14
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Discrete Riccati solutions of one plant for a batch of weights by the structure-
    preserving doubling algorithm (Chu, Fan, Lin & Wang 2004; no inverse of A needed).

    A₀ = A, G₀ = B R⁻¹ Bᵀ, H₀ = Q and W = I + G H, A ← A W⁻¹ A, G ← G + A W⁻¹ G Aᵀ,
    H ← H + Aᵀ H W⁻¹ A, with H → P quadratically for a stabilizable (A, B) and a
    detectable (A, Q^½). The caller checks the residual and the stability of the loop.

    Parameters
    ----------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, m)
    Q : ndarray, shape (C, n, n)
        State weights (symmetric PSD).
    R : ndarray, shape (C, m, m)
        Input weights (symmetric PD).
    max_iter : int
        Most doubling steps.
    step_rtol : float
        The iteration stops once every candidate's step ‖H_new − H‖ is at most
        ``step_rtol``·‖H‖ (or not finite).

    Returns
    -------
    P : ndarray, shape (C, n, n)
        Symmetrized solutions, zero where ``finite`` is False.
    finite : ndarray of bool, shape (C,)
        Whether the iteration ended on a finite matrix (False for the whole batch when a
        linear solve failed).
    """
    n_c, n = Q.shape[0], A.shape[0]
    eye = np.eye(n)
    with np.errstate(all="ignore"):
        try:
            Ak = np.broadcast_to(A, (n_c, n, n)).copy()
            G = B @ np.linalg.solve(R, np.broadcast_to(B.T, (n_c,) + B.T.shape))
            H = Q.copy()
            for _ in range(max_iter):
                W = eye + G @ H
                WA = np.linalg.solve(W, Ak)                      # (I + G H)⁻¹ A
                WG = np.linalg.solve(W, G)                       # (I + G H)⁻¹ G
                At = np.swapaxes(Ak, 1, 2)
                H_new = H + At @ H @ WA
                G = G + Ak @ WG @ At
                Ak = Ak @ WA
                step = np.linalg.norm(H_new - H, axis=(1, 2))
                H = H_new
                if np.all(~np.isfinite(step)
                          | (step <= step_rtol * np.linalg.norm(H, axis=(1, 2)))):
                    break
            P = 0.5 * (H + np.swapaxes(H, 1, 2))
            finite = np.all(np.isfinite(P), axis=(1, 2))
            P[~finite] = 0.0
        except np.linalg.LinAlgError:
            P = np.zeros((n_c, n, n))
            finite = np.zeros(n_c, dtype=bool)
    return P, finite


def dlqr_gains(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray,
               max_iter: int = 80, *, margin_abs: float = 0.0,
               margin_rel: float = STABILITY_MARGIN
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Discrete-time LQR gains of one plant for a batch of penalties.

    The batch runs :func:`doubling_solutions`; candidates whose relative residual exceeds
    :data:`RESIDUAL_TOL` or whose loop A − BK is not Schur (spectral radius ≥ 1 − μ, μ from
    :func:`margin`) are solved again with :func:`scipy.linalg.solve_discrete_are`.

    Parameters and returns as :func:`lqr_gains` (u[k] = −K x[k]); ``max_iter``: most
    doubling steps.
    """
    from scipy.linalg import solve_discrete_are

    Q = np.asarray(Q, dtype=float)
    R = np.asarray(R, dtype=float)
    mu = margin(A, margin_abs, margin_rel)
    P, good = doubling_solutions(A, B, Q, R, max_iter)
    with np.errstate(all="ignore"):
        try:
            K = _discrete_gain(A, B, R, P)
            res = discrete_residual(A, B, Q, R, P)
            res = np.where(good & np.isfinite(res), res, np.inf)
            ok = good & (res < RESIDUAL_TOL) & _schur_stable(A, B, K, mu)
        except np.linalg.LinAlgError:
            res = np.full(Q.shape[0], np.inf)
            ok = np.zeros(Q.shape[0], dtype=bool)
        _rescue(P, ok, res, "discrete",
                solve=lambda c: solve_discrete_are(A, B, Q[c], R[c]),
                residual_of=lambda c, Pc: discrete_residual(A, B, Q[c], R[c], Pc),
                stabilizing=lambda c, Pc: _schur_stable(A, B, _discrete_gain(A, B, R[c], Pc),
                                                        mu))
        K = _discrete_gain(A, B, R, P)
    K[~ok] = 0.0
    return K, ok, np.where(ok, 0.0, res)


__all__ = ["COMPILED_MAX_STATES", "COND_MAX", "RESIDUAL_TOL", "STABILITY_MARGIN",
           "discrete_residual", "dlqr_gains", "doubling_solutions", "hamiltonian_compiled",
           "hamiltonian_solutions", "lqr_gains", "margin", "residual"]
