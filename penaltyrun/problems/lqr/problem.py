"""The ``problem=lqr`` object: LQR gains of the tuned Q, R on the user's plant, and the
performance cost of the closed loop.

Per candidate (Q, R): K = R⁻¹BᵀP from the Riccati equation of (A, B, Q, R)
(:mod:`~penaltyrun.dynamics.riccati`), u = sat(−K x), and the cost

    J = mean over x0 ∈ ``x0`` of ∫₀ᵀ (xᵀ W_x x + uᵀ W_u u) dt.

A discrete-time plant (``dt``) uses the discrete Riccati equation and steps its loop
exactly (:mod:`~penaltyrun.problems.lqr.discrete`); otherwise a linear plant without input
limits is evaluated in closed form
(:func:`penaltyrun.dynamics.linear.quadratic_cost` with W = W_x + Kᵀ W_u K); input limits
or a nonlinear ``dynamics`` go through the vectorized integrator
:func:`penaltyrun.dynamics.linear_feedback.simulate`.

Cost of one start (P = the failure penalty scale, r = ‖x(T)‖ / ‖x0‖):

* ``converged``: J;
* ``constraint`` (a constraint of :mod:`~penaltyrun.problems.lqr.constraints` violated by v,
  the summed relative excess): J + P (1 + v / (1 + v));
* ``not_settled`` (``settle_tol`` set and r > settle_tol): J + P (1 + r / (1 + r));
* ``diverged`` (‖x‖ > ``x_bound``) or ``step_failure`` at time t_f:
  J(t_f) + P (2 + (T − t_f) / T) (the earlier, the worse; T is ``free_time_cap`` under
  ``criterion: time_energy``);
* ``nonfinite``: 10 P + the finite part of J;
* ``care_failure`` (no stabilizing Riccati solution): 10 P (1 + s / (1 + s)), s the
  relative residual of the best solution found (monotone in the failure's size);
* ``cutoff`` (exact cutoff, integrated loops only): the partial J of a start stopped once
  the sum of its candidate's J over the starts exceeded the number of starts × the
  threshold.

Criteria (``criterion``, :mod:`~penaltyrun.problems.lqr.criteria`): ``terminal`` adds
x(T)ᵀ S x(T) to each start's J; ``time_energy`` replaces J by the performance cost to the
settling time plus ρ times that time, ``not_settled`` where the start has not settled by
``free_time_cap``.

Every graded cost is at least the start's J, so a cut candidate's mean cost is above its
threshold and at most its uncut cost. A candidate's cost is the mean over its starts, its
status the worst one (in the order above; ``cutoff`` whenever a start was cut) and it
converged only if every start did. J(cQ, cR) = J(Q, R) for every c > 0 (the
gain does not change), so one direction of the search space is redundant.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

import numpy as np

from penaltyrun.dynamics import linear_feedback as loop
from penaltyrun.dynamics.linear import loop_solution, quadratic_cost, sampled_loop
from penaltyrun.dynamics.riccati import dlqr_gains, lqr_gains
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
from penaltyrun.problems.lqr import constraints as cons
from penaltyrun.problems.lqr import criteria as lqr_criteria
from penaltyrun.problems.lqr import discrete
from penaltyrun.problems.lqr import params as pm
from penaltyrun.problems.lqr.gradient import lqr_gradient
from penaltyrun.problems.lqr.plant import Plant

logger = logging.getLogger(__name__)

#: Statuses from best to worst: a candidate takes the worst of its starts, except that a
#: candidate with a start cut by the exact cutoff is ``cutoff`` (its cost is a bound).
STATUSES = ("converged", "constraint", "not_settled", "diverged", "step_failure", "nonfinite",
            "care_failure", "cutoff")
_RANK = {status: rank for rank, status in enumerate(STATUSES)}
HARD_FACTOR = 10.0
#: Relative margin by which the summed J must exceed a threshold before a candidate is cut.
CUT_MARGIN = 1e-9
_LOOP_STATUS = {loop.HORIZON: "converged", loop.DIVERGED: "diverged",
                loop.STEP_FAILURE: "step_failure", loop.NONFINITE: "nonfinite",
                loop.CUTOFF: "cutoff"}
_STEP_STATUS = {discrete.HORIZON: "converged", discrete.DIVERGED: "diverged",
                discrete.NONFINITE: "nonfinite"}


class LQRProblem:
    """LQR tuning on a plant from the config; tuned matrices ``Q`` (p × p: n × n, or the
    rows of ``q_output``) and ``R`` (m × m).

    With ``integral_outputs`` the plant is augmented by its integrator states
    (:func:`~penaltyrun.problems.lqr.constraints.augment`) before anything else; ``plant``
    is then the augmented one and ``n_plant`` the size of the user's state.

    Parameters
    ----------
    case : str
        Case name.
    params : Params
        Parameters (validated here).
    plant : Plant
        The validated plant.
    """

    name = "lqr"

    def __init__(self, case: str, params: pm.Params, plant: Plant) -> None:
        self.case = case
        self.params = params
        p = params
        self.n_plant = plant.n_states
        self.plant = cons.augment(plant, p.integral_outputs)
        n, m = self.plant.n_states, self.plant.n_inputs
        self.dt = self.plant.dt
        if cons.includes_integrators(p.x0, n):
            self.x0 = pm.states("x0", p.x0, n)
        else:
            self.x0 = cons.pad(pm.states("x0", np.eye(self.n_plant) if p.x0 is None else p.x0,
                                         self.n_plant), n)
        self.Wx = cons.pad_weight(p.state_weight, self.n_plant, n)
        self.Wu = pm.weight("input_weight", p.input_weight, m, definite=True)
        self.u_max = pm.limits(p.u_max, m)
        self.t_max = float(p.t_max)
        self.q_output, self.q_fixed = cons.q_structure(self.plant, p.q_output, p.q_fixed)
        self.matrices = (MatrixSpec("Q", self.q_output.shape[0],
                                    pm.bounds("q_bounds", p.q_bounds)),
                         MatrixSpec("R", m, pm.bounds("r_bounds", p.r_bounds)))
        self.scalars: tuple[ScalarSpec, ...] = ()
        self.closed_form = plant.linear and self.u_max is None and self.dt is None
        self.limits = cons.Limits.build(p, self.plant, self.n_plant, self.closed_form)
        self.optimum = self._optimum()
        self.penalty = float(p.failure_penalty) if p.failure_penalty is not None else \
            1000.0 * (self.optimum if np.isfinite(self.optimum) and self.optimum > 0 else 1.0)
        self.holdout_states()  # validate the held-out set now (bad input: exit 2)
        self.S = lqr_criteria.terminal_weight(self) \
            if p.criterion == criteria.TERMINAL or p.terminal_weight is not None else None
        if p.criterion != criteria.TERMINAL:
            self.S = None   # validated above, used by the terminal criterion only
        self._last_single: tuple[bytes, dict[str, np.ndarray]] | None = None  # see rows

    @property
    def cost_unit(self) -> str:
        """Unit of the cost (``cost_unit``), for reports."""
        return pm.cost_unit(self.params, self.dt is not None)

    def _optimum(self) -> float:
        """J* = mean x0ᵀ P(W_x, W_u) x0: the cost of the LQR of the performance weights on
        the linear model over an infinite horizon (NaN when W_x gives no stabilizing
        solution); the global optimum of an unsaturated linear plant as T → ∞."""
        from scipy.linalg import solve_continuous_are, solve_discrete_are

        solve = solve_continuous_are if self.dt is None else solve_discrete_are
        try:
            P = solve(self.plant.A, self.plant.B, self.Wx, self.Wu)
        except (np.linalg.LinAlgError, ValueError):
            return float("nan")
        return float(np.mean(np.einsum("ki,ij,kj->k", self.x0, P, self.x0)))

    # -- evaluation -----------------------------------------------------------------------
    def state_penalty(self, Q: np.ndarray) -> np.ndarray:
        """The Riccati equation's Q = C_qᵀ Q̃ C_q + Q₀ of tuned Q̃ (C, p, p) → (C, n, n)."""
        C = self.q_output
        return C.T @ Q @ C + self.q_fixed

    def gains(self, Q: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(K, ok, failure) of tuned Q̃ (C, p, p), R (C, m, m): continuous or discrete LQR."""
        solve = lqr_gains if self.dt is None else dlqr_gains
        return solve(self.plant.A, self.plant.B, self.state_penalty(Q), R)

    def _bound(self, X0: np.ndarray) -> float:
        return self.params.x_bound or 1e4 * float(np.max(np.linalg.norm(X0, axis=1)))

    def rows(self, Q: np.ndarray, R: np.ndarray, X0: np.ndarray,
             thresholds: np.ndarray | None = None, metrics: bool = False
             ) -> dict[str, np.ndarray]:
        """Every candidate from every start: per-start results of shape (C, k).

        ``metrics``: also compute the measures of the constraints not set (for reports).

        The rows of the last single candidate from the training starts are kept: a
        gradient optimizer evaluates a point and then asks for its gradient
        (:meth:`gradient`), which needs the same rows, so the Riccati equation and the
        closed loop are solved once per point (the returned arrays are shared: read only).
        A copy of the problem (another horizon) never answers from the original's rows.

        Returns
        -------
        dict
            ``cost`` (graded), ``J`` (raw), ``status`` (str), ``t_final``, ``x_final``
            (C, k, n), ``K`` (C, m, n), ``ok`` (C,) Riccati success, and the measures of
            :meth:`~penaltyrun.problems.lqr.constraints.Limits.measure` (NaN where not
            computed); ``loop``: for one candidate with a stabilizing gain on the closed-form
            route, its :class:`~penaltyrun.dynamics.linear.LoopSolution` (S, e^{A_cl T} and
            the Schur decomposition the exact gradient reuses), else None.
        """
        single = Q.shape[0] == 1 and X0 is self.x0 and thresholds is None and not metrics
        if not single:
            return self._rows(Q, R, X0, thresholds, metrics)
        # id(self): a shallow copy (another horizon, :func:`~penaltyrun.problems.horizon.
        # at_horizon`) starts with this entry but must compute its own rows
        key = str(id(self)).encode() + b"|" + b"|".join(
            part for M in (Q, R)
            for part in (np.asarray(M).dtype.str.encode(), np.ascontiguousarray(M).tobytes()))
        last = self._last_single  # read once: another thread may replace it
        if last is not None and last[0] == key:
            return last[1]
        res = self._rows(Q, R, X0, None, False)
        self._last_single = (key, res)
        return res

    def _rows(self, Q: np.ndarray, R: np.ndarray, X0: np.ndarray,
              thresholds: np.ndarray | None, metrics: bool) -> dict[str, np.ndarray]:
        """:meth:`rows`, computed."""
        n_c, n_k = Q.shape[0], X0.shape[0]
        K, ok, failure = self.gains(Q, R)
        J = np.zeros((n_c, n_k))
        t_end = np.full((n_c, n_k), self.t_max)
        x_final = np.zeros((n_c, n_k, self.plant.n_states))
        codes = np.full((n_c, n_k), "converged", dtype=object)
        good = np.flatnonzero(ok)
        steps = None
        loop_of_one = None
        history = self.limits.needs_history(metrics)
        free = self.params.criterion == criteria.TIME_ENERGY
        if good.size and free:
            J[good], t_end[good], x_final[good], codes[good] = lqr_criteria.free_time(
                self, K[good], X0)
            if self.dt is not None and history:  # the constraints' responses to t_max
                steps = discrete.simulate(
                    self.plant.A, self.plant.B, np.repeat(K[good], n_k, 0),
                    np.tile(X0, (good.size, 1)), self.Wx, self.Wu, self.u_max,
                    discrete.n_steps(self.t_max, self.dt), self._bound(X0), history=True)
        elif good.size and self.dt is not None and self.plant.linear and self.u_max is None \
                and not history:
            A_cl = self.plant.A - self.plant.B @ K[good]
            W = self.Wx + np.swapaxes(K[good], 1, 2) @ self.Wu @ K[good]
            J[good], x_final[good] = discrete.linear_sum(
                A_cl, W, X0, discrete.n_steps(self.t_max, self.dt))
        elif good.size and self.dt is not None:
            cand = np.repeat(good, n_k)
            steps = discrete.simulate(self.plant.A, self.plant.B, K[cand],
                                      np.tile(X0, (good.size, 1)), self.Wx, self.Wu,
                                      self.u_max, discrete.n_steps(self.t_max, self.dt),
                                      self._bound(X0), history=history)
            J[good] = steps["cost"].reshape(good.size, n_k)
            t_end[good] = (steps["k_end"] * self.dt).reshape(good.size, n_k)
            x_final[good] = steps["x_final"].reshape(good.size, n_k, -1)
            codes[good] = np.asarray([_STEP_STATUS[int(s)] for s in steps["status"]],
                                     dtype=object).reshape(good.size, n_k)
        elif n_c == 1 and good.size and self.closed_form:
            loop_of_one = loop_solution(self.plant.A - self.plant.B @ K[0],
                                        self.Wx + K[0].T @ self.Wu @ K[0], self.t_max)
            J[0], x_final[0] = loop_of_one.cost(X0)
        elif good.size and self.closed_form:
            A_cl = self.plant.A - self.plant.B @ K[good]
            W = self.Wx + np.swapaxes(K[good], 1, 2) @ self.Wu @ K[good]
            J[good], x_final[good] = quadratic_cost(A_cl, W, X0, self.t_max)
        elif good.size:
            cand = np.repeat(good, n_k)
            cut = None
            if thresholds is not None:
                thr = np.asarray(thresholds, dtype=float)[good]
                allowed = thr < HARD_FACTOR * self.penalty  # NaN: False
                cut = np.where(allowed, n_k * (thr + CUT_MARGIN * np.abs(thr)), np.inf)
            bound = self._bound(X0)
            run = loop.simulate(self.plant.f, K[cand], np.tile(X0, (good.size, 1)), self.Wx,
                                self.Wu, self.u_max, self.t_max, self.params.rtol,
                                self.params.atol, self.params.max_steps, bound,
                                np.repeat(np.arange(good.size), n_k), cut)
            J[good] = run["cost"].reshape(good.size, n_k)
            t_end[good] = run["t_end"].reshape(good.size, n_k)
            x_final[good] = run["x_final"].reshape(good.size, n_k, -1)
            codes[good] = np.asarray([_LOOP_STATUS[int(s)] for s in run["status"]],
                                     dtype=object).reshape(good.size, n_k)
        if self.S is not None:
            J = J + criteria.terminal_cost(x_final, self.S)
        measures = self.limits.measure(K, ok, X0, self.t_max, steps, metrics)
        cost = self._graded(J, t_end, x_final, X0, codes, measures.pop("violation"), free)
        if not ok.all():
            finite = np.isfinite(failure)
            size = np.ones_like(failure)
            size[finite] = failure[finite] / (1.0 + failure[finite])
            cost[~ok] = (HARD_FACTOR * self.penalty * (1.0 + size[~ok]))[:, None]
            codes[~ok] = "care_failure"
        return {"cost": cost, "J": J, "status": codes, "t_final": t_end, "x_final": x_final,
                "K": K, "ok": ok, "loop": loop_of_one, **measures}

    def _graded(self, J: np.ndarray, t_end: np.ndarray, x_final: np.ndarray,
                X0: np.ndarray, codes: np.ndarray, excess: np.ndarray, free: bool
                ) -> np.ndarray:
        """Graded costs (C, k) of the runs (see the module docstring); marks
        ``not_settled`` (``settle_tol``, not under ``time_energy``: ``free``) and
        ``constraint`` runs in ``codes``. Each penalty is computed only where its status
        occurs: a batch of converged runs costs a few array operations."""
        P = self.penalty
        converged = codes == "converged"
        tol = self.params.settle_tol
        ratio = None
        with np.errstate(all="ignore"):
            if tol is not None and not free:
                ratio = np.linalg.norm(x_final, axis=2) / np.linalg.norm(X0, axis=1)
                unsettled = converged & ~(ratio <= tol)
                if unsettled.any():
                    codes[unsettled] = "not_settled"
                    converged &= ~unsettled
            violated = converged & (excess > 0)
            if violated.any():
                codes[violated] = "constraint"
                converged &= ~violated
            cost = J.copy()
            keep = np.isfinite(cost)
            if not converged.all():
                unsettled = codes == "not_settled"
                if unsettled.any():
                    if ratio is None:
                        ratio = np.linalg.norm(x_final, axis=2) / np.linalg.norm(X0, axis=1)
                    cost[unsettled] = (J + P * (1.0 + ratio / (1.0 + ratio)))[unsettled]
                if violated.any():
                    graded = np.where(np.isfinite(excess), excess / (1.0 + excess), 1.0)
                    cost[violated] = (J + P * (1.0 + graded))[violated]
                failed = (codes == "diverged") | (codes == "step_failure")
                if failed.any():
                    run_t = float(self.params.free_time_cap) if free else self.t_max
                    late = (run_t - t_end) / run_t
                    cost[failed] = (J + P * (2.0 + late))[failed]
                keep = np.isfinite(cost) & (codes != "nonfinite")
        if not keep.all():
            cost = np.where(keep, cost, HARD_FACTOR * P + np.where(np.isfinite(J), J, 0.0))
        return cost

    @staticmethod
    def _aggregate(res: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        worst = np.asarray([STATUSES[max(_RANK[s] for s in row)] for row in res["status"]],
                           dtype=object)
        return res["cost"].mean(axis=1), worst == "converged", worst

    def evaluate_batch(self, mats: Mapping[str, np.ndarray],
                       scalars: Mapping[str, np.ndarray] | None = None,
                       thresholds: np.ndarray | None = None) -> BatchEvaluation:
        """Costs of C candidates: ``mats["Q"]`` (C, n, n), ``mats["R"]`` (C, m, m).

        ``thresholds`` (C,): exact cutoff of integrated loops (``inf``: none); the closed
        form ignores it (it has no partial cost to stop at).
        """
        Q = np.asarray(mats["Q"], dtype=float)
        R = np.asarray(mats["R"], dtype=float)
        res = self.rows(Q, R, self.x0, thresholds)
        cost, converged, status = self._aggregate(res)
        return BatchEvaluation(cost=cost, converged=converged, status=status)

    def _check(self, mats: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray]:
        out = []
        for spec in self.matrices:
            if mats.get(spec.name) is None:
                raise ConfigError(f"matrices.{spec.name}", f"missing matrix ({spec.size}x"
                                  f"{spec.size})")
            if spec.name == "Q":
                out.append(cons.given_q(mats["Q"], spec.size, self.plant, self.q_output,
                                        self.q_fixed))
            else:
                out.append(check_spd(f"matrices.{spec.name}", mats[spec.name], spec.size))
        return out[0], out[1]

    def evaluate(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None
                 ) -> dict[str, Any]:
        """Detailed evaluation of one (Q, R); JSON-serializable.

        Returns
        -------
        dict
            ``problem``, ``case``, ``cost`` (objective, ``cost_unit``), ``converged``,
            ``status``, ``t_final`` (largest end time), ``t_max``, ``optimum`` (J* of the
            linear model, infinite horizon), ``cost_unit``, ``method`` (``closed_form``,
            ``integrated`` or ``stepped`` for a discrete plant), ``gain`` (m × n,
            u = −gain x), ``closed_loop_poles`` (real, imaginary parts),
            ``failure_penalty``, and per start: ``start_costs``, ``start_status``,
            ``final_state_ratio`` (‖x(T)‖ / ‖x0‖); then ``dt``, ``state_penalty`` (the
            Riccati equation's Q) and the constraint measures
            (:meth:`~penaltyrun.problems.lqr.constraints.Limits.report`).
        """
        Q, R = self._check(mats)
        res = self.rows(Q[None], R[None], self.x0, metrics=True)
        cost, converged, status = self._aggregate(res)
        K = res["K"][0]
        poles = np.linalg.eigvals(self.plant.A - self.plant.B @ K) if res["ok"][0] else []
        ratio = np.linalg.norm(res["x_final"][0], axis=1) / np.linalg.norm(self.x0, axis=1)
        return {
            "problem": self.name, "case": self.case, "cost": float(cost[0]),
            "converged": bool(converged[0]), "status": str(status[0]),
            "t_final": float(res["t_final"][0].max()), "t_max": self.t_max,
            "optimum": self.optimum, "cost_unit": self.cost_unit,
            "method": ("stepped" if self.dt is not None else
                       "closed_form" if self.closed_form else "integrated"),
            "gain": K.tolist(),
            "closed_loop_poles": [[float(z.real), float(z.imag)] for z in poles],
            "failure_penalty": self.penalty,
            "start_costs": res["cost"][0].tolist(),
            "start_status": [str(s) for s in res["status"][0]],
            "final_state_ratio": ratio.tolist(),
            "dt": self.dt, "state_penalty": self.state_penalty(Q[None])[0].tolist(),
            **self.limits.report(res),
        }

    def gradient(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None
                 ) -> CostGradient:
        """Cost of one (Q̃, R) and its exact gradient d cost / d (Q̃, R)
        (:mod:`~penaltyrun.problems.lqr.gradient`), or the reason there is none."""
        Q, R = self._check(mats)
        return lqr_gradient(self, Q, R)

    def gradient_cost(self) -> GradientCost:
        """What one gradient costs in evaluations on this plant (its size including
        integrators, continuous or discrete): measured by ``bench/gradient_cost.py`` and
        ``bench/lqr_scaling_ratio.py``, tables in ``bench/README.md``
        (:func:`~penaltyrun.problems.gradient_costs.lqr_cost`)."""
        return gradient_costs.lqr_cost(self.plant.n_states, self.dt is not None)

    def simulate(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None,
                 n_points: int = 400) -> dict[str, np.ndarray]:
        """Closed-loop histories of one (Q, R) from every training start, for plots: exact
        for a linear loop without input limits
        (:func:`penaltyrun.dynamics.linear.sampled_loop`), else scipy's DOP853 dense output
        at the problem's tolerances.

        Returns
        -------
        dict
            ``t`` (n_points,), ``x`` (k, n_points, n), ``u`` (k, n_points, m), ``J``
            (k, n_points) running cost; ``channels`` (names of the columns of ``x`` and
            ``u``) and ``limits`` (``u``: ±``u_max`` when the inputs saturate).
        """
        Q, R = self._check(mats)
        K, ok, _ = self.gains(Q[None], R[None])
        if not ok[0]:
            raise ConfigError("matrices", "no stabilizing Riccati solution for these Q, R")
        if self.dt is not None:
            return discrete.histories(self.plant.A, self.plant.B, K[0], self.x0, self.Wx,
                                      self.Wu, self.u_max, self.t_max, float(self.dt),
                                      self._bound(self.x0))
        K = K[0]
        t = np.linspace(0.0, self.t_max, n_points)
        if self.plant.linear and self.u_max is None and n_points >= 2:
            x, J = sampled_loop((self.plant.A - self.plant.B @ K)[None], self.x0, t,
                                (self.Wx + K.T @ self.Wu @ K)[None])
            x, J = x[0], J[0]
        else:
            x, J = self._integrated(K, t)
        u = np.stack([loop.feedback_input(np.repeat(K[None], n_points, 0), xk, self.u_max)
                      for xk in x])
        names = self.channel_names()
        limits = {} if self.u_max is None else {"u": (-self.u_max, self.u_max)}
        return {"t": t, "x": x, "u": u, "J": J,
                "channels": {"x": list(names[0]), "u": list(names[1])}, "limits": limits}

    def _integrated(self, K: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States (k, N, n) and running cost (k, N) of the gain K (m, n) from every training
        start at the times ``t``, by scipy's DOP853 (NaN after a failed integration)."""
        from scipy.integrate import solve_ivp

        n = self.plant.n_states
        xs, js = [], []
        for x0 in self.x0:
            def rhs(_t: float, y: np.ndarray) -> np.ndarray:
                x = y[None, :n]
                u = loop.feedback_input(K[None], x, self.u_max)
                dx = np.asarray(self.plant.f(x, u), dtype=float)[0]
                return np.append(dx, x[0] @ self.Wx @ x[0] + u[0] @ self.Wu @ u[0])

            sol = solve_ivp(rhs, (0.0, self.t_max), np.append(x0, 0.0), t_eval=t,
                            method="DOP853", rtol=self.params.rtol, atol=self.params.atol)
            x = np.full((t.size, n), np.nan)
            x[: sol.y.shape[1]] = sol.y[:n].T
            J = np.full(t.size, np.nan)
            J[: sol.y.shape[1]] = sol.y[n]
            xs.append(x)
            js.append(J)
        return np.asarray(xs), np.asarray(js)

    def channel_names(self) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """Names of the states (``x1`` … ``xn``) and inputs (``u1`` … ``um``)."""
        return (tuple(f"x{i + 1}" for i in range(self.plant.n_states)),
                tuple(f"u{i + 1}" for i in range(self.plant.n_inputs)))

    def closed_loop(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None
                    ) -> ClosedLoop | None:
        """The closed loop of one (Q̃, R) on the linear model (the plant's Jacobians at the
        origin for a nonlinear ``dynamics``): ẋ = (A − B K) x with the continuous LQR gain
        of the Riccati Q (:meth:`state_penalty`), or, for a plant with a sample time ``dt``,
        x_{k+1} = (A − B K) x_k with the discrete one K = (R + BᵀPB)⁻¹BᵀPA. None when the
        Riccati equation has no stabilizing solution. Input limits are inactive
        at the origin, so they do not enter."""
        Q, R = self._check(mats)
        states, inputs = self.channel_names()
        K, ok, _ = self.gains(Q[None], R[None])
        if not ok[0]:
            return None
        A_cl = self.plant.A - self.plant.B @ K[0]
        if self.dt is None:
            return ClosedLoop(A_cl, "continuous", gain=K[0], state_names=states,
                              input_names=inputs)
        if not np.all(np.abs(np.linalg.eigvals(A_cl)) < 1.0):
            return None
        return ClosedLoop(A_cl, "discrete", dt=float(self.dt), gain=K[0], state_names=states,
                          input_names=inputs)

    # -- scenarios --------------------------------------------------------------------------
    def training_scenario(self) -> dict[str, Any]:
        """The scenario Q, R are tuned on: the training starts."""
        return {"scenario": "x0", "x0": self.x0.tolist()}

    def scenario_key(self) -> tuple:
        """Hashable key of the training scenario (its starts rounded to 1e-9)."""
        return tuple(tuple(np.round(x, 9).tolist()) for x in self.x0)

    def holdout_keys(self) -> set[tuple]:
        """Keys (as :meth:`scenario_key`) of the held-out starts, one start each."""
        return {(tuple(np.round(x, 9).tolist()),) for x in self.holdout_states()}

    def _sphere(self, n_points: int, seed: int) -> np.ndarray:
        rng = np.random.default_rng(int(seed))
        z = rng.normal(size=(n_points, self.n_plant))
        radius = float(np.mean(np.linalg.norm(self.x0, axis=1)))
        return cons.pad(radius * z / np.linalg.norm(z, axis=1, keepdims=True),
                        self.plant.n_states)

    def sample_training(self, n: int, seed: int) -> list[dict[str, Any]]:
        """``n`` seeded training scenarios, one start each, uniform on the sphere of radius
        mean ‖x0‖ (a different stream from the held-out one: ``seed`` is the train seed)."""
        return [{"x0": [x.tolist()]} for x in self._sphere(n, seed + 7919)]

    def holdout_states(self) -> np.ndarray:
        """Held-out starts (k', n): ``holdout_x0``, or ``holdout_n`` seeded ones.

        Raises
        ------
        ConfigError
            A given held-out start that is also a training start.
        """
        p = self.params
        n = self.plant.n_states
        if p.holdout_x0 is not None:
            if len(p.holdout_x0) == 0:
                return np.zeros((0, n))
            if cons.includes_integrators(p.holdout_x0, n):
                held = pm.states("holdout_x0", p.holdout_x0, n)
            else:
                held = cons.pad(pm.states("holdout_x0", p.holdout_x0, self.n_plant), n)
            for x in held:
                if np.any(np.all(np.isclose(self.x0, x, rtol=0.0, atol=1e-9), axis=1)):
                    raise ConfigError(f"{pm.PREFIX}.holdout_x0", f"start {x.tolist()} is also "
                                      "a training start; held-out starts must differ")
            return held
        return self._sphere(p.holdout_n, p.holdout_seed)

    def holdout_scenarios(self) -> dict[str, np.ndarray]:
        """``scenario`` labels and ``x0`` (k', n) of the held-out set."""
        held = self.holdout_states()
        return {"scenario": np.asarray([f"x0[{i}]" for i in range(len(held))], dtype=object),
                "x0": held}

    def holdout(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None
                ) -> dict[str, np.ndarray] | None:
        """One (Q, R) on every held-out start (runner hook), the cost integrated to the
        training horizon ``t_max`` and to the held-out horizon (see
        :mod:`penaltyrun.problems.horizon`); ``None`` when the set is empty.

        Returns
        -------
        dict of ndarray
            Per start, at the held-out horizon: ``scenario``, ``x0``, ``cost`` (graded),
            ``J``, ``converged``, ``status``, ``t_final``, ``final_distance`` (‖x(T)‖);
            ``arrival_time`` is NaN (the cost has no target event); at ``t_max`` the
            fields of :data:`~penaltyrun.problems.horizon.DEADLINE_FIELDS`; ``horizon``
            and ``training_horizon``.
        """
        sc = self.holdout_scenarios()
        if not len(sc["scenario"]):
            return None
        Q, R = self._check(mats)
        p = self.params
        train_t = criteria.run_horizon(p)
        long_t = criteria.judged_at(p, train_t, self.t_max)
        short = self._holdout_runs(Q, R, sc["x0"])
        long = horizon.at_horizon(self, long_t, t_max=long_t)._holdout_runs(Q, R, sc["x0"]) \
            if long_t > train_t else short
        out = horizon.combine(short, long, train_t, long_t)
        if p.criterion != criteria.TIME_ENERGY:   # no target event: no arrival time
            out["arrival_time"] = np.full(len(sc["scenario"]), np.nan)
        return {**sc, **out}

    def basin_axes(self) -> BasinAxes | None:
        """Starts in the plane of the first two plant states (the others 0), ±2 times the
        mean size of the training starts; None for a one-state plant."""
        if self.n_plant < 2:
            return None
        radius = 2.0 * float(np.mean(np.linalg.norm(self.x0[:, :self.n_plant], axis=1)))
        first = self.x0[0]
        marker = (float(first[0]), float(first[1])) \
            if not np.any(first[2:]) and len(self.x0) == 1 else None
        return BasinAxes(self.channel_names()[0][:2], (-radius, -radius), (radius, radius),
                         "", marker)

    def basin_runs(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None,
                   points: np.ndarray) -> dict[str, Any]:
        """One (Q, R) from the starts ``points`` (P, 2) at the horizon the held-out set is
        judged at. ``converged`` means the run neither diverged nor broke a constraint or
        the settling rule; ``arrival_time`` is the settling time under the ``time_energy``
        criterion and NaN otherwise (the cost has no target event)."""
        Q, R = self._check(mats)
        p = self.params
        train_t = criteria.run_horizon(p)
        long_t = criteria.judged_at(p, train_t, self.t_max)
        X0 = np.zeros((len(points), self.plant.n_states))
        X0[:, :2] = points
        prob = horizon.at_horizon(self, long_t, t_max=long_t) if long_t > train_t else self
        runs = prob._holdout_runs(Q, R, X0)
        settled = p.criterion == criteria.TIME_ENERGY  # its runs end at the settling time
        arrival = arrival_times(runs["converged"], runs["t_final"]) if settled \
            else np.full(len(points), np.nan)
        return {"converged": runs["converged"], "cost": runs["cost"], "horizon": long_t,
                "arrival_time": arrival}

    def _holdout_runs(self, Q: np.ndarray, R: np.ndarray, X0: np.ndarray
                      ) -> dict[str, np.ndarray]:
        """Per-start results of one (Q, R) at this problem's horizon ``t_max``."""
        res = self.rows(Q[None], R[None], X0)
        return {"cost": res["cost"][0], "J": res["J"][0],
                "converged": res["status"][0] == "converged",
                "status": np.asarray(res["status"][0], dtype=object),
                "t_final": res["t_final"][0],
                "final_distance": np.linalg.norm(res["x_final"][0], axis=1)}


__all__ = ["CUT_MARGIN", "HARD_FACTOR", "STATUSES", "LQRProblem"]
