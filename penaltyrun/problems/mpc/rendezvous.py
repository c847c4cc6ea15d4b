"""Beyond the paper: tuning the weights of a linear MPC for spacecraft rendezvous.

Plant and prediction model: the Clohessy–Wiltshire equations discretized exactly with a
zero-order hold (:mod:`~penaltyrun.problems.mpc.model`). Controller: at every sample, the
condensed QP of horizon N with stage weights (Q, R), terminal weight P from the discrete
Riccati equation of (A_d, B_d, Q, R) and the box |u_j| ≤ u_max, solved by DAQP
(:mod:`~penaltyrun.problems.mpc.controller`); u_0 is applied. Tuned: Q (6×6) and R (3×3),
acting on the state and input divided by ``state_scale`` and ``input_scale``.

Cost of a candidate (m/s, always finite), with the normalized error
e(s) = max(‖r‖ / pos_tol_m, ‖v‖ / vel_tol_m_s) (converged ⇔ e ≤ 1):

* converged by t_max (status ``converged``): Δv = Σ_k Tₛ ‖u_k‖₂ up to convergence;
* not converged (``horizon``): Δv + failure_penalty · (1 + e(s_T) / e(s_0));
* no stabilizing Riccati solution (``dare_failure``), a QP the solver could not solve
  (``qp_failure``) or a non-finite state (``nonfinite``): 10 · failure_penalty;
* exact cutoff (``evaluate_batch(..., thresholds=...)``, status ``cutoff``): the run stops
  after the first step where Δv exceeds its threshold by the relative margin
  :data:`CUT_MARGIN`, costing that Δv; Δv never decreases and every other outcome costs at
  least Δv, so the bound is exact.

That is the paper-style criterion (``criterion: deadline``, the default); the well-posed
criteria ``time_energy`` and ``terminal`` (control energy Σ ½‖u_k‖² Tₛ plus the price of
time, or plus a terminal penalty) are in :mod:`~penaltyrun.problems.mpc.criteria`.

The MPC is invariant to a common scaling of Q and R (P scales with them).

Gradient (``gradient`` hook): exact where every step's QP keeps its active set and the
arrival step is fixed (:mod:`~penaltyrun.problems.mpc.gradient`); elsewhere the reason.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.problems import criteria, gradient_costs, horizon
from penaltyrun.problems.base import (
    BatchEvaluation,
    ClosedLoop,
    CostGradient,
    GradientCost,
    MatrixSpec,
    ScalarSpec,
    check_spd,
)
from penaltyrun.problems.basins import BasinAxes, arrival_times
from penaltyrun.problems.mpc import controller as ctl
from penaltyrun.problems.mpc import criteria as mpc_criteria
from penaltyrun.problems.mpc import scenarios as scen
from penaltyrun.problems.mpc.criteria import report_info
from penaltyrun.problems.mpc.model import cw_continuous, mean_motion, solve_dare_batch, zoh
from penaltyrun.problems.mpc.params import (
    CASE_PARAMS,
    CASES,
    DEFAULT_CASE,
    VARIANT_IGNORE,
    Params,
    build_params,
)
from penaltyrun.problems.mpc.plots import plot_inputs, plot_trajectory

logger = logging.getLogger(__name__)

NAME = "mpc_rendezvous"
DARE_FAILURE = "dare_failure"
#: Cost multiple of ``failure_penalty`` of candidates without a controller or a finite run.
HARD_FAILURE_FACTOR = 10.0
#: Relative margin by which Δv must exceed a threshold before a run is cut.
CUT_MARGIN = 1e-9
COST_UNIT = "m/s"
#: Label of a converged start's cost (axis labels, tables).
COST_LABEL = "Δv = Σ Tₛ‖u_k‖₂ (m/s)"
#: Names of the relative state (m, m/s) and input (m/s²) channels.
STATE_NAMES = ("x", "y", "z", "vx", "vy", "vz")
INPUT_NAMES = ("ux", "uy", "uz")


class RendezvousMPC:
    """The rendezvous MPC closed loop with tuned weights ``Q`` (6×6) and ``R`` (3×3)."""

    name = NAME

    def __init__(self, case: str, params: Params) -> None:
        self.case = case
        self.params = params
        p = params
        self.matrices = (MatrixSpec("Q", 6, tuple(float(b) for b in p.q_eig_bounds)),
                         MatrixSpec("R", 3, tuple(float(b) for b in p.r_eig_bounds)))
        self.scalars: tuple[ScalarSpec, ...] = ()
        self.n = mean_motion(p.orbit_radius_km * 1e3, p.mu_km3_s2 * 1e9)
        self.A, self.B = cw_continuous(self.n)
        self.Ad, self.Bd = zoh(self.A, self.B, float(p.sample_time_s))
        self.Phi, self.Gam = ctl.prediction_matrices(self.Ad, self.Bd, int(p.horizon))
        self.u_max = np.full(3, float(p.u_max))
        self.state_weight_scale = 1.0 / np.asarray(p.state_scale, dtype=float)
        self.input_weight_scale = 1.0 / np.asarray(p.input_scale, dtype=float)

    # --- controller ---------------------------------------------------------------------

    def physical_weights(self, Q: Any, R: Any) -> tuple[np.ndarray, np.ndarray]:
        """Weights on the state and input in SI units, diag(1/σ) K diag(1/σ), batched."""
        ds, du = self.state_weight_scale, self.input_weight_scale
        Q = np.asarray(Q, dtype=float) * ds[:, None] * ds[None, :]
        R = np.asarray(R, dtype=float) * du[:, None] * du[None, :]
        return Q, R

    def controllers(self, Q: Any, R: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                      np.ndarray]:
        """Scaled QP data of a batch of tuned weights.

        Returns
        -------
        H : ndarray, shape (B, 3N, 3N)
        F : ndarray, shape (B, 3N, 6)
        P : ndarray, shape (B, 6, 6)
            Terminal weights (SI units; zero where ``ok`` is False).
        ok : ndarray of bool, shape (B,)
            Whether the Riccati equation has a stabilizing solution.
        """
        Qp, Rp = self.physical_weights(Q, R)
        P, ok = solve_dare_batch(self.Ad, self.Bd, Qp, Rp)
        Qp = np.where(ok[:, None, None], Qp, np.eye(6))
        Rp = np.where(ok[:, None, None], Rp, np.eye(3))
        Pq = np.where(ok[:, None, None], P, np.eye(6))
        H, F = ctl.qp_matrices(self.Phi, self.Gam, Qp, Rp, Pq, self.u_max)
        return H, F, P, ok

    def plant_for(self, sc: scen.Scenario) -> Any:
        """The simulated plant of a scenario."""
        p = self.params
        if sc.plant == "keplerian":
            return ctl.KeplerianPlant(p.orbit_radius_km * 1e3, sc.eccentricity,
                                      math.radians(p.plant_true_anomaly_deg),
                                      p.mu_km3_s2 * 1e9, p.sample_time_s, p.plant_substeps,
                                      sc.thrust_scale)
        return ctl.LinearPlant(self.Ad, self.Bd, sc.thrust_scale)

    def run(self, H: np.ndarray, F: np.ndarray, sc: scen.Scenario | None = None,
            cutoff: float = math.inf, record: bool = False) -> ctl.LoopResult:
        """Closed loop of one controller (H (3N, 3N), F (3N, 6)) in scenario ``sc``
        (default: the training scenario)."""
        p = self.params
        sc = sc or scen.training(p)
        res = ctl.closed_loop(H, F, self.plant_for(sc), np.asarray(sc.s0, dtype=float),
                              mpc_criteria.run_steps(p), float(p.sample_time_s), self.u_max,
                              mpc_criteria.position_tolerance(p), float(p.vel_tol_m_s),
                              p.daqp_settings(), cutoff, record)
        if p.criterion == criteria.TERMINAL and res.status == ctl.HORIZON:
            res = replace(res, status=ctl.CONVERGED)  # no target event: T reached is done
        return res

    def error(self, s: Any) -> float:
        """Normalized error e(s) = max(‖r‖ / pos_tol_m, ‖v‖ / vel_tol_m_s)."""
        s = np.asarray(s, dtype=float)
        return max(float(np.linalg.norm(s[:3])) / self.params.pos_tol_m,
                   float(np.linalg.norm(s[3:])) / self.params.vel_tol_m_s)

    def graded(self, res: ctl.LoopResult, s0: Any) -> float:
        """Cost of one run (see the module docstring)."""
        fp = float(self.params.failure_penalty)
        value = mpc_criteria.value(res, self.params, float(self.params.sample_time_s))
        if res.status in (ctl.CONVERGED, ctl.CUTOFF):
            return value
        if res.status == ctl.HORIZON:
            e0 = max(self.error(s0), 1.0)
            cost = value + fp * (1.0 + self.error(res.final_state) / e0)
            if math.isfinite(cost):
                return float(cost)
        return HARD_FAILURE_FACTOR * fp

    # --- protocol -----------------------------------------------------------------------

    def evaluate_batch(self, mats: Mapping[str, np.ndarray],
                       scalars: Mapping[str, np.ndarray] | None = None,
                       thresholds: np.ndarray | None = None) -> BatchEvaluation:
        """Costs of B candidates; ``mats["Q"]`` (B, 6, 6), ``mats["R"]`` (B, 3, 3).

        ``thresholds`` (shape (B,), optional): exact cutoff per candidate (m/s, ``inf``:
        none); see the module docstring.
        """
        H, F, _, ok = self.controllers(mats["Q"], mats["R"])
        nb = H.shape[0]
        hard = HARD_FAILURE_FACTOR * float(self.params.failure_penalty)
        cut = np.full(nb, math.inf)
        if thresholds is not None and self.params.criterion == criteria.DEADLINE:
            thr = np.asarray(thresholds, dtype=float).reshape(nb)
            allowed = thr < hard   # NaN: False
            cut = np.where(allowed, thr + CUT_MARGIN * np.abs(thr), math.inf)
        cost = np.full(nb, hard)
        status = np.full(nb, DARE_FAILURE, dtype=object)
        sc = scen.training(self.params)
        for b in np.flatnonzero(ok):
            res = self.run(H[b], F[b], sc, float(cut[b]))
            cost[b] = self.graded(res, sc.s0)
            status[b] = res.status
        return BatchEvaluation(cost=cost, converged=status == ctl.CONVERGED, status=status)

    def _check(self, mats: Mapping[str, Any]) -> dict[str, np.ndarray]:
        out = {}
        for spec in self.matrices:
            if spec.name not in mats or mats[spec.name] is None:
                raise ConfigError(f"matrices.{spec.name}", "missing matrix")
            out[spec.name] = check_spd(f"matrices.{spec.name}", mats[spec.name], spec.size)
        return out

    def controller(self, mats: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray,
                                                           np.ndarray, bool]:
        """Validated QP data (H, F), terminal weight P and Riccati success of one candidate.

        Raises
        ------
        ConfigError
            Malformed matrices.
        """
        m = self._check(mats)
        H, F, P, ok = self.controllers(m["Q"][None], m["R"][None])
        return H[0], F[0], P[0], bool(ok[0])

    def gradient(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None
                 ) -> CostGradient:
        """Cost of one (Q, R) and its exact gradient where every step's QP keeps its active
        set (:mod:`~penaltyrun.problems.mpc.gradient`), or the reason there is none."""
        from penaltyrun.problems.mpc.gradient import mpc_gradient

        m = self._check(mats)
        return mpc_gradient(self, m["Q"], m["R"])

    def gradient_cost(self) -> GradientCost:
        """What one gradient costs in evaluations under this criterion: measured by
        ``bench/gradient_cost_zermelo_mpc.py``, table in ``bench/README.md``
        (:func:`~penaltyrun.problems.gradient_costs.mpc_cost`)."""
        return gradient_costs.mpc_cost(self.params.criterion)

    def _summary(self, res: ctl.LoopResult | None, sc: scen.Scenario) -> dict[str, Any]:
        p = self.params
        if res is None:
            return {"cost": HARD_FAILURE_FACTOR * float(p.failure_penalty),
                    "delta_v": math.nan, "converged": False, "status": DARE_FAILURE,
                    "t_final": math.nan, "final_distance": math.nan,
                    "final_speed": math.nan, "qp_iterations": 0}
        return {"cost": self.graded(res, sc.s0), "delta_v": float(res.delta_v),
                "converged": res.status == ctl.CONVERGED, "status": res.status,
                "t_final": float(res.steps * p.sample_time_s),
                "final_distance": float(np.linalg.norm(res.final_state[:3])),
                "final_speed": float(np.linalg.norm(res.final_state[3:])),
                "qp_iterations": int(res.qp_iterations)}

    def evaluate(self, mats: Mapping[str, Any],
                 scalars: Mapping[str, float] | None = None) -> dict[str, Any]:
        """Detailed evaluation of one candidate; JSON-serializable.

        Returns
        -------
        dict
            ``problem``, ``case``, ``cost`` (m/s), ``delta_v`` (m/s), ``converged``,
            ``status``, ``t_final`` (s), ``t_max`` (s), ``final_distance`` (m),
            ``final_speed`` (m/s), ``qp_iterations``, ``cost_unit``, ``mpc_terminal_P``
            (the MPC's own terminal cost P, the DARE solution, 6×6 nested list, SI units;
            not the criterion's S). Under a well-posed criterion also
            ``criterion``, ``horizon`` (s), ``energy`` (m²/s³), and ``rho`` with
            ``arrival_time`` (s) or ``terminal_S`` (S) with ``terminal_cost``; the cost
            unit is then m²/s³.
        """
        H, F, P, ok = self.controller(mats)
        sc = scen.training(self.params)
        out = {"problem": self.name, "case": self.case}
        res = self.run(H, F, sc) if ok else None
        out.update(self._summary(res, sc))
        out.update({"t_max": float(self.params.t_max), "cost_unit": COST_UNIT,
                    "mpc_terminal_P": P.tolist()})
        p = self.params
        if p.criterion != criteria.DEADLINE:
            out.update({"criterion": p.criterion, "cost_unit": mpc_criteria.COST_UNIT,
                        "horizon": mpc_criteria.run_horizon(p),
                        "energy": float(res.energy) if res else math.nan})
            if p.criterion == criteria.TIME_ENERGY:
                out.update({"rho": float(p.rho), "arrival_time": out["t_final"]
                            if out["converged"] else math.nan})
            else:
                S = mpc_criteria.terminal_weight(p)
                out.update({"terminal_S": S.tolist(), "terminal_cost": float(
                    criteria.terminal_cost(res.final_state, S)) if res else math.nan})
        return out

    def simulate(self, mats: Mapping[str, Any],
                 scalars: Mapping[str, float] | None = None) -> dict[str, np.ndarray]:
        """Histories of one candidate in the training scenario, for plots.

        Returns
        -------
        dict
            ``t`` (k + 1,) s, ``r`` (k + 1, 3) m, ``v`` (k + 1, 3) m/s, ``u`` (k + 1, 3)
            m/s² (input applied from each sample; the last row is zero), ``delta_v``
            (k + 1,) cumulative m/s; ``channels`` (names of the columns of ``r``, ``v``,
            ``u``) and ``limits`` (``u``: ±``u_max``).

        Raises
        ------
        ConfigError
            Malformed matrices, or no stabilizing Riccati solution.
        """
        H, F, _, ok = self.controller(mats)
        if not ok:
            raise ConfigError("matrices", "no stabilizing Riccati solution for these Q, R")
        res = self.run(H, F, record=True)
        u = np.vstack([res.inputs, np.zeros((1, 3))])
        dv = np.concatenate([[0.0], np.cumsum(self.params.sample_time_s
                                               * np.linalg.norm(res.inputs, axis=1))])
        t = self.params.sample_time_s * np.arange(res.states.shape[0])
        return {"t": t, "r": res.states[:, :3], "v": res.states[:, 3:], "u": u,
                "delta_v": dv,
                "channels": {"r": list(STATE_NAMES[:3]), "v": list(STATE_NAMES[3:]),
                             "u": list(INPUT_NAMES)},
                "limits": {"u": (-self.u_max, self.u_max)}}

    def closed_loop(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None
                    ) -> ClosedLoop | None:
        """The MPC's unconstrained gain on the discrete CW model: with no input bound
        active, the QP's minimizer is Ũ = −H̃⁻¹ F̃ s, so u_0 = −K s with K the first three
        rows of diag(u_max) H̃⁻¹ F̃, and s_{k+1} = (A_d − B_d K) s_k (sample time
        ``sample_time_s``). None without a stabilizing Riccati solution."""
        H, F, _, ok = self.controller(mats)
        if not ok:
            return None
        K = self.u_max[:, None] * np.linalg.solve(H, F)[:3]
        return ClosedLoop(self.Ad - self.Bd @ K, "discrete",
                          dt=float(self.params.sample_time_s), gain=K,
                          state_names=STATE_NAMES, input_names=INPUT_NAMES)

    # --- scenarios ----------------------------------------------------------------------

    def training_scenario(self) -> dict[str, Any]:
        """The scenario the weights are tuned on, JSON-ready."""
        sc = scen.training(self.params)
        return {"scenario": sc.label, "s0": list(sc.s0), "plant": sc.plant,
                "eccentricity": sc.eccentricity, "thrust_scale": sc.thrust_scale}

    def scenario_key(self) -> tuple:
        """Hashable key of the training scenario."""
        return scen.training(self.params).key()

    def sample_training(self, n: int, seed: int) -> list[dict[str, Any]]:
        """``n`` seeded training starts on the held-out sphere (see
        :func:`~penaltyrun.problems.mpc.scenarios.sample_training`)."""
        return scen.sample_training(self.params, n, seed)

    def holdout_keys(self) -> set[tuple]:
        """Keys of the held-out scenarios."""
        return {s.key() for s in scen.holdout(self.params)}

    def holdout_scenarios(self) -> dict[str, np.ndarray]:
        """The held-out set: ``scenario`` labels, ``kind``, ``s0`` (n, 6), ``plant``,
        ``eccentricity``, ``thrust_scale``."""
        sc = scen.holdout(self.params)
        return {"scenario": np.asarray([s.label for s in sc], dtype=object),
                "kind": np.asarray([s.kind for s in sc], dtype=object),
                "s0": np.asarray([s.s0 for s in sc], dtype=float).reshape(-1, 6),
                "plant": np.asarray([s.plant for s in sc], dtype=object),
                "eccentricity": np.asarray([s.eccentricity for s in sc], dtype=float),
                "thrust_scale": np.asarray([s.thrust_scale for s in sc], dtype=float)}

    def holdout(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None
                ) -> dict[str, np.ndarray] | None:
        """Evaluate one candidate on the held-out set (runner hook) at the training deadline
        ``t_max`` and at the held-out horizon (see :mod:`penaltyrun.problems.horizon`).

        Returns
        -------
        dict of ndarray or None
            Per scenario: the fields of :meth:`holdout_scenarios`; at the held-out horizon
            ``cost``, ``delta_v``, ``converged``, ``status``, ``t_final``,
            ``arrival_time``, ``final_distance``, ``final_speed``; at the training deadline
            the fields of :data:`~penaltyrun.problems.horizon.DEADLINE_FIELDS`;
            ``horizon`` and ``training_horizon`` (s). ``None`` if the set is empty.
        """
        scenarios = scen.holdout(self.params)
        if not scenarios:
            return None
        p = self.params
        train_t = mpc_criteria.run_horizon(p)
        long_t = criteria.judged_at(p, train_t, p.t_max, p.sample_time_s)
        short = self._holdout_runs(mats, scenarios)
        long = horizon.at_horizon(self, long_t)._holdout_runs(mats, scenarios) \
            if long_t > train_t else short
        out = self.holdout_scenarios()
        out.update(horizon.combine(short, long, train_t, long_t))
        return out

    def basin_axes(self) -> BasinAxes:
        """Starts at rest in the orbital plane: along-track y × radial x (m), a square of
        1.5 times the training start's distance; z as in the training start."""
        s0 = np.asarray(self.params.s0, float)
        reach = 1.5 * float(np.linalg.norm(s0[:3]))
        marker = (float(s0[1]), float(s0[0])) if not np.any(s0[3:]) else None
        return BasinAxes(("along-track y (m)", "radial x (m)"), (-reach, -reach),
                         (reach, reach), "s", marker)

    def basin_runs(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None,
                   points: np.ndarray) -> dict[str, Any]:
        """One candidate from the starts (y, x) ``points`` (P, 2), at rest, on the training
        plant, at the horizon the held-out set is judged at."""
        p = self.params
        train_t = mpc_criteria.run_horizon(p)
        long_t = criteria.judged_at(p, train_t, p.t_max, p.sample_time_s)
        base = scen.training(p)
        starts = [scen.Scenario(f"basin:{k}", "basin", (float(x), float(y), base.s0[2],
                                                        0.0, 0.0, 0.0),
                                base.plant, base.eccentricity, base.thrust_scale)
                  for k, (y, x) in enumerate(points)]
        prob = horizon.at_horizon(self, long_t) if long_t > train_t else self
        runs = prob._holdout_runs(mats, starts)
        return {"converged": runs["converged"], "cost": runs["cost"], "horizon": long_t,
                "arrival_time": arrival_times(runs["converged"], runs["t_final"])}

    def _holdout_runs(self, mats: Mapping[str, Any], scenarios: list[scen.Scenario]
                      ) -> dict[str, np.ndarray]:
        """Per-scenario results of one candidate at this problem's ``t_max``."""
        H, F, _, ok = self.controller(mats)
        rows = [self._summary(self.run(H, F, sc) if ok else None, sc) for sc in scenarios]
        out: dict[str, np.ndarray] = {}
        for key in ("cost", "delta_v", "t_final", "final_distance", "final_speed"):
            out[key] = np.asarray([r[key] for r in rows], dtype=float)
        out["converged"] = np.asarray([r["converged"] for r in rows], dtype=bool)
        out["status"] = np.asarray([r["status"] for r in rows], dtype=object)
        return out


def make_problem(case: str, overrides: Mapping[str, Any]) -> RendezvousMPC:
    """Build the problem: defaults → case entry → ``overrides`` (validated).

    Raises
    ------
    ConfigError
        Unknown case or parameter, or a bad value (naming its key).
    """
    params = build_params(case, overrides)
    scen.holdout(params)      # validates the held-out set
    logger.debug("%s case %s: %s", NAME, case, params)
    return RendezvousMPC(case, params)


__all__ = ["CASES", "CASE_PARAMS", "COST_LABEL", "COST_UNIT", "CUT_MARGIN", "DARE_FAILURE",
           "DEFAULT_CASE", "HARD_FAILURE_FACTOR", "NAME", "VARIANT_IGNORE", "Params",
           "RendezvousMPC", "make_problem", "plot_inputs", "plot_trajectory", "report_info"]
