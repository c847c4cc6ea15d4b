"""Generic quadratic Lyapunov law for low-thrust transfers (the paper's "generic" law).

V = ½ (S W D)ᵀ K (S W D), W = diag(1/a_T, 1, 1, 1, 1), û = −Bᵀ∇V/‖Bᵀ∇V‖, thrust always on;
cost = time of flight (days). No rate scaling, S_a or periapsis penalty: a transfer whose
periapsis falls below ``impact_radius_km`` fails with status ``impact``.

Cost of failures: see :mod:`penaltyrun.problems.lowthrust.common`.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from penaltyrun.dynamics import lowthrust as lt
from penaltyrun.problems.lowthrust import report as lowthrust_report
from penaltyrun.problems.lowthrust.common import (
    CASE_PARAMS,
    CASES,
    DEFAULT_CASE,
    VARIANT_IGNORE,
    LowThrustParams,
    LowThrustProblem,
    base_prm,
    build_params,
    plot_elements,
    plot_thrust,
    plot_trajectory,
)
from penaltyrun.problems.lowthrust.progress import NoProgressParams

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Params(LowThrustParams, NoProgressParams):
    """Generic-law parameters: :class:`LowThrustParams` and the no-progress rule
    (:class:`~penaltyrun.problems.lowthrust.progress.NoProgressParams`); minimum time only."""

    def __post_init__(self) -> None:
        super().__post_init__()
        self.check_no_progress()


def kernel_params(p: Params) -> Any:
    """Kernel settings vector (shape (lt.N_PRM,)) for the generic law."""
    return p.apply_no_progress(base_prm(p, lt.LAW_GENERIC))


def make_problem(case: str, overrides: Mapping[str, Any]) -> LowThrustProblem:
    """Build the generic-law problem for ``case`` with parameter ``overrides``.

    Raises
    ------
    ConfigError
        Unknown case or parameter, or an invalid parameter value.
    """
    params = build_params(Params, case, overrides)
    logger.debug("lyapunov_transfer case %s: %s", case, params)
    return LowThrustProblem("lyapunov_transfer", case, params, kernel_params(params),
                            "min_time")


__all__ = [
    "CASES",
    "CASE_PARAMS",
    "DEFAULT_CASE",
    "VARIANT_IGNORE",
    "Params",
    "kernel_params",
    "make_problem",
    "plot_elements",
    "plot_thrust",
    "plot_trajectory",
]

#: Report hooks (:mod:`penaltyrun.problems.report_hooks`).
report_info, report_plots, report_sections = lowthrust_report.hooks("lyapunov_transfer", Params)
