"""Parameters and cases of the rendezvous MPC problem (``mpc_rendezvous``).

Precedence: :class:`Params` defaults → the case's entry of :data:`CASE_PARAMS` → overrides.
Every value is checked by :func:`validate`; a bad one raises
:class:`~penaltyrun.errors.ConfigError` naming its ``problem.params.<key>``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, ClassVar

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.problems import criteria, horizon
from penaltyrun.problems.base import ParamsMixin
from penaltyrun.problems.multiscenario import TrainingParams
from penaltyrun.typed import is_int, is_number

#: ``default``: weights on the state and input in SI units (m, m/s, m/s²);
#: ``scaled``: the same MPC with weights on the normalized state (1 km, 1 m/s) and input
#: (u_max), and eigenvalue boxes sized for them.
CASES = ("default", "scaled")
DEFAULT_CASE = "default"
CASE_PARAMS: dict[str, dict[str, Any]] = {
    "default": {},
    "scaled": {"state_scale": (1000.0, 1000.0, 1000.0, 1.0, 1.0, 1.0),
               "input_scale": (0.01, 0.01, 0.01),
               "q_eig_bounds": (1e-3, 10.0), "r_eig_bounds": (1e-3, 10.0)},
}
#: Parameters that do not change a run's result (reports do not split cells by them).
VARIANT_IGNORE = ("holdout_n_sphere", "holdout_sphere_radius_m", "holdout_seed",
                  "holdout_eccentricities", "holdout_thrust_scales",
                  "holdout_horizon_factor", "holdout_t_max_cap")
PLANTS = ("cw", "keplerian")


@dataclass(frozen=True)
class Params(ParamsMixin, TrainingParams, criteria.CriterionParams):
    """Rendezvous MPC parameters (SI units unless stated).

    Attributes
    ----------
    orbit_radius_km : float
        Radius a of the target's circular reference orbit (km); n = √(μ/a³).
    mu_km3_s2 : float
        Gravitational parameter μ (km³/s²).
    sample_time_s : float
        Sample time Tₛ of the zero-order hold and the controller (s).
    horizon : int
        Prediction horizon N (steps).
    u_max : float
        Bound on each commanded acceleration component (m/s²).
    t_max : float
        Time limit (s); a multiple of ``sample_time_s``.
    s0 : tuple of 6 float
        Initial relative state (x, y, z m; ẋ, ẏ, ż m/s), LVLH.
    pos_tol_m, vel_tol_m_s : float
        Converged when ‖r‖ ≤ pos_tol_m and ‖v‖ ≤ vel_tol_m_s.
    state_scale : tuple of 6 float
        σ_s: the tuned Q weighs s/σ_s, i.e. the MPC uses diag(1/σ_s) Q diag(1/σ_s).
    input_scale : tuple of 3 float
        σ_u: the tuned R weighs u/σ_u.
    q_eig_bounds, r_eig_bounds : tuple of float
        Eigenvalue (diagonal-entry) bounds of the tuned Q and R.
    failure_penalty : float
        Penalty scale (m/s) for runs that do not converge by t_max.
    plant : str
        ``cw``: the discrete CW model itself; ``keplerian``: nonlinear relative motion about
        a Keplerian target orbit (compiled RK4).
    plant_eccentricity : float
        Eccentricity of that target orbit (semi-major axis ``orbit_radius_km``), ``keplerian``.
    plant_true_anomaly_deg : float
        Target's true anomaly at t = 0 (deg), ``keplerian``.
    plant_substeps : int
        RK4 steps per sample, ``keplerian``.
    thrust_scale : float
        Applied acceleration = thrust_scale × commanded (1: no thrust error).
    qp_primal_tol, qp_dual_tol : float
        DAQP feasibility tolerances (primal relative to u_max).
    qp_iter_limit : int
        DAQP iteration limit per QP (hitting it: status ``qp_failure``).
    holdout_n_sphere : int
        Held-out starts at rest on the sphere of radius ``holdout_sphere_radius_m``
        (seeded, uniform on the sphere); 0: none.
    holdout_sphere_radius_m : float
        Radius of that sphere (m), also that of the training starts drawn for
        ``train_sample`` (so with ``train_sample`` it changes what a run tunes, and
        reports split cells by it).
    holdout_seed : int
        Seed of the sphere sample (same set for every job).
    holdout_eccentricities : tuple of float
        Model-mismatch scenarios: the Keplerian plant with these eccentricities.
    holdout_thrust_scales : tuple of float
        Model-mismatch scenarios: the CW plant with these thrust scales.
    holdout_horizon_factor, holdout_t_max_cap : float
        Held-out horizon T = min(factor · t_max, cap) s, rounded down to whole samples and
        never below ``t_max``: the held-out scenarios are judged at T (a run still not
        converged there gets the graded failure cost at T) and at ``t_max`` (see
        :mod:`penaltyrun.problems.horizon`). Defaults 4 and 12 000 s: every best-known
        gain of the rendezvous study converges from every held-out start within 12 000 s.
    train_scenarios, train_aggregate, train_sample, train_seed
        Multi-scenario tuning (see :mod:`penaltyrun.problems.multiscenario`).
    criterion : str
        ``deadline`` (Δv to convergence before ``t_max``, default), ``time_energy``
        (Σ (½‖u_k‖² + ρ) Tₛ to convergence) or ``terminal`` (Σ ½‖u_k‖² Tₛ over t_max plus
        s_Nᵀ S s_N); see :mod:`penaltyrun.problems.mpc.criteria`.
    rho : float
        ρ of ``time_energy`` (m²/s⁴; default 1e-5).
    terminal_weight : tuple or None
        S of ``terminal`` (6 diagonal entries or 6×6 symmetric PSD, m²/s³ per m² and per
        (m/s)²); ``None``: 0.01 · diag(I₃/pos_tol_m², I₃/vel_tol_m_s²).
    free_time_cap : float
        Long horizon of ``time_energy`` (s, whole samples; default 12 000).
    """

    HOLDOUT_OFF: ClassVar[Mapping[str, Any]] = MappingProxyType(
        {"holdout_n_sphere": 0, "holdout_eccentricities": (), "holdout_thrust_scales": ()})
    orbit_radius_km: float = 6778.137
    mu_km3_s2: float = 398600.4418
    sample_time_s: float = 20.0
    horizon: int = 20
    u_max: float = 0.01
    t_max: float = 3000.0
    s0: tuple[float, ...] = (100.0, -1000.0, 50.0, 0.0, 0.0, 0.0)
    pos_tol_m: float = 1.0
    vel_tol_m_s: float = 0.01
    state_scale: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
    input_scale: tuple[float, ...] = (1.0, 1.0, 1.0)
    q_eig_bounds: tuple[float, float] = (1e-8, 100.0)
    r_eig_bounds: tuple[float, float] = (100.0, 1e4)
    failure_penalty: float = 100.0
    plant: str = "cw"
    plant_eccentricity: float = 0.0
    plant_true_anomaly_deg: float = 0.0
    plant_substeps: int = 20
    thrust_scale: float = 1.0
    qp_primal_tol: float = 1e-10
    qp_dual_tol: float = 1e-12
    qp_iter_limit: int = 1000
    holdout_n_sphere: int = 16
    holdout_sphere_radius_m: float = 1000.0
    holdout_seed: int = 20250422
    holdout_eccentricities: tuple[float, ...] = (0.01,)
    holdout_thrust_scales: tuple[float, ...] = (0.95, 1.05)
    holdout_horizon_factor: float = 4.0
    holdout_t_max_cap: float = 12_000.0
    rho: float = 1e-5
    free_time_cap: float = 12_000.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "terminal_weight", criteria.freeze(self.terminal_weight))

    @property
    def n_steps(self) -> int:
        """Closed-loop steps t_max / Tₛ."""
        return int(round(self.t_max / self.sample_time_s))

    def daqp_settings(self) -> dict[str, float]:
        """DAQP settings of the QPs."""
        return {"primal_tol": float(self.qp_primal_tol), "dual_tol": float(self.qp_dual_tol),
                "iter_limit": int(self.qp_iter_limit)}


def _key(name: str) -> str:
    return f"problem.params.{name}"


def _positive(p: Params, name: str) -> None:
    value = getattr(p, name)
    if not is_number(value, any_real=True) or not (math.isfinite(value) and value > 0):
        raise ConfigError(_key(name), f"must be a positive number, got {value!r}")


def _integer(p: Params, name: str, low: int) -> None:
    value = getattr(p, name)
    if not is_int(value, any_integral=True) or value < low:
        raise ConfigError(_key(name), f"must be an integer >= {low}, got {value!r}")


def _vector(p: Params, name: str, size: int, positive: bool) -> None:
    value = getattr(p, name)
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(_key(name), f"must be a list of {size} numbers, got {value!r}") \
            from None
    if arr.shape != (size,) or not np.all(np.isfinite(arr)) or (positive and np.any(arr <= 0)):
        what = "positive numbers" if positive else "finite numbers"
        raise ConfigError(_key(name), f"must be a list of {size} {what}, got {value!r}")


def _bounds(p: Params, name: str) -> None:
    value = getattr(p, name)
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ConfigError(_key(name), f"expected [lower, upper], got {value!r}") from None
    if not (0.0 < lo < hi < math.inf):
        raise ConfigError(_key(name), f"need 0 < lower < upper < inf, got [{lo}, {hi}]")


def validate(p: Params) -> Params:
    """Check every parameter; return ``p`` unchanged.

    Raises
    ------
    ConfigError
        Naming the first bad key.
    """
    for name in ("orbit_radius_km", "mu_km3_s2", "sample_time_s", "u_max", "t_max",
                 "pos_tol_m", "vel_tol_m_s", "failure_penalty", "thrust_scale",
                 "qp_primal_tol", "qp_dual_tol", "holdout_sphere_radius_m"):
        _positive(p, name)
    for name, low in (("horizon", 1), ("plant_substeps", 1), ("qp_iter_limit", 1),
                      ("holdout_n_sphere", 0), ("holdout_seed", 0)):
        _integer(p, name, low)
    ratio = p.t_max / p.sample_time_s
    if abs(ratio - round(ratio)) > 1e-9 * max(1.0, ratio):
        raise ConfigError(_key("t_max"), f"must be a multiple of sample_time_s "
                          f"({p.sample_time_s:g} s), got {p.t_max:g} s")
    _vector(p, "s0", 6, positive=False)
    _vector(p, "state_scale", 6, positive=True)
    _vector(p, "input_scale", 3, positive=True)
    _bounds(p, "q_eig_bounds")
    _bounds(p, "r_eig_bounds")
    if p.plant not in PLANTS:
        raise ConfigError(_key("plant"), f"unknown plant {p.plant!r}", allowed=PLANTS)
    e = p.plant_eccentricity
    if not is_number(e, any_real=True) or not 0.0 <= e < 1.0:
        raise ConfigError(_key("plant_eccentricity"), f"must be in [0, 1), got {e!r}")
    if p.plant == "cw" and e != 0.0:
        raise ConfigError(_key("plant_eccentricity"),
                          "needs plant=keplerian (the CW plant is a circular orbit)")
    if p.plant == "keplerian" and p.orbit_radius_km * (1.0 - e) <= 6378.137:
        raise ConfigError(_key("plant_eccentricity"), f"perigee radius "
                          f"{p.orbit_radius_km * (1.0 - e):.1f} km is inside the Earth")
    if not math.isfinite(float(p.plant_true_anomaly_deg)):
        raise ConfigError(_key("plant_true_anomaly_deg"), "must be a finite number")
    for name, check in (("holdout_eccentricities", lambda v: 0.0 <= v < 1.0),
                        ("holdout_thrust_scales", lambda v: v > 0.0)):
        try:
            values = [float(v) for v in getattr(p, name)]
        except (TypeError, ValueError):
            raise ConfigError(_key(name), f"must be a list of numbers, got "
                              f"{getattr(p, name)!r}") from None
        if not all(math.isfinite(v) and check(v) for v in values):
            raise ConfigError(_key(name), f"out of range: {values}")
        if len(set(values)) != len(values):
            raise ConfigError(_key(name), f"lists a value twice: {values}")
    horizon.check_settings(p, "problem.params")
    criteria.check(p, "problem.params")
    if p.terminal_weight is not None:
        criteria.terminal_matrix(p.terminal_weight, 6, _key("terminal_weight"))
    return p


def build_params(case: str, overrides: Mapping[str, Any]) -> Params:
    """Defaults → case entry → ``overrides``, validated.

    Raises
    ------
    ConfigError
        Unknown case or parameter, or a bad value.
    """
    if case not in CASE_PARAMS:
        raise ConfigError("case", f"unknown case {case!r}", allowed=CASES)
    merged = {**CASE_PARAMS[case], **dict(overrides)}
    return validate(Params.from_mapping(merged))


__all__ = ["CASES", "CASE_PARAMS", "DEFAULT_CASE", "PLANTS", "VARIANT_IGNORE", "Params",
           "build_params", "validate"]
