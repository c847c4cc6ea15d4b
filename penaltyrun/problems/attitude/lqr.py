"""Problem 2b: minimum-energy attitude control with an LQR gain.

Linearization about q = (1, 0, 0, 0), ω = 0 with x = (q_v, ω): A = [[0, ½I₃], [0, 0]],
B = [[0], [I⁻¹]]. The tuned penalties Q (6×6) and R (3×3) give P from the continuous
algebraic Riccati equation AᵀP + PA − PBR⁻¹BᵀP + Q = 0 and the gain K = R⁻¹BᵀP, applied as
u = −K x to the NONLINEAR rigid body. The objective is the nonlinear closed-loop
J = ∫ ½ uᵀu dt (not the LQR quadratic cost); failures are penalized as described in
:mod:`penaltyrun.problems.attitude.common`. (αQ, αR) gives the same gain for every α > 0.

The batch path solves the Riccati equations exactly by the stable invariant subspace of the
Hamiltonian matrix (batched eigen-decomposition; the closed-loop poles are the selected
eigenvalues, so no second eigen-decomposition is needed); candidates whose residual is not
small are re-solved with :func:`scipy.linalg.solve_continuous_are`, and those without a
stabilizing solution get status ``care_failure``.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

import numpy as np

from penaltyrun.problems.attitude import report as attitude_report
from penaltyrun.problems.attitude.common import (
    CASE_PARAMS,
    CASES,
    DEFAULT_CASE,
    VARIANT_IGNORE,
    AttitudeProblem,
    Params,
    build_params,
    evaluate_grid,
    plot_histories,
    plot_quaternions,
    plot_rates,
    plot_torques,
    reference_run,
    robustness_grid,
)
from penaltyrun.problems.base import MatrixSpec

logger = logging.getLogger(__name__)

NAME = "attitude_lqr"
#: Relative Riccati residual above which the batched solution is re-solved by scipy.
RESIDUAL_TOL = 1e-9
#: A solution counts as stabilizing when every closed-loop eigenvalue of A − BK has real part
#: below −STABILITY_MARGIN (1/s). Within eigenvalue bounds ≥ 1e-8 the slowest true pole is
#: ~6e-4 1/s; round-off leaves the open-loop poles (all at 0) within ~1e-8 of 0.
STABILITY_MARGIN = 1e-7


def linear_model(inertia: Any) -> tuple[np.ndarray, np.ndarray]:
    """Linearized attitude model about the target.

    Parameters
    ----------
    inertia : array_like, shape (3, 3)
        Inertia (kg·m²).

    Returns
    -------
    A : ndarray, shape (6, 6)
    B : ndarray, shape (6, 3)
    """
    A = np.zeros((6, 6))
    A[:3, 3:] = 0.5 * np.eye(3)
    B = np.zeros((6, 3))
    B[3:, :] = np.linalg.inv(np.asarray(inertia, dtype=float))
    return A, B


def _residual(A: np.ndarray, S: np.ndarray, Q: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Relative Riccati residual ‖AᵀP + PA − PSP + Q‖ / (‖Q‖ + ‖P‖·(‖A‖ + ‖S‖‖P‖)), (B,)."""
    At = np.swapaxes(A, -1, -2)
    res = At @ P + P @ A - P @ S @ P + Q
    nA = np.linalg.norm(A)
    scale = (np.linalg.norm(Q, axis=(-2, -1))
             + np.linalg.norm(P, axis=(-2, -1)) * (nA + np.linalg.norm(S, axis=(-2, -1))
                                                   * np.linalg.norm(P, axis=(-2, -1))))
    return np.linalg.norm(res, axis=(-2, -1)) / np.maximum(scale, 1e-300)


def _stabilizing(A: np.ndarray, S: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Whether A − SP is Hurwitz with margin :data:`STABILITY_MARGIN`, per batch entry (B,)."""
    lam = np.linalg.eigvals(A - S @ P)
    return np.max(lam.real, axis=-1) < -STABILITY_MARGIN


def lqr_gains(Q: Any, R: Any, inertia: Any) -> tuple[np.ndarray, np.ndarray]:
    """LQR gains K = R⁻¹BᵀP for a batch of penalties.

    Parameters
    ----------
    Q : array_like, shape (B, 6, 6)
        State penalties (symmetric PD).
    R : array_like, shape (B, 3, 3)
        Control penalties (symmetric PD).
    inertia : array_like, shape (3, 3)
        Inertia (kg·m²).

    Returns
    -------
    K : ndarray, shape (B, 3, 6)
        Gains (zero where ``ok`` is False).
    ok : ndarray of bool, shape (B,)
        Whether a stabilizing solution was found (A − BK Hurwitz, see
        :data:`STABILITY_MARGIN`).
    """
    from scipy.linalg import solve_continuous_are

    Q = np.asarray(Q, dtype=float)
    R = np.asarray(R, dtype=float)
    n_b = Q.shape[0]
    A, Bm = linear_model(inertia)
    R_inv = np.linalg.inv(R)
    S = Bm @ R_inv @ Bm.T
    H = np.zeros((n_b, 12, 12))
    H[:, :6, :6] = A
    H[:, :6, 6:] = -S
    H[:, 6:, :6] = -Q
    H[:, 6:, 6:] = -A.T
    P = np.zeros((n_b, 6, 6))
    ok = np.zeros(n_b, dtype=bool)
    with np.errstate(all="ignore"):
        try:
            lam, V = np.linalg.eig(H)
            order = np.argsort(lam.real, axis=1)[:, :6]
            lam_cl = np.take_along_axis(lam.real, order, axis=1)
            X = np.take_along_axis(V, order[:, None, :], axis=2)
            X1, X2 = X[:, :6, :], X[:, 6:, :]
            good = lam_cl.max(axis=1) < -STABILITY_MARGIN
            X1[~good] = np.eye(6)
            try:
                X1_inv = np.linalg.inv(X1)
            except np.linalg.LinAlgError:  # an exactly singular X1: guard each entry
                cond = np.linalg.cond(X1)
                good &= np.isfinite(cond) & (cond < 1e12)
                X1[~good] = np.eye(6)
                X1_inv = np.linalg.inv(X1)
            P = np.real(X2 @ X1_inv)
            P = 0.5 * (P + np.swapaxes(P, 1, 2))
            ok = good & np.all(np.isfinite(P), axis=(1, 2))
            P = np.where(ok[:, None, None], P, 0.0)
            # A − SP has the selected stable eigenvalues of H (the invariant subspace), so a
            # small residual makes P the stabilizing solution with margin STABILITY_MARGIN;
            # an ill-conditioned X1 shows up as a large residual and goes to scipy below.
            ok &= _residual(A, S, Q, P) < RESIDUAL_TOL
        except np.linalg.LinAlgError:
            ok[:] = False
    for b in np.flatnonzero(~ok):
        try:
            P[b] = solve_continuous_are(A, Bm, Q[b], R[b])
            ok[b] = bool(np.all(np.isfinite(P[b])) and _stabilizing(A, S[b], P[b]))
        except (np.linalg.LinAlgError, ValueError):
            logger.debug("no stabilizing Riccati solution for candidate %d", b)
            ok[b] = False
    K = R_inv @ Bm.T @ P
    K[~ok] = 0.0
    return K, ok


def closed_form_gain(inertia_diag: Any, Qq: Any, Qw: Any, r: Any) -> tuple[np.ndarray, np.ndarray]:
    """Decoupled LQR gains for diagonal I, Q = diag(Qq, Qω), R = diag(r).

    Kq_i = √(Qq_i / r_i), Kω_i = √(Qω_i / r_i + I_i·Kq_i).

    Returns
    -------
    Kq, Kw : ndarray, shape (3,)
    """
    Iv, Qq, Qw, r = (np.asarray(v, dtype=float) for v in (inertia_diag, Qq, Qw, r))
    Kq = np.sqrt(Qq / r)
    return Kq, np.sqrt(Qw / r + Iv * Kq)


def make_problem(case: str, overrides: Mapping[str, Any]) -> AttitudeProblem:
    """Build the LQR-law problem: defaults → case entry → ``overrides``.

    Raises
    ------
    ConfigError
        Unknown case or parameter, or an invalid value.
    """
    params = build_params(Params, case, overrides)
    logger.debug("%s case %s: %s", NAME, case, params)
    eb = tuple(float(b) for b in params.eig_bounds)
    inertia = params.inertia_matrix()

    def gains(mats: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        return lqr_gains(mats["Q"], mats["R"], inertia)

    return AttitudeProblem(NAME, case, params, (MatrixSpec("Q", 6, eb), MatrixSpec("R", 3, eb)),
                           gains)


def reference_cost(mats: Mapping[str, Any], params: Params | None = None) -> dict[str, Any]:
    """Independent scipy evaluation of one (Q, R): gain by
    :func:`scipy.linalg.solve_continuous_are`, closed loop by ``solve_ivp``; keys as in
    :func:`penaltyrun.problems.attitude.common.reference_run` plus ``gain`` (3, 6)."""
    from scipy.linalg import solve_continuous_are

    p = params or Params()
    A, Bm = linear_model(p.inertia_matrix())
    Q = np.asarray(mats["Q"], dtype=float)
    R = np.asarray(mats["R"], dtype=float)
    P = solve_continuous_are(A, Bm, Q, R)
    K = np.linalg.solve(R, Bm.T @ P)
    out = reference_run(K, p)
    out["gain"] = K
    return out


__all__ = [
    "CASES",
    "CASE_PARAMS",
    "DEFAULT_CASE",
    "VARIANT_IGNORE",
    "NAME",
    "RESIDUAL_TOL",
    "STABILITY_MARGIN",
    "Params",
    "closed_form_gain",
    "evaluate_grid",
    "linear_model",
    "lqr_gains",
    "make_problem",
    "plot_histories",
    "plot_quaternions",
    "plot_rates",
    "plot_torques",
    "reference_cost",
    "robustness_grid",
]

#: Report hooks (:mod:`penaltyrun.problems.report_hooks`).
report_info, report_plots, report_sections = attitude_report.hooks(NAME)
