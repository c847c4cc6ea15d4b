"""Shared pieces of the low-thrust problems (``qlaw`` and ``lyapunov_transfer``).

Holds the problem object that wraps :func:`penaltyrun.dynamics.lowthrust.propagate` and
re-exports the pieces it is built from: the case table and parameters
(:mod:`~penaltyrun.problems.lowthrust.params`), the held-out scenarios
(:mod:`~penaltyrun.problems.lowthrust.holdout`) and the plots
(:mod:`~penaltyrun.problems.lowthrust.plots`).

Cost of a candidate
-------------------
Converged: time of flight in days (``min_time``) or propellant used in kg (``min_fuel``).
Not converged (any failure status): a graded penalty

    cost = base + fail_weight · Σ_targeted min(|D_j| / scale_j, 10),

with base = ``tof_cap_days`` (min_time) or ``m0_kg`` (min_fuel), so every failure costs more
than every converged transfer; scale = (a_T, 1, π, π, π) for (a, e, i, Ω, ω) and
``fail_weight`` defaults to ``base``. The cost is always finite.

Exact cutoff (``evaluate_batch(..., thresholds=...)``): a candidate stops as soon as its
elapsed time (min_time, days) or propellant used (min_fuel, kg) exceeds its threshold, with
status ``cutoff`` and that accumulated cost as its value, a bound above the threshold and never
above the uncut cost (see :mod:`penaltyrun.dynamics.lowthrust.loop`; the failure base is the
kernel's cap). Off when ``fail_weight`` < 0 (failures could then cost less than the base).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from penaltyrun.dynamics import lowthrust as lt
from penaltyrun.errors import ConfigError
from penaltyrun.problems.base import (
    BatchEvaluation,
    MatrixSpec,
    ScalarSpec,
    check_spd,
    status_names,
)
from penaltyrun.problems.lowthrust import holdout as holdout_set
from penaltyrun.problems.lowthrust.params import (
    CASE_PARAMS,
    CASES,
    DEFAULT_CASE,
    DEG,
    ELEMENTS,
    STATUS_NAMES,
    VARIANT_IGNORE,
    LowThrustParams,
    base_prm,
    build_params,
    params_dict,
)
from penaltyrun.problems.lowthrust.plots import (
    ANGLE_KEYS,
    plot_elements,
    plot_thrust,
    plot_trajectory,
)

logger = logging.getLogger(__name__)


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
    no_gradient : str
        Why the law's cost has no gradient (``no_gradient`` of
        :func:`~penaltyrun.problems.base.gradient_support`); empty: not stated.
    """

    def __init__(
        self,
        name: str,
        case: str,
        params: LowThrustParams,
        prm: np.ndarray,
        objective: str,
        scalars: tuple[ScalarSpec, ...] = (),
        no_gradient: str = "",
    ) -> None:
        self.name = name
        self.no_gradient = no_gradient
        self.case = case
        self.params = params
        self.objective = objective
        self.matrices = (MatrixSpec("K", 5, params.eig_bounds),)
        self.scalars = scalars
        self._prm = np.ascontiguousarray(prm, dtype=float)
        pr = params
        self._oe0 = holdout_set.initial_elements(pr)
        self._holdout = holdout_set.scenarios(pr)
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

    def _run(self, K: np.ndarray, prm: np.ndarray, hist: np.ndarray, every: int,
             oe0: np.ndarray | None = None) -> tuple:
        return lt.propagate(self._oe0 if oe0 is None else oe0, self.params.m0_kg, self._oeT,
                            self._sel, self._tol, np.ascontiguousarray(K), prm, hist, every)

    def _cost(self, status: int, t: float, mass: float, y: np.ndarray) -> float:
        if status == lt.ST_CONVERGED or status == lt.ST_CUTOFF:
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

    def _with_cutoff(self, prm: np.ndarray, threshold: float) -> np.ndarray:
        """``prm`` with the exact cutoff at ``threshold`` (unchanged when it cannot cut)."""
        if not threshold < self._base or self._fail_weight < 0.0:  # also NaN
            return prm
        prm = prm.copy()
        prm[lt.I_CUTKIND] = lt.CUT_TIME if self.objective == "min_time" else lt.CUT_PROPELLANT
        prm[lt.I_CUTOFF] = threshold
        prm[lt.I_CUTCAP] = self._base
        return prm

    # -- Problem protocol ----------------------------------------------------------------
    def evaluate_batch(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, np.ndarray] | None = None,
        thresholds: np.ndarray | None = None,
    ) -> BatchEvaluation:
        """Evaluate B candidates serially; ``mats["K"]`` has shape (B, 5, 5).

        Parameters
        ----------
        mats, scalars
            Candidates (``K`` of shape (B, 5, 5); ``eta_cut`` of shape (B,) in min-fuel).
        thresholds : ndarray, shape (B,), optional
            Exact cutoff per candidate (days or kg; ``inf``: none): a candidate whose
            accumulated cost exceeds it stops early with status ``cutoff`` and a cost above
            its threshold (see the module docstring).

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
        cut = None if thresholds is None else np.asarray(thresholds, dtype=float).reshape(nb)
        for b in range(nb):
            prm = self._prm_for(scalars, b)
            if cut is not None:
                prm = self._with_cutoff(prm, float(cut[b]))
            st, t, y, _, _, _, _ = self._run(Ks[b], prm, empty, 0)
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

    def training_scenario(self) -> dict[str, Any]:
        """The scenario K is tuned on: the case's departure and discretization."""
        return {"scenario": self.case, "oe0": self._oe0.tolist(),
                "control_step_s": float(self.params.control_step_s),
                "rk4_substeps": int(self.params.rk4_substeps)}

    def scenario_key(self) -> tuple:
        """Hashable key of the training scenario: departure (rounded) and discretization."""
        return holdout_set.key(tuple(self._oe0), float(self.params.control_step_s),
                               int(self.params.rk4_substeps))

    def sample_training(self, n: int, seed: int) -> list[dict[str, Any]]:
        """``n`` seeded training departures, drawn as the held-out ones but with ``seed``.

        Returns
        -------
        list of dict
            Overrides of (a0_km, e0, i0_deg, Omega0_deg, omega0_deg, nu0_deg).
        """
        from dataclasses import replace

        try:
            drawn = holdout_set.departures(replace(self.params, holdout_n_perturbed=int(n),
                                                   holdout_seed=int(seed)))
        except ConfigError as err:
            raise ConfigError("problem.params.train_sample", "a seeded training departure "
                              f"(drawn with the holdout_* sizes) is invalid: {err}") from None
        names = ("a0_km", "e0", "i0_deg", "Omega0_deg", "omega0_deg", "nu0_deg")
        return [{name: (v if k < 2 else v / DEG) for k, (name, v) in
                 enumerate(zip(names, sc.oe0))} for sc in drawn]

    def holdout_keys(self) -> set[tuple]:
        """Keys (as :meth:`scenario_key`) of the held-out scenarios."""
        return {holdout_set.key(s.oe0, s.control_step_s, s.rk4_substeps)
                for s in self._holdout}

    def holdout_scenarios(self) -> list[holdout_set.Scenario]:
        """The held-out set (see :mod:`penaltyrun.problems.lowthrust.holdout`)."""
        return list(self._holdout)

    def holdout(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None
                ) -> dict[str, Any] | None:
        """Evaluate one candidate on every held-out scenario (runner hook).

        Cost: about one evaluation per scenario (``holdout_n_perturbed`` departures plus
        ``len(holdout_control_steps) + len(holdout_substeps)`` discretizations; a 40 s step
        costs twice an 80.7 s one).

        Returns
        -------
        dict or None
            Per scenario (lists): ``scenario``, ``kind``, ``control_step_s``,
            ``rk4_substeps``, ``cost``, ``converged``, ``status``, ``tof_days``,
            ``propellant_kg``, ``revolutions``; plus the training run's ``training``
            summary (cost, converged, status, tof_days, propellant_kg); ``arrival_time`` (s,
            None if not converged), ``converged_by_deadline`` (= ``converged``) and
            ``horizon`` = ``training_horizon`` = the time-of-flight cap (s): the transfers
            are free-final-time, ending on arrival or at the training caps
            (``tof_cap_days``, ``max_revs``), so there is no earlier deadline to lift.
            ``None`` when the set is empty.
        """
        if not self._holdout:
            return None
        K = self._matrix(mats, batch=False)
        prm0 = self._prm_for(scalars, None)
        empty = np.zeros((0, lt.N_HIST))
        keys = ("scenario", "kind", "control_step_s", "rk4_substeps", "cost", "converged",
                "status", "tof_days", "propellant_kg", "revolutions")
        out: dict[str, Any] = {k: [] for k in keys}
        for sc in self._holdout:
            prm = prm0.copy()
            prm[lt.I_DT] = sc.control_step_s
            prm[lt.I_NSUB] = sc.rk4_substeps
            st, t, y, revs, _, _, _ = self._run(K, prm, empty, 0, np.asarray(sc.oe0))
            row = (sc.label, sc.kind, sc.control_step_s, sc.rk4_substeps,
                   self._cost(st, t, y[6], y), bool(st == lt.ST_CONVERGED), STATUS_NAMES[st],
                   float(t / 86400.0), float(self.params.m0_kg - y[6]), float(revs))
            for key, value in zip(keys, row):
                out[key].append(value)
        st, t, y, revs, _, _, _ = self._run(K, prm0, empty, 0)
        out["training"] = {"scenario": self.case, "cost": self._cost(st, t, y[6], y),
                           "converged": bool(st == lt.ST_CONVERGED), "status": STATUS_NAMES[st],
                           "tof_days": float(t / 86400.0),
                           "propellant_kg": float(self.params.m0_kg - y[6]),
                           "control_step_s": float(self.params.control_step_s),
                           "rk4_substeps": int(self.params.rk4_substeps)}
        # free final time: a held-out transfer ends on arrival or at the training caps, so
        # its horizon is the training one and "by the deadline" is "converged"
        conv = np.asarray(out["converged"], dtype=bool)
        cap_s = float(self.params.tof_cap_days) * 86400.0
        out["arrival_time"] = [float(t) * 86400.0 if c else None
                               for t, c in zip(out["tof_days"], conv)]
        out["converged_by_deadline"] = conv.tolist()
        out["horizon"] = out["training_horizon"] = cap_s
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


__all__ = [
    "ANGLE_KEYS",
    "CASES",
    "CASE_PARAMS",
    "DEFAULT_CASE",
    "DEG",
    "ELEMENTS",
    "STATUS_NAMES",
    "VARIANT_IGNORE",
    "LowThrustParams",
    "LowThrustProblem",
    "base_prm",
    "build_params",
    "params_dict",
    "plot_elements",
    "plot_thrust",
    "plot_trajectory",
]
