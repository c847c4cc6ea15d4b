"""``problem=lqr``: tune the Q and R of an LQR on the user's plant, given in the config.

The plant is ẋ = A x + B u (``A``, ``B``, ``plant_file`` or ``plant``) or a nonlinear
vectorized model (``dynamics``) linearized at the origin; the gain is the LQR gain of the
tuned (Q, R); the cost is the closed-loop performance ∫ (xᵀ W_x x + uᵀ W_u u) dt averaged
over the training starts ``x0``. Modules: :mod:`~penaltyrun.problems.lqr.plant` (sources
and their checks), :mod:`~penaltyrun.problems.lqr.params` (parameters, the known-answer
set-up), :mod:`~penaltyrun.problems.lqr.problem` (the problem object, its gains from
:mod:`penaltyrun.dynamics.riccati`),
:mod:`~penaltyrun.problems.lqr.plots` (figures),
:mod:`~penaltyrun.problems.lqr.expr` (arithmetic in the YAML),
:mod:`~penaltyrun.problems.lqr.discrete` (discrete-time loops),
:mod:`~penaltyrun.problems.lqr.constraints` (semi-definite Q, integral action,
constraints), :mod:`~penaltyrun.problems.lqr.margins` (disk margin, settling time,
overshoot) and :mod:`~penaltyrun.problems.lqr.reference` (independent scipy references).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

from penaltyrun.problems.lqr import params as _params
from penaltyrun.problems.lqr.params import (
    CASES,
    CODE_PARAMS,
    DEFAULT_CASE,
    FILE_PARAMS,
    KNOWN_ANSWER,
    VARIANT_IGNORE,
    Params,
    build_params,
)
from penaltyrun.problems.lqr.plant import load
from penaltyrun.problems.lqr.plots import plot_histories
from penaltyrun.problems.lqr.problem import STATUSES, LQRProblem

logger = logging.getLogger(__name__)


def make_problem(case: str, overrides: Mapping[str, Any]) -> LQRProblem:
    """Build ``problem=lqr``: defaults → known-answer set-up (no plant given) → overrides.

    Raises
    ------
    ConfigError
        Naming the key of any malformed input (plant, sizes, weights, bounds, limits).
    """
    params = build_params(case, overrides)
    _params.scalars(params)
    n_hint = m_hint = None
    if params.x0 is not None:
        first = params.x0[0] if params.x0 and isinstance(params.x0[0], tuple) else params.x0
        n_hint = len(first)
    if params.input_weight is not None:
        m_hint = len(params.input_weight)
    elif isinstance(params.u_max, tuple):
        m_hint = len(params.u_max)
    plant = load({**{k: getattr(params, k) for k in _params.PLANT_KEYS}, "dt": params.dt},
                 n_hint, m_hint)
    logger.debug("lqr plant from %s: n=%d, m=%d", plant.source, plant.n_states,
                 plant.n_inputs)
    return LQRProblem(case, params, plant)


def report_info(case: str, params: Mapping[str, Any]) -> Any:
    """Report hook (``penaltyrun.problems.report_hooks``): the cost, its unit
    (``cost_unit``) and what the held-out starts are.

    Returns
    -------
    penaltyrun.problems.base.ReportInfo
    """
    from penaltyrun.problems.base import ReportInfo

    p = build_params(case, params)
    if p.holdout_x0 is not None:
        holdout = f"{len(p.holdout_x0)} initial states given in holdout_x0"
    elif p.holdout_n:
        holdout = (f"{p.holdout_n} initial states drawn uniformly (seed {p.holdout_seed}) on "
                   "the sphere whose radius is the mean norm of the training states x0")
    else:
        holdout = ""
    name = ("J = mean over x0 of Σ_k<T/dt (x[k]ᵀW_x x[k] + u[k]ᵀW_u u[k])" if p.dt is not None
            else "J = mean over x0 of ∫₀ᵀ (xᵀW_x x + uᵀW_u u) dt")
    from penaltyrun.problems.criteria import report_name

    free = ("mean over x0 of Σ_k<k_s (x[k]ᵀW_x x[k] + u[k]ᵀW_u u[k])" if p.dt is not None
            else "mean over x0 of ∫₀^t_s (xᵀW_x x + uᵀW_u u) dt")
    return ReportInfo(cost_name=report_name(p, name, free, name.removeprefix("J = ")),
                      cost_unit=_params.cost_unit(p, p.dt is not None),
                      holdout_description=holdout)


def report_plots(sims: Mapping[str, Mapping[str, Any]], case: str,
                 params: Mapping[str, Any]) -> dict[str, Any]:
    """Report hook: state and input norms of every training start (:func:`plot_histories`)."""
    return {"closed-loop state and input norms, every training start": plot_histories(sims)}


__all__ = ["CASES", "CODE_PARAMS", "DEFAULT_CASE", "FILE_PARAMS", "KNOWN_ANSWER", "STATUSES",
           "VARIANT_IGNORE", "LQRProblem", "Params", "make_problem", "plot_histories",
           "report_info", "report_plots"]
