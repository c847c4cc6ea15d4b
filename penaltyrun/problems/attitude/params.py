"""Parameters, cases and validation of the attitude problems (``attitude_lyapunov``,
``attitude_lqr``).

Cases
-----
* ``detumble`` (ω0 = (0.01, −0.01, 0.01) rad/s) and ``rest_to_rest`` (ω0 = 0), both from
  Euler angles (yaw, pitch, roll) = (60°, 80°, −60°), intrinsic Z-Y-X, I = diag(10, 15, 20)
  kg·m², t_max = 100 s, event ‖(q0 − 1, q_v, ω)‖ ≤ 1e-4 (the main set-up).
* ``schaub_detumble`` and ``schaub_detumble_sat``: the authors' companion study (after
  Schaub & Junkins): I = diag(140, 100, 80) kg·m², MRP σ0 = (0.6, −0.4, 0.2),
  ω0 = (0.70, 0.20, −0.15) rad/s, t_max = 350 s, event ‖(10·q_v, ω)‖ ≤ 1e-3 (weights
  (0, 10, 1): q0 = ±1 both accepted), eigenvalue bounds [1e-8, 20]; ``_sat`` adds the
  per-axis torque limit |u_i| ≤ 1 N·m. Their held-out set is seeded perturbations of that
  initial attitude and those rates (no Euler grid). Both minimize the authors' objective
  form ``neg_reciprocal`` (see :mod:`penaltyrun.problems.attitude.objective`).

Initial quaternions are normalized to unit length with q0 ≥ 0.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from numbers import Integral, Real
from types import MappingProxyType
from typing import Any, ClassVar

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.problems import criteria, horizon
from penaltyrun.problems.attitude.frames import (
    ATTITUDE_TYPES,
    PREFIX,
    attitude_to_quaternion,
)
from penaltyrun.problems.attitude.objective import OBJECTIVE_FORMS
from penaltyrun.problems.base import ParamsMixin
from penaltyrun.problems.multiscenario import TrainingParams

#: Parameters that do not change a run's result (reports do not split cells by them).
VARIANT_IGNORE = ("holdout_n", "holdout_lo_deg", "holdout_hi_deg", "holdout_n_perturbed",
                  "holdout_perturb_deg", "holdout_rate_rel", "holdout_seed",
                  "holdout_horizon_factor", "holdout_t_max_cap")

_SCHAUB: dict[str, Any] = {
    "inertia": (140.0, 100.0, 80.0), "attitude_type": "mrp", "attitude": (0.6, -0.4, 0.2),
    "omega0": (0.70, 0.20, -0.15), "t_max": 350.0, "tol": 1e-3, "event_weight_q0": 0.0,
    "event_weight_qv": 10.0, "event_weight_w": 1.0, "eig_bounds": (1e-8, 20.0),
    "holdout_n": 0, "holdout_n_perturbed": 32, "objective_form": "neg_reciprocal",
}
CASES = ("detumble", "rest_to_rest", "schaub_detumble", "schaub_detumble_sat")
DEFAULT_CASE = "detumble"
CASE_PARAMS: dict[str, dict[str, Any]] = {
    "detumble": {"omega0": (0.01, -0.01, 0.01)},
    "rest_to_rest": {"omega0": (0.0, 0.0, 0.0)},
    "schaub_detumble": dict(_SCHAUB),
    "schaub_detumble_sat": {**_SCHAUB, "u_max": 1.0},
}


@dataclass(frozen=True)
class Params(ParamsMixin, TrainingParams, criteria.CriterionParams):
    """Attitude problem parameters (SI units).

    Attributes
    ----------
    inertia : tuple
        Inertia in kg·m²: 3 principal moments (diagonal) or a symmetric PD 3×3 nested tuple.
    attitude_type : str
        How ``attitude`` is given: ``"euler"`` (yaw, pitch, roll in degrees, intrinsic
        Z-Y-X), ``"quaternion"`` (q0, q1, q2, q3, scalar first; normalized) or ``"mrp"``
        (modified Rodrigues parameters σ1, σ2, σ3).
    attitude : tuple of float
        Initial attitude in the representation ``attitude_type``.
    omega0 : tuple of float
        Initial body rates (rad/s).
    t_max : float
        Horizon cap t_f (s); the terminal event must fire before it.
    tol : float
        Terminal event: the weighted distance
        ‖(w_q0 (q0 − 1), w_qv q_v, w_ω ω)‖ ≤ tol (mixed units: quaternion and rad/s).
    event_weight_q0, event_weight_qv, event_weight_w : float
        Event weights w_q0, w_qv, w_ω (≥ 0, w_qv and w_ω > 0). Default (1, 1, 1):
        ‖(q0 − 1, q_v, ω)‖; the companion study uses (0, 10, 1).
    u_max : float or None
        Per-axis torque limit |u_i| ≤ u_max (N·m); ``None``: no saturation.
    rtol, atol : float
        Integration tolerances (paper: 1e-10).
    max_step : float
        Largest integration step (s); default none (the error control chooses the steps).
    event_spacing : float
        Largest time between two dense-output checks of the event (and of the saturation
        switch points) where it could fire (s), so a short dip of the non-monotone distance
        under ``tol`` is not stepped over: dips longer than this are always found.
    n_event_samples : int
        At least this many such checks per step.
    max_steps : int
        Step cap per run (hitting it counts as ``step_failure``).
    eig_bounds : tuple of float
        Eigenvalue (or diagonal-entry) bounds of every tuned matrix.
    failure_penalty : float
        Scale of the graded penalty of runs whose event does not fire (N²·m²·s).
    objective_form : str
        What the optimizer minimizes: ``cost`` (the recorded cost) or ``neg_reciprocal``
        (−1/J if converged, else the final error d − tol; the companion study's form).
        Records and reports always hold J (see
        :mod:`penaltyrun.problems.attitude.objective`).
    holdout_n : int
        Held-out robustness grid: yaw, pitch and roll each take ``holdout_n`` values in
        linspace(holdout_lo_deg, holdout_hi_deg) → holdout_n³ rest-to-rest starts
        (0 disables the held-out evaluation).
    holdout_lo_deg, holdout_hi_deg : float
        Range of the held-out Euler angles (degrees).
    holdout_n_perturbed : int
        Further held-out scenarios: seeded perturbations of this problem's own initial
        state (attitude rotated about a random axis by up to ``holdout_perturb_deg``,
        each rate scaled by 1 ± up to ``holdout_rate_rel``); 0 = none.
    holdout_perturb_deg, holdout_rate_rel : float
        Perturbation sizes (degrees; relative), also those of the training states drawn
        for ``train_sample`` (so with ``train_sample`` they change what a run tunes, and
        reports split cells by them).
    holdout_seed : int
        Seed of the perturbations (the held-out set is the same for every job).
    holdout_horizon_factor, holdout_t_max_cap : float
        Held-out horizon T = min(factor · t_max, cap) s, never below ``t_max``: the
        held-out starts are judged at T (a gain still not converged there gets the graded
        failure cost at T) and at ``t_max`` (see :mod:`penaltyrun.problems.horizon`).
        Defaults 50 and 10 000 s: the slowest stable gains tuned at t_max = 100 s need
        up to ~5 000 s from held-out attitudes.
    train_scenarios, train_aggregate
        Multi-scenario tuning (see :mod:`penaltyrun.problems.multiscenario`).
    criterion : str
        ``deadline`` (the paper's: energy to the event before ``t_max``), ``time_energy``
        (free final time: energy + ρ · arrival time) or ``terminal`` (energy to ``t_max``
        plus x(T)ᵀ S x(T), x = (q_v, ω), no event); see
        :mod:`penaltyrun.problems.attitude.criteria`.
    rho : float
        ρ of ``time_energy``, N²·m² (the energy one second is worth); default 1e-3.
    terminal_weight : tuple or None
        S of ``terminal`` (6 diagonal entries or a 6×6 symmetric PSD matrix, N²·m²·s per
        unit of (q_v, ω)²); ``None``: diag(w_qv² I₃, w_ω² I₃) / tol².
    free_time_cap : float
        Long horizon of ``time_energy`` (s; default 10 000): no arrival by then is a failure.
    """

    HOLDOUT_OFF: ClassVar[Mapping[str, Any]] = MappingProxyType(
        {"holdout_n": 0, "holdout_n_perturbed": 0})
    inertia: tuple = (10.0, 15.0, 20.0)
    attitude_type: str = "euler"
    attitude: tuple = (60.0, 80.0, -60.0)
    omega0: tuple = (0.01, -0.01, 0.01)
    t_max: float = 100.0
    tol: float = 1e-4
    event_weight_q0: float = 1.0
    event_weight_qv: float = 1.0
    event_weight_w: float = 1.0
    u_max: float | None = None
    rtol: float = 1e-10
    atol: float = 1e-10
    max_step: float = float("inf")
    event_spacing: float = 0.05
    n_event_samples: int = 4
    max_steps: int = 1_000_000
    eig_bounds: tuple = (1e-8, 10.0)
    failure_penalty: float = 1000.0
    objective_form: str = "cost"
    holdout_n: int = 6
    holdout_lo_deg: float = 10.0
    holdout_hi_deg: float = 350.0
    holdout_n_perturbed: int = 0
    holdout_perturb_deg: float = 10.0
    holdout_rate_rel: float = 0.1
    holdout_seed: int = 20250422
    holdout_horizon_factor: float = 50.0
    holdout_t_max_cap: float = 10_000.0
    rho: float = 1e-3
    free_time_cap: float = 10_000.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "terminal_weight", criteria.freeze(self.terminal_weight))
        inertia = self.inertia
        if len(inertia) == 3 and all(np.ndim(row) == 1 for row in inertia):
            object.__setattr__(self, "inertia", tuple(tuple(float(v) for v in row)
                                                      for row in inertia))
        else:
            object.__setattr__(self, "inertia", tuple(inertia))

    def inertia_matrix(self) -> np.ndarray:
        """Inertia as a 3×3 array (kg·m²)."""
        arr = np.asarray(self.inertia, dtype=float)
        return np.diag(arr) if arr.ndim == 1 else arr

    def initial_quaternion(self) -> np.ndarray:
        """Unit initial quaternion with q0 ≥ 0, shape (4,)."""
        return attitude_to_quaternion(self.attitude_type, self.attitude)

    def initial_state(self) -> np.ndarray:
        """Initial (q, ω), shape (7,)."""
        return np.concatenate([self.initial_quaternion(), np.asarray(self.omega0, float)])

    def event_weights(self) -> tuple[float, float, float]:
        """Event weights (w_q0, w_qv, w_ω)."""
        return (float(self.event_weight_q0), float(self.event_weight_qv),
                float(self.event_weight_w))

    def event_distance(self, y: Any) -> np.ndarray:
        """Weighted event distance of states ``y`` (shape (..., ≥7): q, ω, ...)."""
        y = np.asarray(y, dtype=float)
        w0, wq, ww = self.event_weights()
        return np.sqrt((w0 * (y[..., 0] - 1.0)) ** 2 + wq ** 2 * np.sum(y[..., 1:4] ** 2, axis=-1)
                       + ww ** 2 * np.sum(y[..., 4:7] ** 2, axis=-1))

    def saturation(self) -> float:
        """Per-axis torque limit for the kernel (``inf`` when saturation is off)."""
        return float("inf") if self.u_max is None else float(self.u_max)



def validate(params: Params) -> Params:
    """Check parameter values; returns ``params`` unchanged.

    Raises
    ------
    ConfigError
        Naming the first offending key.
    """
    try:
        inertia = params.inertia_matrix()
    except (TypeError, ValueError):
        raise ConfigError(f"{PREFIX}.inertia", "expected 3 moments or a 3x3 matrix") from None
    if inertia.shape != (3, 3) or not np.all(np.isfinite(inertia)):
        raise ConfigError(f"{PREFIX}.inertia", "expected 3 moments or a 3x3 matrix")
    if not np.allclose(inertia, inertia.T, rtol=0.0, atol=1e-12 * np.max(np.abs(inertia))) \
            or np.linalg.eigvalsh(inertia)[0] <= 0.0:
        raise ConfigError(f"{PREFIX}.inertia", "inertia must be symmetric positive definite")
    if params.attitude_type not in ATTITUDE_TYPES:
        raise ConfigError(f"{PREFIX}.attitude_type", f"unknown type {params.attitude_type!r}",
                          allowed=ATTITUDE_TYPES)
    need = 4 if params.attitude_type == "quaternion" else 3
    att = np.asarray(params.attitude, dtype=float)
    if att.shape != (need,) or not np.all(np.isfinite(att)):
        raise ConfigError(f"{PREFIX}.attitude",
                          f"expected {need} finite numbers for type {params.attitude_type!r}")
    if need == 4 and np.linalg.norm(att) == 0.0:
        raise ConfigError(f"{PREFIX}.attitude", "quaternion must be nonzero")
    w0 = np.asarray(params.omega0, dtype=float)
    if w0.shape != (3,) or not np.all(np.isfinite(w0)):
        raise ConfigError(f"{PREFIX}.omega0", "expected 3 finite rates (rad/s)")
    for key in ("t_max", "tol", "rtol", "atol", "max_step", "event_spacing",
                "failure_penalty"):
        value = getattr(params, key)
        if not (isinstance(value, Real) and value > 0):
            raise ConfigError(f"{PREFIX}.{key}", f"must be a positive number, got {value!r}")
    if params.u_max is not None and not (isinstance(params.u_max, Real) and params.u_max > 0):
        raise ConfigError(f"{PREFIX}.u_max", "must be null (off) or a positive torque (N·m)")
    if params.objective_form not in OBJECTIVE_FORMS:
        raise ConfigError(f"{PREFIX}.objective_form",
                          f"unknown form {params.objective_form!r}", allowed=OBJECTIVE_FORMS)
    for key in ("n_event_samples", "max_steps"):
        value = getattr(params, key)
        if not (isinstance(value, Integral) and value >= 1):
            raise ConfigError(f"{PREFIX}.{key}", f"must be a positive integer, got {value!r}")
    lo, hi = (float(v) for v in params.eig_bounds)
    if not 0.0 < lo < hi:
        raise ConfigError(f"{PREFIX}.eig_bounds", "need 0 < lower < upper")
    for key, low in (("event_weight_q0", 0.0), ("event_weight_qv", None),
                     ("event_weight_w", None)):
        value = getattr(params, key)
        if not isinstance(value, Real) or not np.isfinite(value) or value < 0 \
                or (low is None and value == 0):
            need = "a number >= 0" if low is not None else "a positive number"
            raise ConfigError(f"{PREFIX}.{key}", f"must be {need}, got {value!r}")
    for key in ("holdout_n", "holdout_n_perturbed", "holdout_seed"):
        value = getattr(params, key)
        if not (isinstance(value, Integral) and value >= 0):
            raise ConfigError(f"{PREFIX}.{key}", f"must be an integer >= 0, got {value!r}")
    for key in ("holdout_perturb_deg", "holdout_rate_rel"):
        value = getattr(params, key)
        if not (isinstance(value, Real) and 0 <= value):
            raise ConfigError(f"{PREFIX}.{key}", f"must be a number >= 0, got {value!r}")
    horizon.check_settings(params, PREFIX)
    criteria.check(params, PREFIX)
    if params.criterion != criteria.DEADLINE and params.objective_form != "cost":
        raise ConfigError(f"{PREFIX}.objective_form", f"criterion {params.criterion} is "
                          "minimized as it is: use objective_form=cost")
    if params.terminal_weight is not None:
        criteria.terminal_matrix(params.terminal_weight, 6, f"{PREFIX}.terminal_weight")
    return params


def build_params(cls: type[Params], case: str, overrides: Mapping[str, Any]) -> Params:
    """Defaults → case entry → ``overrides``, validated.

    Raises
    ------
    ConfigError
        Unknown case or parameter, or an invalid value.
    """
    if case not in CASES:
        raise ConfigError("case", f"unknown case {case!r}", allowed=CASES)
    merged = {**CASE_PARAMS[case], **dict(overrides)}
    if merged.get("criterion", criteria.DEADLINE) != criteria.DEADLINE \
            and "objective_form" not in overrides:
        merged["objective_form"] = "cost"  # a case's companion form belongs to its deadline
    return validate(cls.from_mapping(merged))


__all__ = ["CASES", "CASE_PARAMS", "DEFAULT_CASE", "Params", "VARIANT_IGNORE",
           "build_params", "validate"]
