"""Parameters and the Petropoulos case table of the low-thrust problems (``qlaw``,
``lyapunov_transfer``), and the kernel settings vector common to both laws."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from types import MappingProxyType
from typing import Any, ClassVar

import numpy as np

from penaltyrun.dynamics import lowthrust as lt
from penaltyrun.errors import ConfigError
from penaltyrun.problems.base import ParamsMixin
from penaltyrun.problems.multiscenario import TrainingParams

CASES = ("A", "B", "C", "D", "E", "Estar")
DEFAULT_CASE = "A"
ELEMENTS = ("a", "e", "i", "Omega", "omega")
STATUS_NAMES = lt.STATUS_NAMES
DEG = math.pi / 180.0

_BASE_E = {
    "a0_km": 24505.9, "e0": 0.725, "i0_deg": 0.06, "a_target_km": 26500.0, "e_target": 0.7,
    "i_target_deg": 116.0, "Omega_target_deg": 270.0, "omega_target_deg": 180.0,
    "thrust_newton": 2.0, "m0_kg": 2000.0, "isp_s": 2000.0, "tof_cap_days": 300.0,
    "targeted": ("a", "e", "i", "Omega", "omega"),
}

#: Parameters that do not change a run's result (reports do not split cells by them).
VARIANT_IGNORE = ("sim_max_points", "holdout_n_perturbed", "holdout_seed", "holdout_da_rel",
                  "holdout_de", "holdout_di_deg", "holdout_draan_deg", "holdout_domega_deg",
                  "holdout_dnu_deg", "holdout_control_steps", "holdout_substeps")

CASE_PARAMS: dict[str, dict[str, Any]] = {
    "A": {
        "a0_km": 7000.0, "e0": 0.01, "i0_deg": 0.05, "a_target_km": 42000.0, "e_target": 0.01,
        "thrust_newton": 1.0, "m0_kg": 300.0, "isp_s": 3100.0, "tof_cap_days": 60.0,
        "targeted": ("a", "e"),
    },
    "B": {
        "a0_km": 24505.9, "e0": 0.725, "i0_deg": 7.05, "a_target_km": 42165.0, "e_target": 0.001,
        "i_target_deg": 0.05, "thrust_newton": 0.35, "m0_kg": 2000.0, "isp_s": 2000.0,
        "tof_cap_days": 400.0, "targeted": ("a", "e", "i"),
    },
    "C": {
        "a0_km": 9222.7, "e0": 0.2, "i0_deg": 0.573, "a_target_km": 30000.0, "e_target": 0.7,
        "thrust_newton": 9.3, "m0_kg": 300.0, "isp_s": 3100.0, "tof_cap_days": 10.0,
        "targeted": ("a", "e"),
    },
    # Case D propulsion (2 N, 2000 kg, 2000 s) is not confirmed by any public source: it is an
    # assumption copied from Case E.
    "D": {**_BASE_E, "omega_target_deg": 0.0, "targeted": ("a", "e", "i", "Omega")},
    "E": dict(_BASE_E),
    "Estar": {**_BASE_E, "i0_deg": 30.06, "i_target_deg": 86.0},
}
"""Petropoulos cases (angles in degrees); entries override the dataclass defaults."""


@dataclass(frozen=True)
class LowThrustParams(ParamsMixin, TrainingParams):
    """Parameters shared by both low-thrust laws (units in the names; angles in degrees).

    Attributes
    ----------
    a0_km, e0, i0_deg, Omega0_deg, omega0_deg, nu0_deg : float
        Initial Keplerian elements (km, -, deg); 0 ≤ e0 < 1 and the periapsis a0(1 − e0)
        above the Earth's radius.
    a_target_km, e_target, i_target_deg, Omega_target_deg, omega_target_deg : float
        Target slow elements (only the ``targeted`` ones matter).
    targeted : tuple of str
        Targeted elements, subset of ("a", "e", "i", "Omega", "omega"); defines the selector S.
    thrust_newton, m0_kg, isp_s : float
        Thrust (N), initial mass (kg), specific impulse (s).
    tof_cap_days : float
        Time-of-flight cap, days (status ``tof_cap``).
    max_revs : float
        Revolution cap (status ``rev_cap``).
    mass_floor_kg : float or None
        Mass floor, kg (status ``propellant``); None → 10 % of ``m0_kg``.
    control_step_s : float
        Zero-order-hold control step, s (recorded with every result).
    rk4_substeps : int
        RK4 substeps per control step.
    tol_a_km, tol_e, tol_angle_deg : float
        Convergence tolerances (angle tolerance used for i, Ω and ω).
    selector_sides : int
        2: selector S on both factors of the quadratic form (default); 1: left factor only.
    stall_window_revs : float
        Stall check window in revolutions (0 disables): status ``stall`` when the best Q (or
        V) did not decrease by the relative amount ``stall_rel_decrease`` over a window.
    stall_rel_decrease : float
        Required relative decrease of min Q per window.
    max_steps : int
        Evaluation cap in control steps (status ``stall``).
    impact_radius_km : float
        Periapsis radius below which the transfer fails with status ``impact``.
    law_e_floor, law_i_floor_rad : float
        Floors of e and i inside the law (singular rates and Gauss matrix otherwise).
    fail_weight : float or None
        Weight of the remaining error in the failure penalty; None → the penalty base.
    eig_bounds : tuple of float
        (lower, upper) eigenvalue bounds of K (paper: [0, 100]; 1e-8 keeps K definite).
    sim_max_points : int
        Maximum number of history rows returned by ``simulate``.
    holdout_n_perturbed : int
        Held-out departures: seeded perturbations of the initial orbit (0: none). Each
        element moves by a uniform draw in ± its size: a by ``holdout_da_rel``·a0, e by
        ``holdout_de``, i by ``holdout_di_deg``, Ω by ``holdout_draan_deg``, ω by
        ``holdout_domega_deg``, ν0 by ``holdout_dnu_deg``. An invalid orbit (e outside
        [0, 1), i outside [0°, 180°], periapsis inside the Earth) is a config error.
    holdout_seed : int
        Seed of the perturbations (the same held-out set for every job).
    holdout_control_steps : tuple of float
        The same transfer at these zero-order-hold control steps, s (discretization check).
    holdout_substeps : tuple of int
        The same transfer at the training control step with these RK4 substep counts.
    train_scenarios, train_aggregate
        Multi-scenario tuning (see :mod:`penaltyrun.problems.multiscenario`).
    """

    HOLDOUT_OFF: ClassVar[Mapping[str, Any]] = MappingProxyType(
        {"holdout_n_perturbed": 0, "holdout_control_steps": (), "holdout_substeps": ()})
    a0_km: float = 7000.0
    e0: float = 0.01
    i0_deg: float = 0.05
    Omega0_deg: float = 0.0
    omega0_deg: float = 0.0
    nu0_deg: float = 0.0
    a_target_km: float = 42000.0
    e_target: float = 0.01
    i_target_deg: float = 0.0
    Omega_target_deg: float = 0.0
    omega_target_deg: float = 0.0
    targeted: tuple[str, ...] = ("a", "e")
    thrust_newton: float = 1.0
    m0_kg: float = 300.0
    isp_s: float = 3100.0
    tof_cap_days: float = 60.0
    max_revs: float = 3000.0
    mass_floor_kg: float | None = None
    control_step_s: float = 80.7
    rk4_substeps: int = 1
    tol_a_km: float = 10.0
    tol_e: float = 1e-3
    tol_angle_deg: float = 0.01
    selector_sides: int = 2
    stall_window_revs: float = 25.0
    stall_rel_decrease: float = 1e-4
    max_steps: int = 10_000_000
    impact_radius_km: float = lt.R_E
    law_e_floor: float = 1e-4
    law_i_floor_rad: float = 1e-4
    fail_weight: float | None = None
    eig_bounds: tuple[float, float] = (1e-8, 100.0)
    sim_max_points: int = 20000
    holdout_n_perturbed: int = 8
    holdout_seed: int = 20250422
    holdout_da_rel: float = 0.01
    holdout_de: float = 0.005
    holdout_di_deg: float = 0.04
    holdout_draan_deg: float = 10.0
    holdout_domega_deg: float = 10.0
    holdout_dnu_deg: float = 180.0
    holdout_control_steps: tuple[float, ...] = (40.0, 60.0, 100.0)
    holdout_substeps: tuple[int, ...] = (2,)

    def __post_init__(self) -> None:
        object.__setattr__(self, "targeted", tuple(str(t) for t in self.targeted))
        object.__setattr__(self, "eig_bounds", tuple(float(v) for v in self.eig_bounds))
        object.__setattr__(self, "holdout_control_steps",
                           tuple(float(v) for v in self.holdout_control_steps))
        object.__setattr__(self, "holdout_substeps", tuple(self.holdout_substeps))
        lo, hi = (self.eig_bounds + (0.0, 0.0))[:2]
        if len(self.eig_bounds) != 2 or not 0.0 < lo < hi:
            raise ConfigError("problem.params.eig_bounds", "need [lower, upper], 0 < lower < upper")
        bad = [t for t in self.targeted if t not in ELEMENTS]
        if bad or not self.targeted:
            raise ConfigError("problem.params.targeted", f"invalid elements {bad}", ELEMENTS)
        positive = ("a0_km", "a_target_km", "m0_kg", "isp_s", "tof_cap_days", "max_revs",
                    "control_step_s", "rk4_substeps", "tol_a_km", "tol_e", "tol_angle_deg",
                    "max_steps", "sim_max_points")
        for name in positive:
            if not float(getattr(self, name)) > 0.0:
                raise ConfigError(f"problem.params.{name}", "must be > 0")
        if not 0.0 <= self.e0 < 1.0 or not 0.0 <= self.e_target < 1.0:
            raise ConfigError("problem.params.e0", "eccentricities must be in [0, 1)")
        periapsis = float(self.a0_km) * (1.0 - float(self.e0))
        if periapsis <= lt.R_E:
            raise ConfigError("problem.params.a0_km", f"departure periapsis a0(1 - e0) = "
                              f"{periapsis:.6g} km is inside the Earth (R_E = {lt.R_E:g} km)")
        if self.thrust_newton < 0.0:
            raise ConfigError("problem.params.thrust_newton", "must be >= 0")
        if self.selector_sides not in (1, 2):
            raise ConfigError("problem.params.selector_sides", "must be 1 or 2", ("1", "2"))

    @property
    def mass_floor(self) -> float:
        """Effective mass floor, kg."""
        return 0.1 * self.m0_kg if self.mass_floor_kg is None else float(self.mass_floor_kg)


def build_params(cls: type, case: str, overrides: Mapping[str, Any]) -> Any:
    """Dataclass defaults → ``CASE_PARAMS[case]`` → ``overrides``.

    Raises
    ------
    ConfigError
        Unknown case (key ``case``) or unknown parameter (key ``problem.params.<name>``).
    """
    if case not in CASES:
        raise ConfigError("case", f"unknown low-thrust case {case!r}", allowed=CASES)
    merged = {**CASE_PARAMS[case], **dict(overrides)}
    return cls.from_mapping(merged, prefix="problem.params")


def base_prm(p: LowThrustParams, law: int) -> np.ndarray:
    """Kernel settings vector with the fields common to both laws (law-specific ones zero)."""
    prm = np.zeros(lt.N_PRM)
    prm[lt.I_THRUST] = p.thrust_newton
    prm[lt.I_ISP] = p.isp_s
    prm[lt.I_DT] = p.control_step_s
    prm[lt.I_NSUB] = p.rk4_substeps
    prm[lt.I_TMAX] = p.tof_cap_days * 86400.0
    prm[lt.I_REVMAX] = p.max_revs
    prm[lt.I_MFLOOR] = p.mass_floor
    prm[lt.I_LAW] = law
    prm[lt.I_SIDES] = p.selector_sides
    prm[lt.I_STALLREVS] = p.stall_window_revs
    prm[lt.I_STALLREL] = p.stall_rel_decrease
    prm[lt.I_MAXSTEPS] = p.max_steps
    prm[lt.I_EFLOOR] = p.law_e_floor
    prm[lt.I_IFLOOR] = p.law_i_floor_rad
    prm[lt.I_RIMPACT] = p.impact_radius_km
    prm[lt.I_NGRID] = 36
    return prm


def params_dict(p: LowThrustParams) -> dict[str, Any]:
    """Plain dict of the resolved parameters (for logging/recording)."""
    d = asdict(p)
    d["targeted"] = list(p.targeted)
    d["eig_bounds"] = list(p.eig_bounds)
    return {f.name: d[f.name] for f in fields(p)}


__all__ = ["CASES", "CASE_PARAMS", "DEFAULT_CASE", "DEG", "ELEMENTS", "LowThrustParams",
           "STATUS_NAMES", "VARIANT_IGNORE", "base_prm", "build_params", "params_dict"]
