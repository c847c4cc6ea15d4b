"""Shared pieces of the low-thrust problems (``qlaw`` and ``lyapunov_transfer``).

Holds the Petropoulos case table, the common parameter dataclass, the problem object that
wraps :func:`penaltyrun.dynamics.lowthrust.propagate`, and the plot helpers.

Cost of a candidate
-------------------
Converged: time of flight in days (``min_time``) or propellant used in kg (``min_fuel``).
Not converged (any failure status): a graded penalty

    cost = base + fail_weight · Σ_targeted min(|D_j| / scale_j, 10),

with base = ``tof_cap_days`` (min_time) or ``m0_kg`` (min_fuel), so every failure costs more
than every converged transfer; scale = (a_T, 1, π, π, π) for (a, e, i, Ω, ω) and
``fail_weight`` defaults to ``base``. The cost is always finite.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

from penaltyrun.dynamics import lowthrust as lt
from penaltyrun.errors import ConfigError
from penaltyrun.problems.base import (
    BatchEvaluation,
    MatrixSpec,
    ParamsMixin,
    ScalarSpec,
    check_spd,
    status_names,
)

logger = logging.getLogger(__name__)

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
VARIANT_IGNORE = ("sim_max_points",)

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
class LowThrustParams(ParamsMixin):
    """Parameters shared by both low-thrust laws (units in the names; angles in degrees).

    Attributes
    ----------
    a0_km, e0, i0_deg, Omega0_deg, omega0_deg, nu0_deg : float
        Initial Keplerian elements.
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
    """

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

    def __post_init__(self) -> None:
        object.__setattr__(self, "targeted", tuple(str(t) for t in self.targeted))
        object.__setattr__(self, "eig_bounds", tuple(float(v) for v in self.eig_bounds))
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


class LowThrustProblem:
    """A low-thrust transfer controlled by the Q-law or the generic Lyapunov law.

    Parameters
    ----------
    name : str
        Registry name (``"qlaw"`` or ``"lyapunov_transfer"``).
    case : str
        Case name (one of :data:`CASES`).
    params : LowThrustParams
        Resolved parameters (a subclass carrying the law-specific fields).
    prm : ndarray, shape (lt.N_PRM,)
        Kernel settings vector built by the caller from ``params``.
    objective : str
        ``"min_time"`` or ``"min_fuel"``.
    scalars : tuple of ScalarSpec
        Extra decision variables (``eta_cut`` for the min-fuel Q-law).
    """

    def __init__(
        self,
        name: str,
        case: str,
        params: LowThrustParams,
        prm: np.ndarray,
        objective: str,
        scalars: tuple[ScalarSpec, ...] = (),
    ) -> None:
        self.name = name
        self.case = case
        self.params = params
        self.objective = objective
        self.matrices = (MatrixSpec("K", 5, params.eig_bounds),)
        self.scalars = scalars
        self._prm = np.ascontiguousarray(prm, dtype=float)
        pr = params
        self._oe0 = np.array([pr.a0_km, pr.e0, pr.i0_deg * DEG, pr.Omega0_deg * DEG,
                              pr.omega0_deg * DEG, pr.nu0_deg * DEG])
        self._oeT = np.array([pr.a_target_km, pr.e_target, pr.i_target_deg * DEG,
                              pr.Omega_target_deg * DEG, pr.omega_target_deg * DEG])
        self._sel = np.array([1.0 if el in pr.targeted else 0.0 for el in ELEMENTS])
        tol_ang = pr.tol_angle_deg * DEG
        self._tol = np.array([pr.tol_a_km, pr.tol_e, tol_ang, tol_ang, tol_ang])
        self._scale = np.array([pr.a_target_km, 1.0, math.pi, math.pi, math.pi])
        self._base = pr.tof_cap_days if objective == "min_time" else pr.m0_kg
        self._fail_weight = self._base if pr.fail_weight is None else float(pr.fail_weight)

    # -- helpers -------------------------------------------------------------------------
    def _prm_for(self, scalars: Mapping[str, Any] | None, index: int | None) -> np.ndarray:
        if not self.scalars or not scalars or scalars.get("eta_cut") is None:
            return self._prm
        value = np.asarray(scalars["eta_cut"], dtype=float)
        prm = self._prm.copy()
        prm[lt.I_ETACUT] = float(value if index is None or value.ndim == 0 else value[index])
        return prm

    def _run(self, K: np.ndarray, prm: np.ndarray, hist: np.ndarray, every: int) -> tuple:
        return lt.propagate(self._oe0, self.params.m0_kg, self._oeT, self._sel, self._tol,
                            np.ascontiguousarray(K), prm, hist, every)

    def _cost(self, status: int, t: float, mass: float, y: np.ndarray) -> float:
        if status == lt.ST_CONVERGED:
            return t / 86400.0 if self.objective == "min_time" else self.params.m0_kg - mass
        err = self._errors(y)
        with np.errstate(invalid="ignore"):
            norm = np.where(np.isfinite(err), np.minimum(np.abs(err) / self._scale, 10.0), 10.0)
        return float(self._base + self._fail_weight * float(np.sum(norm * self._sel)))

    def _errors(self, y: np.ndarray) -> np.ndarray:
        oe = np.array(lt.mee2kep(y[0], y[1], y[2], y[3], y[4], y[5]))
        err = np.empty(5)
        lt.element_errors(oe, self._oeT, err)
        return err

    @staticmethod
    def _matrix(mats: Mapping[str, Any], batch: bool) -> np.ndarray:
        if "K" not in mats:
            raise ConfigError("matrices", "missing matrix 'K'", allowed=("K",))
        arr = np.asarray(mats["K"], dtype=float)
        if not batch:
            return check_spd("matrices.K", arr, 5)
        if arr.ndim != 3:
            raise ConfigError("matrices.K", f"expected shape (B, 5, 5), got {arr.shape}")
        return np.stack([check_spd("matrices.K", arr[b], 5) for b in range(arr.shape[0])])

    # -- Problem protocol ----------------------------------------------------------------
    def evaluate_batch(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, np.ndarray] | None = None
    ) -> BatchEvaluation:
        """Evaluate B candidates serially; ``mats["K"]`` has shape (B, 5, 5).

        Returns
        -------
        BatchEvaluation
            Costs (days or kg, graded penalty for failures), convergence flags and statuses.
        """
        Ks = self._matrix(mats, batch=True)
        nb = Ks.shape[0]
        cost = np.empty(nb)
        codes = np.empty(nb, dtype=np.int64)
        empty = np.zeros((0, lt.N_HIST))
        for b in range(nb):
            st, t, y, _, _, _, _ = self._run(Ks[b], self._prm_for(scalars, b), empty, 0)
            codes[b] = st
            cost[b] = self._cost(st, t, y[6], y)
        return BatchEvaluation(cost=cost, converged=codes == lt.ST_CONVERGED,
                               status=status_names(codes, STATUS_NAMES))

    def evaluate(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, float] | None = None
    ) -> dict[str, Any]:
        """Evaluate one candidate in detail (JSON-serializable plain Python values).

        Keys: ``cost``, ``converged``, ``status``, ``t_final`` (s), ``tof_days``,
        ``final_mass_kg``, ``propellant_kg``, ``revolutions``, ``n_steps``, ``final_errors``
        (a_km, e, i_deg, Omega_deg, omega_deg), ``final_elements`` (a_km, e, i_deg,
        Omega_deg, omega_deg, nu_deg in [0, 360)), ``q_final``, ``objective``, ``control_step_s``,
        ``rk4_substeps``, ``eta_cut`` (min-fuel only), ``case``, ``problem``, ``targeted``,
        ``tolerances`` (a_km, e, angle_deg).
        """
        K = self._matrix(mats, batch=False)
        prm = self._prm_for(scalars, None)
        st, t, y, revs, n_steps, _, q = self._run(K, prm, np.zeros((0, lt.N_HIST)), 0)
        return self._summary(st, t, y, revs, n_steps, q, prm)

    def _summary(self, st: int, t: float, y: np.ndarray, revs: float, n_steps: int,
                 q: float, prm: np.ndarray) -> dict[str, Any]:
        oe = lt.mee2kep(y[0], y[1], y[2], y[3], y[4], y[5])
        err = self._errors(y)
        out: dict[str, Any] = {
            "problem": self.name,
            "case": self.case,
            "objective": self.objective,
            "cost": self._cost(st, t, y[6], y),
            "converged": bool(st == lt.ST_CONVERGED),
            "status": STATUS_NAMES[st],
            "t_final": float(t),
            "tof_days": float(t / 86400.0),
            "final_mass_kg": float(y[6]),
            "propellant_kg": float(self.params.m0_kg - y[6]),
            "revolutions": float(revs),
            "n_steps": int(n_steps),
            "q_final": float(q),
            "control_step_s": float(self.params.control_step_s),
            "rk4_substeps": int(self.params.rk4_substeps),
            "targeted": list(self.params.targeted),
            "tolerances": {"a_km": self.params.tol_a_km, "e": self.params.tol_e,
                           "angle_deg": self.params.tol_angle_deg},
            "final_errors": {
                "a_km": float(err[0]), "e": float(err[1]), "i_deg": float(err[2] / DEG),
                "Omega_deg": float(err[3] / DEG), "omega_deg": float(err[4] / DEG),
            },
            "final_elements": {
                "a_km": float(oe[0]), "e": float(oe[1]), "i_deg": float(oe[2] / DEG),
                "Omega_deg": float(oe[3] / DEG), "omega_deg": float(oe[4] / DEG),
                "nu_deg": float(np.mod(oe[5], 2.0 * np.pi) / DEG),
            },
        }
        if self.scalars:
            out["eta_cut"] = float(prm[lt.I_ETACUT])
        return out

    def simulate(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, float] | None = None
    ) -> dict[str, np.ndarray]:
        """Histories of one candidate, at most ``sim_max_points`` rows plus the final state.

        Returns
        -------
        dict of ndarray, each shape (n,)
            ``t`` (s), ``a`` (km), ``e``, ``i``, ``Omega``, ``omega`` (rad), ``mass`` (kg),
            ``thrust_on`` (0/1, control held over the following step), ``x``, ``y``, ``z``
            (km, inertial), ``Q`` (Q or V before the step).
        """
        K = self._matrix(mats, batch=False)
        prm = self._prm_for(scalars, None)
        _, _, _, _, n_steps, _, _ = self._run(K, prm, np.zeros((0, lt.N_HIST)), 0)
        every = max(1, -(-n_steps // self.params.sim_max_points))
        hist = np.zeros((n_steps // every + 2, lt.N_HIST))
        _, _, _, _, _, n_rec, _ = self._run(K, prm, hist, every)
        return {col: hist[:n_rec, j].copy() for j, col in enumerate(lt.HIST_COLS)}


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


# -- plot helpers (matplotlib, Agg-safe; take the dicts returned by ``simulate``) ----------
def _figure_axes(ax: Any, projection: str | None = None, nrows: int = 1) -> tuple[Any, Any]:
    import matplotlib.pyplot as plt

    if ax is not None:
        return ax.figure, ax
    if nrows == 1:
        fig = plt.figure(figsize=(6, 5))
        return fig, fig.add_subplot(111, projection=projection)
    fig, axes = plt.subplots(nrows, 1, figsize=(7, 2.0 * nrows), sharex=True)
    return fig, axes


def _finish(fig: Any, out: Any) -> Any:
    if out is not None:
        import matplotlib.pyplot as plt

        fig.tight_layout()
        fig.savefig(out, dpi=120)
        plt.close(fig)
    return fig


def plot_trajectory(sim: Mapping[str, np.ndarray], out: Any = None, ax: Any = None,
                    title: str = "") -> Any:
    """3-D trajectory (km) with Earth's radius marked; thrust arcs solid, coast arcs grey.

    Parameters
    ----------
    sim : mapping
        Output of ``simulate`` (``x``, ``y``, ``z``, ``thrust_on``).
    out : path-like, optional
        Save the figure there and close it.
    ax : matplotlib 3-D Axes, optional
        Draw into this Axes instead of a new figure.
    """
    fig, ax = _figure_axes(ax, projection="3d")
    x, y, z = sim["x"], sim["y"], sim["z"]
    on = np.asarray(sim["thrust_on"]) > 0.5
    ax.plot(x, y, z, color="0.7", lw=0.4)
    ax.plot(np.where(on, x, np.nan), np.where(on, y, np.nan), np.where(on, z, np.nan),
            color="C3", lw=0.5)
    u = np.linspace(0.0, 2.0 * np.pi, 60)
    ax.plot(lt.R_E * np.cos(u), lt.R_E * np.sin(u), 0.0 * u, color="C0")
    lim = float(np.nanmax(np.abs(np.concatenate([x, y, z])))) if len(x) else lt.R_E
    for setter in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
        setter(-lim, lim)
    ax.set_xlabel("x [km]")
    ax.set_ylabel("y [km]")
    ax.set_zlabel("z [km]")
    ax.set_title(title)
    return _finish(fig, out)


#: Histories plotted unwrapped (rad in ``simulate`` output).
ANGLE_KEYS = ("Omega", "omega")


def plot_elements(sims: Mapping[str, Mapping[str, np.ndarray]], out: Any = None,
                  axes: Any = None) -> Any:
    """Element histories (a, e, i, Ω, ω, mass vs days) of labelled runs, e.g. diagonal vs full.

    Ω and ω are unwrapped (continuous through ±180°), so an angle settling at 180° does not
    draw a wall of jumps between −180° and 180°.

    Parameters
    ----------
    sims : mapping of label → simulate dict
        For example ``{"diagonal": sim_d, "full": sim_f}``.
    out : path-like, optional
        Save the figure there and close it.
    axes : sequence of 6 Axes, optional
    """
    fig, axes = _figure_axes(axes, nrows=6)
    rows = (("a", "a [km]", 1.0), ("e", "e [-]", 1.0), ("i", "i [deg]", 1.0 / DEG),
            ("Omega", "Ω [deg, unwrapped]", 1.0 / DEG), ("omega", "ω [deg, unwrapped]", 1.0 / DEG),
            ("mass", "m [kg]", 1.0))
    for label, sim in sims.items():
        days = np.asarray(sim["t"]) / 86400.0
        for ax, (key, _, fac) in zip(axes, rows, strict=True):
            values = np.asarray(sim[key], float)
            if key in ANGLE_KEYS:
                values = np.unwrap(values)
            ax.plot(days, values * fac, lw=0.8, label=label)
    for ax, (_, ylabel, _) in zip(axes, rows, strict=True):
        ax.set_ylabel(ylabel)
    axes[0].legend(loc="best", fontsize="small")
    axes[-1].set_xlabel("time [days]")
    return _finish(fig, out)


def plot_thrust(sim: Mapping[str, np.ndarray], out: Any = None, ax: Any = None,
                title: str = "") -> Any:
    """Thrust/coast pattern (on = 1) versus time in days, with the mass on a twin axis."""
    fig, ax = _figure_axes(ax)
    days = np.asarray(sim["t"]) / 86400.0
    ax.fill_between(days, 0.0, np.asarray(sim["thrust_on"]), step="post", color="C3",
                    alpha=0.5, lw=0.0)
    ax.set_ylim(-0.05, 1.05)
    ax.set_ylabel("thrust on")
    ax.set_xlabel("time [days]")
    twin = ax.twinx()
    twin.plot(days, sim["mass"], color="C0", lw=1.0)
    twin.set_ylabel("mass [kg]")
    ax.set_title(title)
    return _finish(fig, out)
