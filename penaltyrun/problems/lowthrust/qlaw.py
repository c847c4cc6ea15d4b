"""Q-law (Petropoulos) low-thrust transfers with a full penalty matrix K (paper Eq. 30).

Q = (1 + W_p P) (S N D)ᵀ K (S N D); thrust direction û = −Bᵀ∇Q/‖Bᵀ∇Q‖ (see
:mod:`penaltyrun.dynamics.lowthrust`). ``objective: min_time`` thrusts always and costs the
time of flight (days); ``objective: min_fuel`` coasts when the effectivity (η_a or η_r) is
below η_cut and costs the propellant (kg). In min-fuel mode η_cut is also an extra decision
variable (``scalars``), its config value is the default when no scalar is given.

Cost of failures: see :mod:`penaltyrun.problems.lowthrust.common`.

No gradient (:data:`NO_GRADIENT`): the cost is piecewise in K. In min-fuel mode the
effectivity gate η ≥ η_cut switches the thrust on and off, so the propellant jumps when a
coast arc appears or vanishes; in both modes the maximum rates carry |cos ω| and |sin ω|
and the arrival is the first time every targeted element is inside its tolerance (the
last element to enter changes with K), which gives kinks. An exact gradient would belong to
a different law with a smoothed gate and smooth tolerances (a possible future variant), not
to this one; a difference quotient across the switches is not a gradient.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from penaltyrun.dynamics import lowthrust as lt
from penaltyrun.errors import ConfigError
from penaltyrun.problems.base import ScalarSpec
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

OBJECTIVES = ("min_time", "min_fuel")
#: Why the Q-law's cost has no gradient (one line; see the module docstring).
NO_GRADIENT = ("the Q-law cost is piecewise in K (the effectivity gate switches the thrust "
               "on and off, |cos ω|, |sin ω| in the maximum rates and the arrival test on "
               "every targeted element give jumps and kinks); only a smoothed law would "
               "have one")
COAST_MODES = ("eta_a", "eta_r")


@dataclass(frozen=True)
class Params(LowThrustParams, NoProgressParams):
    """Q-law parameters: the shared ones (:class:`LowThrustParams`), the no-progress rule
    (:class:`~penaltyrun.problems.lowthrust.progress.NoProgressParams`) plus

    Attributes
    ----------
    objective : str
        ``"min_time"`` (cost: ToF, days) or ``"min_fuel"`` (cost: propellant, kg).
    coast_mode : str
        Effectivity used for coasting in min-fuel mode: ``"eta_a"`` (absolute) or
        ``"eta_r"`` (relative).
    eta_cut : float
        Effectivity threshold (thrust when η ≥ η_cut); default of the ``eta_cut`` scalar.
    n_grid : int
        True-anomaly grid points (≥ 36) for Q̇_nn and Q̇_nx, refined by golden section.
    rp_min_km, k_p, W_p : float
        Periapsis penalty P = exp[k_p (1 − r_p/r_p,min)] with weight W_p.
    m_s, n_exp, r_exp : float
        S_a = [1 + |(a − a_T)/(m_s a_T)|^n]^(1/r).
    b : float
        ω̇_xx blending of in-plane and out-of-plane maxima.
    a_cap_km : float
        Semi-major-axis cap, km; when > 0 the penalty gains a term exp[k_p (a/a_cap − 1)]
        (0 disables; used to make Case E* converge).
    """

    objective: str = "min_time"
    coast_mode: str = "eta_a"
    eta_cut: float = 0.2
    n_grid: int = 36
    rp_min_km: float = 6578.0
    k_p: float = 100.0
    W_p: float = 1.0
    m_s: float = 3.0
    n_exp: float = 4.0
    r_exp: float = 2.0
    b: float = 0.01
    a_cap_km: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        self.check_no_progress()
        if self.objective not in OBJECTIVES:
            raise ConfigError("problem.params.objective", f"got {self.objective!r}", OBJECTIVES)
        if self.coast_mode not in COAST_MODES:
            raise ConfigError("problem.params.coast_mode", f"got {self.coast_mode!r}",
                              COAST_MODES)
        if self.n_grid < 36:
            raise ConfigError("problem.params.n_grid", "must be >= 36")
        if not 0.0 <= self.eta_cut <= 1.0:
            raise ConfigError("problem.params.eta_cut", "must be in [0, 1]")
        for name in ("rp_min_km", "m_s", "r_exp"):
            if not getattr(self, name) > 0.0:
                raise ConfigError(f"problem.params.{name}", "must be > 0")


def kernel_params(p: Params) -> Any:
    """Kernel settings vector (shape (lt.N_PRM,)) for the Q-law."""
    prm = p.apply_no_progress(base_prm(p, lt.LAW_QLAW))
    prm[lt.I_RPMIN] = p.rp_min_km
    prm[lt.I_KP] = p.k_p
    prm[lt.I_WP] = p.W_p
    prm[lt.I_MS] = p.m_s
    prm[lt.I_N] = p.n_exp
    prm[lt.I_R] = p.r_exp
    prm[lt.I_B] = p.b
    prm[lt.I_ACAP] = p.a_cap_km
    prm[lt.I_NGRID] = p.n_grid
    prm[lt.I_ETACUT] = p.eta_cut
    if p.objective == "min_fuel":
        prm[lt.I_COAST] = lt.COAST_ETA_A if p.coast_mode == "eta_a" else lt.COAST_ETA_R
    return prm


def make_problem(case: str, overrides: Mapping[str, Any]) -> LowThrustProblem:
    """Build the Q-law problem for ``case`` with parameter ``overrides``.

    Raises
    ------
    ConfigError
        Unknown case or parameter, or an invalid parameter value.
    """
    params = build_params(Params, case, overrides)
    scalars = (ScalarSpec("eta_cut", (0.0, 1.0)),) if params.objective == "min_fuel" else ()
    logger.debug("qlaw case %s: %s", case, params)
    return LowThrustProblem("qlaw", case, params, kernel_params(params), params.objective,
                            scalars, NO_GRADIENT)


__all__ = [
    "CASES",
    "CASE_PARAMS",
    "DEFAULT_CASE",
    "NO_GRADIENT",
    "VARIANT_IGNORE",
    "OBJECTIVES",
    "Params",
    "kernel_params",
    "make_problem",
    "plot_elements",
    "plot_thrust",
    "plot_trajectory",
]

#: Report hooks (:mod:`penaltyrun.problems.report_hooks`).
report_info, report_plots, report_sections = lowthrust_report.hooks("qlaw", Params)
