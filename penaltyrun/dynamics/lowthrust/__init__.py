"""Compiled low-thrust transfer kernels: MEE dynamics, Q-law and generic Lyapunov law.

Everything here is a numba ``@njit(cache=True)`` function of floats and arrays.

Units: km, s, kg, N (thrust), s (Isp); angles in rad. Slow (Keplerian) elements are ordered
``(a, e, i, Ω, ω)``; modified equinoctial elements (MEE) ``(p, f, g, h, k, L)``; the propagated
state is ``y = (p, f, g, h, k, L, m)`` with time as the independent variable.

Modules (this package re-exports their public names):

* :mod:`.settings` — constants, kernel settings indices ``I_*``, status codes, history columns;
* :mod:`.elements` — element conversions, Gauss variational equations in MEE, RK4 step, Gauss
  matrix;
* :mod:`.qlaw` — the Q-law and its analytic gradient in one real-valued pass (production);
* :mod:`.qlaw_complex` — the complex-step Q-law, kept as the test and benchmark reference;
* :mod:`.steering` — thrust direction, generic Lyapunov law, min-fuel effectivity search;
* :mod:`.loop` — :func:`propagate`, the zero-order-hold propagation loop and its stop rules.

Both laws share the penalty machinery: ``K`` (5×5, SPD), a binary selector ``sel`` (targeted
elements) applied to both factors of the quadratic form (``sides = 2``) or to the left factor
only (``sides = 1``).
"""

from penaltyrun.dynamics.lowthrust.elements import (
    element_errors,
    gauss_matrix,
    kep2mee,
    mee2cart,
    mee2kep,
    mee_rhs,
    rk4_step,
    wrap_angle,
)
from penaltyrun.dynamics.lowthrust.loop import propagate
from penaltyrun.dynamics.lowthrust.qlaw import N_WORK, qlaw_grad, qlaw_gradient, selector_matrix
from penaltyrun.dynamics.lowthrust.qlaw_complex import (
    CS_STEP,
    effectivity_extremes_golden,
    max_rates,
    qlaw_gradient_cs,
    qlaw_value,
)
from penaltyrun.dynamics.lowthrust.settings import (
    COAST_ETA_A,
    COAST_ETA_R,
    COAST_NONE,
    G0,
    GRAD_ANALYTIC,
    GRAD_COMPLEX,
    HIST_COLS,
    I_ACAP,
    I_B,
    I_COAST,
    I_DT,
    I_EFLOOR,
    I_ETACUT,
    I_GRAD,
    I_IFLOOR,
    I_ISP,
    I_KP,
    I_LAW,
    I_MAXSTEPS,
    I_MFLOOR,
    I_MS,
    I_N,
    I_NGRID,
    I_NPFRAC,
    I_NPREVS,
    I_NSUB,
    I_R,
    I_REVMAX,
    I_RIMPACT,
    I_RPMIN,
    I_SIDES,
    I_STALLREL,
    I_STALLREVS,
    I_THRUST,
    I_TMAX,
    I_WP,
    LAW_GENERIC,
    LAW_QLAW,
    MU,
    N_HIST,
    N_PRM,
    R_E,
    ST_CONVERGED,
    ST_ESCAPE,
    ST_IMPACT,
    ST_NO_PROGRESS,
    ST_PROPELLANT,
    ST_REV,
    ST_STALL,
    ST_TOF,
    STATUS_NAMES,
    TWO_PI,
)
from penaltyrun.dynamics.lowthrust.steering import (
    bt_grad,
    effectivity_extremes,
    generic_grad,
    generic_gradient,
    law_eval,
    law_eval_m,
)

__all__ = [
    "COAST_ETA_A",
    "COAST_ETA_R",
    "COAST_NONE",
    "CS_STEP",
    "G0",
    "GRAD_ANALYTIC",
    "GRAD_COMPLEX",
    "HIST_COLS",
    "I_ACAP",
    "I_B",
    "I_COAST",
    "I_DT",
    "I_EFLOOR",
    "I_ETACUT",
    "I_GRAD",
    "I_IFLOOR",
    "I_ISP",
    "I_KP",
    "I_LAW",
    "I_MAXSTEPS",
    "I_MFLOOR",
    "I_MS",
    "I_N",
    "I_NGRID",
    "I_NPFRAC",
    "I_NPREVS",
    "I_NSUB",
    "I_R",
    "I_REVMAX",
    "I_RIMPACT",
    "I_RPMIN",
    "I_SIDES",
    "I_STALLREL",
    "I_STALLREVS",
    "I_THRUST",
    "I_TMAX",
    "I_WP",
    "LAW_GENERIC",
    "LAW_QLAW",
    "MU",
    "N_HIST",
    "N_PRM",
    "N_WORK",
    "R_E",
    "STATUS_NAMES",
    "ST_CONVERGED",
    "ST_ESCAPE",
    "ST_IMPACT",
    "ST_NO_PROGRESS",
    "ST_PROPELLANT",
    "ST_REV",
    "ST_STALL",
    "ST_TOF",
    "TWO_PI",
    "bt_grad",
    "effectivity_extremes",
    "effectivity_extremes_golden",
    "element_errors",
    "gauss_matrix",
    "generic_grad",
    "generic_gradient",
    "kep2mee",
    "law_eval",
    "law_eval_m",
    "max_rates",
    "mee2cart",
    "mee2kep",
    "mee_rhs",
    "propagate",
    "qlaw_grad",
    "qlaw_gradient",
    "qlaw_gradient_cs",
    "qlaw_value",
    "rk4_step",
    "selector_matrix",
    "wrap_angle",
]
