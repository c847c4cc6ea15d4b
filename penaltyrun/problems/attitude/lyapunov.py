"""Problem 2a: minimum-energy attitude control with the Lyapunov PD law.

u = −K_p q_v − K_d ω with K_p, K_d 3×3 symmetric positive definite (no gyroscopic term),
applied to the nonlinear rigid body (quaternion kinematics, Euler's equation). Cost
J = ∫ ½ uᵀu dt to the first time ‖(q0 − 1, q_v, ω)‖ ≤ tol; failures are penalized as
described in :mod:`penaltyrun.problems.attitude.common`.
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

NAME = "attitude_lyapunov"


def pd_gains(mats: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Gains G = [K_p, K_d] of a batch.

    Parameters
    ----------
    mats : mapping
        ``"Kp"`` and ``"Kd"``, each of shape (B, 3, 3) (N·m and N·m·s).

    Returns
    -------
    G : ndarray, shape (B, 3, 6)
    ok : ndarray of bool, shape (B,)
        All True (a PD gain always exists).
    """
    Kp = np.asarray(mats["Kp"], dtype=float)
    Kd = np.asarray(mats["Kd"], dtype=float)
    G = np.concatenate([Kp, Kd], axis=-1)
    return G, np.ones(G.shape[0], dtype=bool)


def make_problem(case: str, overrides: Mapping[str, Any]) -> AttitudeProblem:
    """Build the PD-law problem: defaults → case entry → ``overrides``.

    Raises
    ------
    ConfigError
        Unknown case or parameter, or an invalid value.
    """
    params = build_params(Params, case, overrides)
    logger.debug("%s case %s: %s", NAME, case, params)
    eb = tuple(float(b) for b in params.eig_bounds)
    return AttitudeProblem(NAME, case, params, (MatrixSpec("Kp", 3, eb), MatrixSpec("Kd", 3, eb)),
                           pd_gains)


def reference_cost(mats: Mapping[str, Any], params: Params | None = None) -> dict[str, Any]:
    """Independent scipy ``solve_ivp`` evaluation of one (K_p, K_d); see
    :func:`penaltyrun.problems.attitude.common.reference_run` for the returned keys."""
    G, _ = pd_gains({k: np.asarray(mats[k], dtype=float)[None] for k in ("Kp", "Kd")})
    return reference_run(G[0], params or Params())


__all__ = [
    "CASES",
    "CASE_PARAMS",
    "DEFAULT_CASE",
    "VARIANT_IGNORE",
    "NAME",
    "Params",
    "evaluate_grid",
    "make_problem",
    "pd_gains",
    "plot_histories",
    "plot_quaternions",
    "plot_rates",
    "plot_torques",
    "reference_cost",
    "robustness_grid",
]

#: Report hooks (:mod:`penaltyrun.problems.report_hooks`).
report_info, report_plots, report_sections = attitude_report.hooks(NAME)
