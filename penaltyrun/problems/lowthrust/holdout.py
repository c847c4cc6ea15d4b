"""Held-out scenarios of the low-thrust problems: seeded perturbations of the departure
orbit and the same transfer at other control-hold steps and RK4 substep counts.

The training scenario is the case's departure orbit at ``control_step_s`` with
``rk4_substeps``; every held-out scenario differs from it (a perturbed departure, or another
discretization), and a settings combination that would repeat it is a config error, as is a
perturbation that makes an invalid departure orbit.
"""

from __future__ import annotations

from dataclasses import dataclass
from numbers import Integral

import numpy as np

from penaltyrun.dynamics import lowthrust as lt
from penaltyrun.errors import ConfigError
from penaltyrun.problems.lowthrust.params import DEG, LowThrustParams

#: Scenario kinds, in the order they are listed.
KINDS = ("departure", "control_step", "substeps")


@dataclass(frozen=True)
class Scenario:
    """One held-out transfer.

    Attributes
    ----------
    label : str
        Unique name, e.g. ``departure:3``, ``step=40s``, ``substeps=2``.
    kind : str
        One of :data:`KINDS`.
    oe0 : tuple of float
        Departure (a km, e, i rad, Ω rad, ω rad, ν0 rad).
    control_step_s : float
        Zero-order-hold control step (s).
    rk4_substeps : int
        RK4 substeps per control step.
    """

    label: str
    kind: str
    oe0: tuple[float, ...]
    control_step_s: float
    rk4_substeps: int


def key(oe0: tuple, control_step_s: float, rk4_substeps: int) -> tuple:
    """Hashable key of a transfer set-up (elements rounded to 1e-9), for overlap checks."""
    return tuple(np.round(np.asarray(oe0, float), 9).tolist()) + (float(control_step_s),
                                                                 int(rk4_substeps))


def initial_elements(p: LowThrustParams) -> np.ndarray:
    """Departure (a km, e, i, Ω, ω, ν0 in rad) of the parameters, shape (6,)."""
    return np.array([p.a0_km, p.e0, p.i0_deg * DEG, p.Omega0_deg * DEG, p.omega0_deg * DEG,
                     p.nu0_deg * DEG])


def _check_orbit(k: int, oe: np.ndarray, p: LowThrustParams) -> None:
    a, e, i = oe[0], oe[1], oe[2]
    if not 0.0 <= e < 1.0:
        raise ConfigError("problem.params.holdout_de", f"perturbed departure {k} has e = "
                          f"{e:.6g}: not an ellipse (need 0 <= e < 1); reduce holdout_de")
    if not 0.0 <= i <= np.pi:
        raise ConfigError("problem.params.holdout_di_deg", f"perturbed departure {k} has "
                          f"i = {i / DEG:.6g} deg (need 0 <= i <= 180); reduce holdout_di_deg")
    if not a > 0.0 or a * (1.0 - e) <= lt.R_E:
        raise ConfigError("problem.params.holdout_da_rel", f"perturbed departure {k} has "
                          f"periapsis a(1 - e) = {a * (1.0 - e):.6g} km inside the Earth "
                          f"(R_E = {lt.R_E:g} km); reduce holdout_da_rel or holdout_de")


def departures(p: LowThrustParams) -> list[Scenario]:
    """``holdout_n_perturbed`` seeded perturbations of the departure orbit.

    Raises
    ------
    ConfigError
        Negative sizes or a perturbed orbit that is not a valid departure.
    """
    sizes = {"holdout_da_rel": p.holdout_da_rel, "holdout_de": p.holdout_de,
             "holdout_di_deg": p.holdout_di_deg, "holdout_draan_deg": p.holdout_draan_deg,
             "holdout_domega_deg": p.holdout_domega_deg, "holdout_dnu_deg": p.holdout_dnu_deg}
    for key, value in sizes.items():
        if not (np.isfinite(value) and value >= 0.0):
            raise ConfigError(f"problem.params.{key}", f"must be a number >= 0, got {value!r}")
    n = p.holdout_n_perturbed
    if not (isinstance(n, Integral) and n >= 0):
        raise ConfigError("problem.params.holdout_n_perturbed",
                          f"must be an integer >= 0, got {n!r}")
    rng = np.random.default_rng(int(p.holdout_seed))
    half = np.array([p.holdout_da_rel * p.a0_km, p.holdout_de, p.holdout_di_deg * DEG,
                     p.holdout_draan_deg * DEG, p.holdout_domega_deg * DEG,
                     p.holdout_dnu_deg * DEG])
    base = initial_elements(p)
    out = []
    for k in range(n):
        oe = base + half * rng.uniform(-1.0, 1.0, size=6)
        _check_orbit(k, oe, p)
        out.append(Scenario(f"departure:{k}", "departure", tuple(float(v) for v in oe),
                            float(p.control_step_s), int(p.rk4_substeps)))
    return out


def discretizations(p: LowThrustParams) -> list[Scenario]:
    """The training departure at the other control steps and substep counts.

    Raises
    ------
    ConfigError
        A non-positive step or substep count, or one that repeats the training set-up.
    """
    base = tuple(float(v) for v in initial_elements(p))
    out = []
    for dt in p.holdout_control_steps:
        if not (np.isfinite(dt) and dt > 0.0):
            raise ConfigError("problem.params.holdout_control_steps",
                              f"steps must be positive seconds, got {dt!r}")
        if dt == float(p.control_step_s):
            raise ConfigError("problem.params.holdout_control_steps",
                              f"{dt:g} s is the training control step (control_step_s); "
                              "held-out scenarios must differ from training")
        out.append(Scenario(f"step={dt:g}s", "control_step", base, float(dt),
                            int(p.rk4_substeps)))
    for ns in p.holdout_substeps:
        if not (isinstance(ns, Integral) and ns >= 1):
            raise ConfigError("problem.params.holdout_substeps",
                              f"substep counts must be positive integers, got {ns!r}")
        if int(ns) == int(p.rk4_substeps):
            raise ConfigError("problem.params.holdout_substeps",
                              f"{ns} is the training substep count (rk4_substeps); "
                              "held-out scenarios must differ from training")
        out.append(Scenario(f"substeps={ns}", "substeps", base, float(p.control_step_s),
                            int(ns)))
    return out


def scenarios(p: LowThrustParams) -> list[Scenario]:
    """The whole held-out set: departures, then discretizations (validated)."""
    out = departures(p) + discretizations(p)
    labels = [s.label for s in out]
    if len(set(labels)) != len(labels):
        dup = next(lab for lab in labels if labels.count(lab) > 1)
        raise ConfigError("problem.params.holdout_control_steps" if dup.startswith("step")
                          else "problem.params.holdout_substeps", f"{dup} listed twice")
    return out


__all__ = ["KINDS", "Scenario", "departures", "discretizations", "initial_elements", "key",
           "scenarios"]
