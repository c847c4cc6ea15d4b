"""Problem 2b: minimum-energy attitude control with an LQR gain.

Linearization about q = (1, 0, 0, 0), ω = 0 with x = (q_v, ω): A = [[0, ½I₃], [0, 0]],
B = [[0], [I⁻¹]]. The tuned penalties Q (6×6) and R (3×3) give P from the continuous
algebraic Riccati equation AᵀP + PA − PBR⁻¹BᵀP + Q = 0 and the gain K = R⁻¹BᵀP, applied as
u = −K x to the NONLINEAR rigid body. The objective is the nonlinear closed-loop
J = ∫ ½ uᵀu dt (not the LQR quadratic cost); failures are penalized as described in
:mod:`penaltyrun.problems.attitude.common`. (αQ, αR) gives the same gain for every α > 0.

The gains come from the package's batched Riccati solver
(:func:`penaltyrun.dynamics.riccati.lqr_gains`: the stable invariant subspace of the
Hamiltonian matrix, re-solved by :func:`scipy.linalg.solve_continuous_are` where the residual
is not small) with this problem's absolute stability margin :data:`STABILITY_MARGIN`;
candidates without a stabilizing solution get status ``care_failure``.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

import numpy as np

from penaltyrun.dynamics import riccati
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
#: A solution counts as stabilizing when every closed-loop eigenvalue of A − BK has real part
#: below −STABILITY_MARGIN (1/s), an absolute margin: within eigenvalue bounds ≥ 1e-8 the
#: slowest true pole is ~6e-4 1/s; round-off leaves the open-loop poles (all at 0) within
#: ~1e-8 of 0.
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
    A, Bm = linear_model(inertia)
    # The numpy batch, not the compiled loop: the two agree to round-off, but a loop that
    # arrives at the edge of the horizon turns round-off in K into 1e-7 of cost, and the
    # committed attitude_lqr results were computed with the numpy batch.
    K, ok, _ = riccati.lqr_gains(A, Bm, np.asarray(Q, dtype=float), np.asarray(R, dtype=float),
                                 margin_abs=STABILITY_MARGIN, margin_rel=0.0, compiled=False)
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
