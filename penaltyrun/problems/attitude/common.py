"""Shared parts of the spacecraft attitude problems (``attitude_lyapunov``, ``attitude_lqr``).

Rigid spacecraft, quaternion kinematics and Euler's equation (see
:mod:`penaltyrun.dynamics.attitude`), a linear state feedback u = −G (q_v, ω) whose gain
G (3 × 6) comes from the tuned matrices (PD: G = [K_p, K_d]; LQR: G = R⁻¹BᵀP), and the
minimum-energy cost J = ∫ ½ uᵀu dt (N²·m²·s) up to the FIRST time the weighted distance
d = ‖(w_q0 (q0 − 1), w_qv q_v, w_ω ω)‖ falls to ``tol`` (default weights 1, 1, 1).

Cost of a candidate (always finite):

* event fired before ``t_max``: ``cost = J(t_event)``;
* otherwise (``horizon``, ``step_failure``, ``diverged``): the graded penalty
  ``cost = J(t_end) + failure_penalty · (1 + d(t_end) / d(0))``, so every failure costs
  more than ``failure_penalty`` and failures are ranked by how close they got;
  ``diverged`` is the kernel's divergence guard (‖ω‖ beyond its bound, see
  :mod:`penaltyrun.dynamics.attitude`): t_end is where the run left the bound, so its
  d(t_end) ≥ w_ω · bound is large and it ranks behind most failures that stayed bounded;
* non-finite results (``nonfinite``) and LQR gains whose Riccati equation has no
  stabilizing solution (``care_failure``): ``cost = 1000 · failure_penalty``.
* exact cutoff (``evaluate_batch(..., thresholds=...)``, status ``cutoff``): the run stopped
  at the end of the first integration step where J exceeded its threshold by the relative
  margin :data:`CUT_MARGIN`; ``cost = J`` there, a bound above the threshold. J̇ = ½ uᵀu ≥ 0,
  so every later cost (J at the event, or J plus the failure penalty) is at least that J up
  to the integrator's round-off (checked in ``tests/problems/test_cutoff_problems.py``);
  thresholds at or above ``1000 · failure_penalty`` (the flat cost of non-finite runs) cut
  nothing.

The optimizer minimizes this cost or, with ``objective_form: neg_reciprocal``, the
companion study's −1/J (:mod:`~penaltyrun.problems.attitude.objective`); thresholds are
converted to J before the kernel sees them, and records keep the cost above.

That is the paper's criterion (``criterion: deadline``, the default). The well-posed
criteria ``time_energy`` (free final time) and ``terminal`` (fixed horizon, terminal
penalty) are in :mod:`~penaltyrun.problems.attitude.criteria`.

The pieces live in :mod:`~penaltyrun.problems.attitude.params` (parameters, cases),
:mod:`~penaltyrun.problems.attitude.frames` (attitude representations, held-out states),
:mod:`~penaltyrun.problems.attitude.reference` (scipy references) and
:mod:`~penaltyrun.problems.attitude.plots`; this module holds the problem object and
re-exports their public names.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from penaltyrun.dynamics import attitude as kernel
from penaltyrun.dynamics import integrate
from penaltyrun.errors import ConfigError
from penaltyrun.problems import criteria, gradient_costs
from penaltyrun.problems.attitude import criteria as attitude_criteria
from penaltyrun.problems.attitude.frames import (
    ATTITUDE_TYPES,
    attitude_to_quaternion,
    euler_to_quaternion,
    mrp_to_quaternion,
    normalize_quaternion,
    perturbed_states,
    robustness_grid,
)
from penaltyrun.problems.attitude.objective import cost_thresholds, optimizer_values
from penaltyrun.problems.attitude.params import (
    CASE_PARAMS,
    CASES,
    DEFAULT_CASE,
    VARIANT_IGNORE,
    Params,
    build_params,
    validate,
)
from penaltyrun.problems.attitude.plots import (
    plot_histories,
    plot_quaternions,
    plot_rates,
    plot_torques,
)
from penaltyrun.problems.attitude.reference import (
    HARD_FAILURE_FACTOR,
    _rhs_numpy,
    graded_cost,
    reference_run,
    trajectory,
)
from penaltyrun.problems.attitude.scenarios import AttitudeScenarios
from penaltyrun.problems.base import (
    BatchEvaluation,
    ClosedLoop,
    CostGradient,
    GradientCost,
    MatrixSpec,
    ScalarSpec,
)

logger = logging.getLogger(__name__)

#: Status name of an LQR candidate without a stabilizing Riccati solution.
CARE_FAILURE = "care_failure"
#: Relative margin by which J must exceed a threshold before a run is cut (covers the
#: integrator's round-off in J, which never decreases in exact arithmetic).
CUT_MARGIN = 1e-9
#: Channel names of the body rates and torques (``simulate``, ``closed_loop``).
OMEGA_NAMES = ("w1", "w2", "w3")
TORQUE_NAMES = ("u1", "u2", "u3")


def kernel_cutoffs(thresholds: np.ndarray, ok: np.ndarray, hard_cost: float) -> np.ndarray:
    """Per-run kernel cutoffs on J from the optimizer's thresholds.

    Parameters
    ----------
    thresholds : ndarray, shape (B,)
        Thresholds (N²·m²·s).
    ok : ndarray of bool, shape (B,)
        Candidates with a gain (the others get their flat failure cost, never cut).
    hard_cost : float
        Flat cost of non-finite runs: a threshold at or above it cuts nothing.

    Returns
    -------
    ndarray, shape (B,)
        ``threshold + CUT_MARGIN · |threshold|`` where a cut is allowed, else ``inf``.
    """
    thr = np.asarray(thresholds, dtype=float).reshape(ok.shape)
    allowed = ok & (thr < hard_cost)  # NaN compares False
    return np.where(allowed, thr + CUT_MARGIN * np.abs(thr), np.inf)


def status_strings(status: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Status names: ``"converged"``, the integrator failure name, or ``"care_failure"``."""
    names = []
    for s, good in zip(status, ok):
        if not good:
            names.append(CARE_FAILURE)
        elif int(s) == integrate.EVENT:
            names.append("converged")
        else:
            names.append(integrate.STATUS_NAMES[int(s)])
    return np.asarray(names, dtype=object)


class AttitudeProblem(AttitudeScenarios):
    """Attitude closed loop with a linear gain built from the tuned matrices.

    The training scenario and the held-out set come from
    :class:`~penaltyrun.problems.attitude.scenarios.AttitudeScenarios`.

    Parameters
    ----------
    name : str
        Registered problem name.
    case : str
        Case name (one of :data:`CASES`).
    params : Params
        Validated parameters.
    matrices : tuple of MatrixSpec
        The tuned matrices.
    gains : callable
        ``gains(mats) -> (G, ok)`` with ``mats[name]`` of shape (B, N, N), ``G`` of shape
        (B, 3, 6) and ``ok`` (B,) bool (False: no gain could be built).
    """

    def __init__(self, name: str, case: str, params: Params, matrices: tuple[MatrixSpec, ...],
                 gains: Callable[[Mapping[str, np.ndarray]], tuple[np.ndarray, np.ndarray]]
                 ) -> None:
        self.name = name
        self.case = case
        self.params = params
        self.matrices = matrices
        self.scalars: tuple[ScalarSpec, ...] = ()
        self.gains = gains
        self.inertia = params.inertia_matrix()
        self.inertia_inv = np.linalg.inv(self.inertia)
        self.y0 = params.initial_state()
        self.d0 = float(params.event_distance(self.y0))

    def run(self, G: np.ndarray, y0: np.ndarray | None = None,
            cutoff: np.ndarray | None = None, t_max: float | None = None
            ) -> tuple[np.ndarray, ...]:
        """Raw kernel runs (see :func:`penaltyrun.dynamics.attitude.simulate_batch`).

        Parameters
        ----------
        G : ndarray, shape (B, 3, 6)
            Gains.
        y0 : ndarray, shape (S, 7), optional
            Initial states (default: the problem's); B or S may be 1 (broadcast).
        cutoff : ndarray, shape (max(B, S),), optional
            Kernel cutoff on J per run (``inf``: none).
        t_max : float, optional
            Horizon cap (s); default the parameter ``t_max``.

        Returns
        -------
        t_end, energy, dist, status : ndarray, shape (max(B, S),)
        """
        p = self.params
        y0 = self.y0[None] if y0 is None else y0
        return kernel.simulate_batch(
            np.ascontiguousarray(G, dtype=float), np.ascontiguousarray(y0, dtype=float),
            self.inertia, self.inertia_inv, float(p.t_max if t_max is None else t_max),
            float(p.tol), p.saturation(),
            float(p.rtol), float(p.atol), float(p.max_step), float(p.event_spacing),
            int(p.n_event_samples),
            int(p.max_steps), *p.event_weights(),
            None if cutoff is None else np.ascontiguousarray(cutoff, dtype=float))

    def _finish(self, G: np.ndarray, ok: np.ndarray, y0: np.ndarray | None,
                d0: Any, thresholds: np.ndarray | None = None) -> dict[str, np.ndarray]:
        n = max(G.shape[0], 1 if y0 is None else y0.shape[0])
        form = self.params.objective_form
        cutoff = None
        if thresholds is not None:
            cutoff = kernel_cutoffs(cost_thresholds(form, thresholds), ok,
                                    HARD_FAILURE_FACTOR * self.params.failure_penalty)
        G = np.where(ok[:, None, None], G, 0.0)
        if self.params.criterion == criteria.DEADLINE:
            t_end, energy, dist, status = self.run(G, y0, cutoff)
            cost = graded_cost(energy, dist, d0, status, self.params.failure_penalty)
            term = np.zeros_like(energy)
        else:
            res = attitude_criteria.finish(self, G, ok, y0, d0, cutoff)
            t_end, energy, dist, status, cost, term = (res[k] for k in (
                "t_final", "energy", "final_distance", "status", "cost", "terminal_cost"))
        ok_full = np.broadcast_to(ok, (n,))
        cost = np.where(ok_full, cost, HARD_FAILURE_FACTOR * self.params.failure_penalty)
        converged = ok_full & (status == integrate.EVENT)
        return {"cost": cost, "converged": converged, "status": status_strings(status, ok_full),
                "energy": energy, "t_final": t_end, "final_distance": dist,
                "terminal_cost": term,
                "objective": optimizer_values(form, cost, energy, dist, self.params.tol,
                                              status, ok_full)}

    def evaluate_batch(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, np.ndarray] | None = None,
        thresholds: np.ndarray | None = None,
    ) -> BatchEvaluation:
        """Costs of B candidates; ``mats[name]`` has shape (B, N, N) (not re-validated).

        ``thresholds`` (shape (B,), optional): exact cutoff per candidate (N²·m²·s,
        ``inf``: none); see the module docstring.
        """
        G, ok = self.gains(mats)
        res = self._finish(G, ok, None, self.d0, thresholds)
        return BatchEvaluation(cost=res["cost"], converged=res["converged"],
                               status=res["status"], objective=res["objective"])

    def _check(self, mats: Mapping[str, Any]) -> dict[str, np.ndarray]:
        from penaltyrun.problems.base import check_spd

        out = {}
        for spec in self.matrices:
            if spec.name not in mats:
                raise ConfigError(f"matrices.{spec.name}", "missing matrix")
            out[spec.name] = check_spd(f"matrices.{spec.name}", mats[spec.name], spec.size)
        return out

    def gain(self, mats: Mapping[str, Any]) -> np.ndarray:
        """Validated gain G (3, 6) of one candidate.

        Raises
        ------
        ConfigError
            Malformed matrices, or (LQR) no stabilizing Riccati solution.
        """
        checked = self._check(mats)
        G, ok = self.gains({k: v[None] for k, v in checked.items()})
        if not ok[0]:
            raise ConfigError("matrices", "no stabilizing Riccati solution for these Q, R")
        return G[0]

    def evaluate(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, float] | None = None
    ) -> dict[str, Any]:
        """Detailed evaluation of one candidate; JSON-serializable.

        Returns
        -------
        dict
            ``problem``, ``case``, ``cost`` (objective), ``energy`` (J at the end, N²·m²·s),
            ``converged``, ``status``, ``t_final`` (s), ``t_max`` (s), ``final_distance``,
            ``initial_distance``, ``gain`` (3×6 nested list, u = −gain·(q_v, ω)),
            ``objective_form`` and ``objective`` (the value the optimizer saw); under a
            well-posed criterion also the keys of
            :func:`~penaltyrun.problems.attitude.criteria.detail`.
        """
        checked = self._check(mats)
        G, ok = self.gains({k: v[None] for k, v in checked.items()})
        res = self._finish(G, ok, None, self.d0)
        return {
            "problem": self.name,
            "case": self.case,
            "cost": float(res["cost"][0]),
            "energy": float(res["energy"][0]),
            "converged": bool(res["converged"][0]),
            "status": str(res["status"][0]),
            "t_final": float(res["t_final"][0]),
            "t_max": float(self.params.t_max),
            "final_distance": float(res["final_distance"][0]),
            "initial_distance": self.d0,
            "tol": float(self.params.tol),
            "event_weights": list(self.params.event_weights()),
            "gain": G[0].tolist(),
            "objective_form": self.params.objective_form,
            "objective": float(res["cost"][0] if res["objective"] is None
                               else res["objective"][0]),
            **attitude_criteria.detail(self.params, res),
        }

    def gradient(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None
                 ) -> CostGradient:
        """Cost of one candidate and its exact gradient with respect to its matrices under
        ``criterion`` ``terminal`` or ``time_energy``
        (:mod:`~penaltyrun.problems.attitude.gradient`), or the reason there is none (always
        under ``deadline``)."""
        from penaltyrun.problems.attitude.gradient import attitude_gradient

        return attitude_gradient(self, mats)

    def gradient_cost(self) -> GradientCost:
        """What one gradient costs in evaluations for this law under this criterion:
        measured by ``bench/attitude_gradient_cost.py``, table in ``bench/README.md``
        (:func:`~penaltyrun.problems.gradient_costs.attitude_cost`)."""
        return gradient_costs.attitude_cost(self.name, self.params.criterion)

    def simulate(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, float] | None = None,
        n_points: int = 500,
    ) -> dict[str, np.ndarray]:
        """Time histories of one candidate for plots, up to its event time (or ``t_max``).

        The end time comes from the production kernel; the histories are scipy DOP853 dense
        output at the problem's tolerances.

        Returns
        -------
        dict
            ``t`` (n,) s, ``q`` (n, 4), ``w`` (n, 3) rad/s, ``u`` (n, 3) N·m, ``J`` (n,),
            ``dist`` (n,) distance to the target; ``channels`` (names of the columns of
            ``q``, ``w``, ``u``) and ``limits`` (``u``: ±``u_max`` when saturated).
        """
        G = self.gain(mats)
        t_end = float(self._finish(G[None], np.ones(1, dtype=bool), None, self.d0)["t_final"][0])
        out = trajectory(G, self.params, t_end, n_points, self.y0)
        u_max = self.params.saturation()
        out["channels"] = {"q": ["q0", "q1", "q2", "q3"], "w": list(OMEGA_NAMES),
                           "u": list(TORQUE_NAMES)}
        out["limits"] = {"u": (-u_max, u_max)} if np.isfinite(u_max) else {}
        return out

    def closed_loop(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None
                    ) -> ClosedLoop | None:
        """The law linearized at the target q = (1, 0, 0, 0), ω = 0 with x = (q_v, ω):
        q̇_v = ½ ω, I ω̇ = u (the gyroscopic term is quadratic), u = −G x, so
        ẋ = (A − B G) x with A = [[0, ½I₃], [0, 0]], B = [[0], [I⁻¹]]; the torque limit is
        inactive at the target. None when (LQR) no stabilizing Riccati solution exists."""
        checked = self._check(mats)
        G, ok = self.gains({k: v[None] for k, v in checked.items()})
        if not ok[0]:
            return None
        A = np.zeros((6, 6))
        A[:3, 3:] = 0.5 * np.eye(3)
        B = np.vstack([np.zeros((3, 3)), self.inertia_inv])
        return ClosedLoop(A - B @ G[0], "continuous", gain=G[0],
                          state_names=("q1", "q2", "q3") + OMEGA_NAMES,
                          input_names=TORQUE_NAMES)

    def evaluate_states(self, mats: Mapping[str, Any], y0: Any) -> dict[str, np.ndarray]:
        """Evaluate one candidate from many initial states (one kernel call).

        Parameters
        ----------
        mats : mapping
            The candidate's matrices, each (N, N).
        y0 : array_like, shape (n, 7)
            Initial (q, ω); quaternions are normalized to unit length with q0 ≥ 0 here.

        Returns
        -------
        dict of ndarray, each of length n
            ``cost``, ``converged``, ``status``, ``energy``, ``t_final``, ``final_distance``,
            ``initial_distance`` (weighted event distances) and ``y0`` (n, 7) as run.
        """
        G = self.gain(mats)
        y0 = np.array(np.atleast_2d(y0), dtype=float)
        if y0.ndim != 2 or y0.shape[1] != 7:
            raise ConfigError("y0", f"expected shape (n, 7), got {y0.shape}")
        y0[:, :4] = normalize_quaternion(y0[:, :4])
        d0 = self.params.event_distance(y0)
        res = self._finish(G[None], np.ones(1, dtype=bool), y0, d0)
        res.pop("objective")
        res.pop("terminal_cost")
        res.update({"initial_distance": d0, "y0": y0})
        return res

    def evaluate_grid(self, mats: Mapping[str, Any], attitudes_deg: Any) -> dict[str, np.ndarray]:
        """Evaluate one candidate from many initial attitudes (Euler angles, degrees).

        Rates, inertia, horizon and tolerances are this problem's. See :func:`evaluate_grid`.
        """
        att = np.atleast_2d(np.asarray(attitudes_deg, dtype=float))
        if att.ndim != 2 or att.shape[1] != 3:
            raise ConfigError("attitudes_deg", f"expected shape (n, 3), got {att.shape}")
        q = euler_to_quaternion(att)
        y0 = np.concatenate([q, np.broadcast_to(np.asarray(self.params.omega0, float),
                                                (q.shape[0], 3))], axis=1)
        res = self.evaluate_states(mats, y0)
        res.pop("y0")
        res.update({"attitudes_deg": att, "q0": q})
        return res


def evaluate_grid(problem: Any, mats: Mapping[str, Any], attitudes_deg: Any,
                  params: Mapping[str, Any] | None = None) -> dict[str, np.ndarray]:
    """Evaluate tuned matrices over a grid of initial attitudes (robustness study).

    All starts run in one call of the compiled kernel with the same gain.

    Parameters
    ----------
    problem : str or AttitudeProblem
        A problem instance (its rates, inertia, horizon and tolerances are used), or a
        registered name (``"attitude_lyapunov"`` / ``"attitude_lqr"``), built for the
        ``rest_to_rest`` case with ``params`` overrides.
    mats : mapping
        The candidate's matrices (e.g. ``{"Kp": ..., "Kd": ...}``), each (N, N).
    attitudes_deg : array_like, shape (n, 3)
        (yaw, pitch, roll) in degrees, intrinsic Z-Y-X (e.g. :func:`robustness_grid`).
    params : mapping, optional
        Overrides when ``problem`` is a name.

    Returns
    -------
    dict of ndarray, each of length n
        ``cost``, ``converged``, ``status``, ``energy``, ``t_final``, ``final_distance``,
        ``initial_distance``, plus ``attitudes_deg`` (n, 3) and ``q0`` (n, 4) (normalized,
        q0 ≥ 0).
    """
    if isinstance(problem, str):
        from penaltyrun import problems as registry

        problem = registry.module(problem).make_problem("rest_to_rest", dict(params or {}))
    return problem.evaluate_grid(mats, attitudes_deg)


__all__ = [
    "ATTITUDE_TYPES",
    "CARE_FAILURE",
    "CASES",
    "CASE_PARAMS",
    "CUT_MARGIN",
    "DEFAULT_CASE",
    "HARD_FAILURE_FACTOR",
    "VARIANT_IGNORE",
    "AttitudeProblem",
    "Params",
    "_rhs_numpy",
    "attitude_to_quaternion",
    "build_params",
    "euler_to_quaternion",
    "evaluate_grid",
    "graded_cost",
    "kernel_cutoffs",
    "mrp_to_quaternion",
    "normalize_quaternion",
    "perturbed_states",
    "plot_histories",
    "plot_quaternions",
    "plot_rates",
    "plot_torques",
    "reference_run",
    "robustness_grid",
    "status_strings",
    "trajectory",
    "validate",
]
