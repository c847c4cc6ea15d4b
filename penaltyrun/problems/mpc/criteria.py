"""The well-posed criteria of the rendezvous MPC (see :mod:`penaltyrun.problems.criteria`).

Discrete-time analogues, sums over the applied samples k (each of length Tₛ) with the
control energy E = Σ_k ½ ‖u_k‖² Tₛ (m²/s³; u in m/s²):

``time_energy``
    J = Σ_{k < k_f} (½ ‖u_k‖² + ρ) Tₛ = E + ρ t_f, t_f = k_f Tₛ the first sample where
    ‖r‖ ≤ ``pos_tol_m`` and ‖v‖ ≤ ``vel_tol_m_s`` (the problem's own convergence test),
    searched up to ``free_time_cap`` (whole samples; default 12 000 s). ρ (``rho``) in
    m²/s⁴; the default 1e-5 puts the optimum near 2 000–2 500 s for the default start
    (measured energies fall about as c / t_f³ with c ≈ 1.2e8 m²·s, so t_f* ≈ (3c/ρ)^¼).
    A run not converged by the cap costs J + failure_penalty · (1 + e(s_T) / e(s_0)).
``terminal``
    J = E + s_Nᵀ S s_N, N = t_max / Tₛ samples, the convergence test switched off (every
    run lasts t_max). S (``terminal_weight``, 6 × 6 on (x, y, z, ẋ, ẏ, ż) in m and m/s)
    is in m²/s³ per m² and per (m/s)²; the default
    S = 0.01 · diag(I₃ / pos_tol_m², I₃ / vel_tol_m_s²) makes a state on the tolerance
    boundary cost 0.01 m²/s³, the order of the controllers' energies.

Under both, the exact cutoff is not used (it bounds Δv, not J), and the recorded cost is
J (not Δv; ``delta_v`` stays in the detailed results).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from penaltyrun.problems import criteria

#: Default ρ of ``time_energy`` (m²/s⁴).
DEFAULT_RHO = 1e-5
#: Cost (m²/s³) of a final state on the tolerance boundary under the default S.
TERMINAL_SCALE = 0.01
#: Cost unit of the well-posed criteria.
COST_UNIT = "m²/s³"


def terminal_weight(params: Any) -> np.ndarray:
    """S (6 × 6) of ``terminal``: ``terminal_weight`` or the default (module docstring)."""
    if params.terminal_weight is not None:
        return criteria.terminal_matrix(params.terminal_weight, 6,
                                        "problem.params.terminal_weight")
    return TERMINAL_SCALE * np.diag([params.pos_tol_m ** -2] * 3
                                    + [params.vel_tol_m_s ** -2] * 3)


def run_steps(params: Any) -> int:
    """Samples a run may last: ``free_time_cap`` (whole samples, at least one) for
    ``time_energy``, else t_max / Tₛ."""
    if params.criterion == criteria.TIME_ENERGY:
        return max(1, math.floor(params.free_time_cap / params.sample_time_s + 1e-9))
    return params.n_steps


def run_horizon(params: Any) -> float:
    """:func:`run_steps` in seconds."""
    return run_steps(params) * float(params.sample_time_s)


def position_tolerance(params: Any) -> float:
    """Convergence radius passed to the loop: −1 (never met) under ``terminal``."""
    return -1.0 if params.criterion == criteria.TERMINAL else float(params.pos_tol_m)


def report_info(case: str, params: Mapping[str, Any]) -> Any:
    """Report hook (:mod:`penaltyrun.problems.report_hooks`): Δv (m/s) under ``deadline``,
    the criterion's J (m²/s³) otherwise."""
    from penaltyrun.problems.base import ReportInfo
    from penaltyrun.problems.mpc.params import build_params

    p = build_params(case, params)
    if p.criterion == criteria.DEADLINE:
        return ReportInfo(cost_name="Δv = Σ Tₛ‖u_k‖₂", cost_unit="m/s")
    return ReportInfo(cost_name=criteria.report_name(p, "", "Σ_k<k_f ½‖u_k‖² Tₛ",
                                                         "Σ_k<N ½‖u_k‖² Tₛ"),
                      cost_unit=COST_UNIT)


def value(res: Any, params: Any, dt: float) -> float:
    """The criterion's value of a run (before any failure penalty): Δv (``deadline``),
    E + ρ t_f (``time_energy``) or E + s_Nᵀ S s_N (``terminal``)."""
    if params.criterion == criteria.DEADLINE:
        return float(res.delta_v)
    if params.criterion == criteria.TIME_ENERGY:
        return float(criteria.time_energy_cost(res.energy, res.steps * dt, params.rho))
    return float(res.energy + criteria.terminal_cost(res.final_state,
                                                     terminal_weight(params)))


__all__ = ["COST_UNIT", "DEFAULT_RHO", "TERMINAL_SCALE", "position_tolerance", "report_info",
           "run_horizon", "run_steps", "terminal_weight", "value"]
