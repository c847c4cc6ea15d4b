"""Shared parts of the spacecraft attitude problems (``attitude_lyapunov``, ``attitude_lqr``).

Rigid spacecraft, quaternion kinematics and Euler's equation (see
:mod:`penaltyrun.dynamics.attitude`), a linear state feedback u = −G (q_v, ω) whose gain
G (3 × 6) comes from the tuned matrices (PD: G = [K_p, K_d]; LQR: G = R⁻¹BᵀP), and the
minimum-energy cost J = ∫ ½ uᵀu dt (N²·m²·s) up to the FIRST time the weighted distance
d = ‖(w_q0 (q0 − 1), w_qv q_v, w_ω ω)‖ falls to ``tol`` (default weights 1, 1, 1).

Cost of a candidate (always finite):

* event fired before ``t_max``: ``cost = J(t_event)``;
* otherwise (``horizon``, ``step_failure``): the graded penalty
  ``cost = J(t_end) + failure_penalty · (1 + d(t_end) / d(0))``, so every failure costs
  more than ``failure_penalty`` and failures are ranked by how close they got;
* non-finite results (``nonfinite``) and LQR gains whose Riccati equation has no
  stabilizing solution (``care_failure``): ``cost = 1000 · failure_penalty``.

The pieces live in :mod:`~penaltyrun.problems.attitude_params` (parameters, cases),
:mod:`~penaltyrun.problems.attitude_frames` (attitude representations, held-out states),
:mod:`~penaltyrun.problems.attitude_reference` (scipy references) and
:mod:`~penaltyrun.problems.attitude_plots`; this module holds the problem object and
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
from penaltyrun.problems.attitude_frames import (
    ATTITUDE_TYPES,
    attitude_to_quaternion,
    euler_to_quaternion,
    mrp_to_quaternion,
    normalize_quaternion,
    perturbed_states,
    robustness_grid,
)
from penaltyrun.problems.attitude_params import (
    CASE_PARAMS,
    CASES,
    DEFAULT_CASE,
    VARIANT_IGNORE,
    Params,
    build_params,
    validate,
)
from penaltyrun.problems.attitude_plots import (
    plot_histories,
    plot_quaternions,
    plot_rates,
    plot_torques,
)
from penaltyrun.problems.attitude_reference import (
    HARD_FAILURE_FACTOR,
    _rhs_numpy,
    graded_cost,
    reference_run,
    trajectory,
)
from penaltyrun.problems.base import BatchEvaluation, MatrixSpec, ScalarSpec

logger = logging.getLogger(__name__)

#: Status name of an LQR candidate without a stabilizing Riccati solution.
CARE_FAILURE = "care_failure"


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


class AttitudeProblem:
    """Attitude closed loop with a linear gain built from the tuned matrices.

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

    def run(self, G: np.ndarray, y0: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
        """Raw kernel runs (see :func:`penaltyrun.dynamics.attitude.simulate_batch`).

        Parameters
        ----------
        G : ndarray, shape (B, 3, 6)
            Gains.
        y0 : ndarray, shape (S, 7), optional
            Initial states (default: the problem's); B or S may be 1 (broadcast).

        Returns
        -------
        t_end, energy, dist, status : ndarray, shape (max(B, S),)
        """
        p = self.params
        y0 = self.y0[None] if y0 is None else y0
        return kernel.simulate_batch(
            np.ascontiguousarray(G, dtype=float), np.ascontiguousarray(y0, dtype=float),
            self.inertia, self.inertia_inv, float(p.t_max), float(p.tol), p.saturation(),
            float(p.rtol), float(p.atol), float(p.max_step), int(p.n_event_samples),
            int(p.max_steps), *p.event_weights())

    def _finish(self, G: np.ndarray, ok: np.ndarray, y0: np.ndarray | None,
                d0: Any) -> dict[str, np.ndarray]:
        n = max(G.shape[0], 1 if y0 is None else y0.shape[0])
        t_end, energy, dist, status = self.run(np.where(ok[:, None, None], G, 0.0), y0)
        ok_full = np.broadcast_to(ok, (n,))
        cost = graded_cost(energy, dist, d0, status, self.params.failure_penalty)
        cost = np.where(ok_full, cost, HARD_FAILURE_FACTOR * self.params.failure_penalty)
        converged = ok_full & (status == integrate.EVENT)
        return {"cost": cost, "converged": converged, "status": status_strings(status, ok_full),
                "energy": energy, "t_final": t_end, "final_distance": dist}

    def evaluate_batch(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, np.ndarray] | None = None
    ) -> BatchEvaluation:
        """Costs of B candidates; ``mats[name]`` has shape (B, N, N) (not re-validated)."""
        G, ok = self.gains(mats)
        res = self._finish(G, ok, None, self.d0)
        return BatchEvaluation(cost=res["cost"], converged=res["converged"],
                               status=res["status"])

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
            ``initial_distance``, ``gain`` (3×6 nested list, u = −gain·(q_v, ω)).
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
        }

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
            ``dist`` (n,) distance to the target.
        """
        G = self.gain(mats)
        t_end = float(self.run(G[None])[0][0])
        return trajectory(G, self.params, t_end, n_points, self.y0)

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

    def training_scenario(self) -> dict[str, Any]:
        """The scenario the matrices are tuned on (this case's initial state), JSON-ready."""
        return {"scenario": self.case, "q0": self.y0[:4].tolist(),
                "omega0": self.y0[4:7].tolist()}

    def scenario_key(self) -> tuple:
        """Hashable key of the training scenario: initial (q, ω) rounded to 1e-9."""
        return tuple(np.round(self.y0, 9).tolist())

    def sample_training(self, n: int, seed: int) -> list[dict[str, Any]]:
        """``n`` seeded training states: perturbations of this case's initial state with the
        held-out sizes (``holdout_perturb_deg``, ``holdout_rate_rel``) and ``seed``.

        Returns
        -------
        list of dict
            Overrides ``{"attitude_type": "quaternion", "attitude": q, "omega0": ω}``.
        """
        p = self.params
        q, w = perturbed_states(self.y0[:4], self.y0[4:7], n, p.holdout_perturb_deg,
                                p.holdout_rate_rel, seed)
        return [{"attitude_type": "quaternion", "attitude": tuple(qi.tolist()),
                 "omega0": tuple(wi.tolist())} for qi, wi in zip(q, w)]

    def holdout_keys(self) -> set[tuple]:
        """Keys (as :meth:`scenario_key`) of the held-out scenarios."""
        return {tuple(np.round(y, 9).tolist()) for y in self.holdout_scenarios()["y0"]}

    def holdout_scenarios(self) -> dict[str, np.ndarray]:
        """The held-out set, disjoint from the training scenario.

        Rest-to-rest (ω0 = 0) from the attitudes of :func:`robustness_grid` (``holdout_n``,
        ``holdout_lo_deg``, ``holdout_hi_deg``), then ``holdout_n_perturbed`` seeded
        perturbations of this case's initial attitude and rates (see
        :func:`~penaltyrun.problems.attitude_frames.perturbed_states`).

        Returns
        -------
        dict
            ``scenario`` (n,) labels (``grid:yaw,pitch,roll`` or ``perturbed:k``), ``y0``
            (n, 7) initial states, ``attitudes_deg`` (n, 3) (NaN for perturbed states).
        """
        p = self.params
        labels: list[str] = []
        states, angles = [np.zeros((0, 7))], [np.zeros((0, 3))]
        if p.holdout_n > 0:
            grid = robustness_grid(p.holdout_n, p.holdout_lo_deg, p.holdout_hi_deg)
            states.append(np.concatenate([euler_to_quaternion(grid),
                                          np.zeros((grid.shape[0], 3))], axis=1))
            angles.append(grid)
            labels += [f"grid:{a:g},{b:g},{c:g}" for a, b, c in grid]
        if p.holdout_n_perturbed > 0:
            q, w = perturbed_states(self.y0[:4], self.y0[4:7], p.holdout_n_perturbed,
                                    p.holdout_perturb_deg, p.holdout_rate_rel, p.holdout_seed)
            states.append(np.concatenate([q, w], axis=1))
            angles.append(np.full((q.shape[0], 3), np.nan))
            labels += [f"perturbed:{k}" for k in range(q.shape[0])]
        return {"scenario": np.asarray(labels, dtype=object),
                "y0": np.concatenate(states), "attitudes_deg": np.concatenate(angles)}

    def holdout(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None
                ) -> dict[str, np.ndarray] | None:
        """Evaluate one candidate on the held-out set (runner hook, see
        :meth:`holdout_scenarios`); inertia, horizon, event and tolerances are this
        problem's.

        Returns
        -------
        dict of ndarray or None
            Per scenario: ``scenario``, ``cost``, ``converged``, ``status``, ``energy``,
            ``t_final``, ``final_distance``, ``initial_distance``, ``attitudes_deg`` (NaN
            rows for perturbed states), ``q_init`` (n, 4), ``omega_init`` (n, 3). ``None``
            if the set is empty or the candidate has no gain (LQR without a stabilizing
            Riccati solution).
        """
        sc = self.holdout_scenarios()
        if not len(sc["scenario"]):
            return None
        try:
            res = self.evaluate_states(mats, sc["y0"])
        except ConfigError as exc:
            logger.warning("no held-out evaluation: %s", exc)
            return None
        y0 = res.pop("y0")
        res.update({"scenario": sc["scenario"], "attitudes_deg": sc["attitudes_deg"],
                    "q_init": y0[:, :4], "omega_init": y0[:, 4:7]})
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
