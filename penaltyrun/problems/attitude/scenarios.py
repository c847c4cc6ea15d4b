"""Training scenario and held-out set of the attitude problems (a mixin of
:class:`~penaltyrun.problems.attitude.common.AttitudeProblem`).

The training scenario is the case's initial state; the held-out set is rest-to-rest starts
from a grid of attitudes plus seeded perturbations of the training state (see
:meth:`AttitudeScenarios.holdout_scenarios`). The mixin needs ``params``, ``case``, ``y0``
and ``evaluate_states`` from the problem.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.problems import criteria, horizon
from penaltyrun.problems.attitude import sublevel
from penaltyrun.problems.attitude.frames import (
    euler_to_quaternion,
    perturbed_states,
    quaternion_to_euler,
    robustness_grid,
)
from penaltyrun.problems.basins import BasinAxes, arrival_times

logger = logging.getLogger(__name__)


class AttitudeScenarios:
    """Training-scenario and held-out methods shared by the attitude problems."""

    params: Any
    case: str
    y0: np.ndarray

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
        :func:`~penaltyrun.problems.attitude.frames.perturbed_states`).

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
        :meth:`holdout_scenarios`) at the training deadline ``t_max`` and at the held-out
        horizon (``holdout_horizon_factor``, ``holdout_t_max_cap``; see
        :mod:`penaltyrun.problems.horizon`); inertia, event and tolerances are this
        problem's. Under a well-posed criterion the held-out set is judged by the same
        criterion once, at its own horizon (``free_time_cap`` or ``t_max``), which is then
        both ``horizon`` and ``training_horizon``.

        Returns
        -------
        dict of ndarray or None
            Per scenario, at the held-out horizon: ``scenario``, ``cost``, ``converged``,
            ``status``, ``energy``, ``t_final``, ``arrival_time``, ``final_distance``,
            ``initial_distance``, ``attitudes_deg`` (NaN rows for perturbed states),
            ``q_init`` (n, 4), ``omega_init`` (n, 3); at the training deadline the fields
            of :data:`~penaltyrun.problems.horizon.DEADLINE_FIELDS`; ``horizon`` and
            ``training_horizon`` (s). ``None`` if the set is empty or the candidate has no
            gain (LQR without a stabilizing Riccati solution).
        """
        sc = self.holdout_scenarios()
        if not len(sc["scenario"]):
            return None
        p = self.params
        train_t = criteria.run_horizon(p)
        long_t = criteria.judged_at(p, train_t, p.t_max)
        try:
            short = self.evaluate_states(mats, sc["y0"])
            res = horizon.at_horizon(self, long_t).evaluate_states(mats, sc["y0"]) \
                if long_t > train_t else dict(short)
        except ConfigError as exc:
            logger.warning("no held-out evaluation: %s", exc)
            return None
        y0 = res.pop("y0")
        res = horizon.combine(short, res, train_t, long_t)
        res.update({"scenario": sc["scenario"], "attitudes_deg": sc["attitudes_deg"],
                    "q_init": y0[:, :4], "omega_init": y0[:, 4:7]})
        return res

    def basin_axes(self) -> BasinAxes:
        """Initial attitudes over yaw and pitch (roll 0, degrees), the case's initial
        rates; the training attitude is marked when its roll is 0."""
        yaw, pitch, roll = quaternion_to_euler(self.y0[:4])
        marker = (float(yaw), float(pitch)) if abs(roll) < 1e-6 else None
        return BasinAxes(("yaw (deg)", "pitch (deg)"), (-180.0, -89.0), (180.0, 89.0),
                         "s", marker)

    def basin_runs(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None,
                   points: np.ndarray) -> dict[str, Any]:
        """One candidate from the attitudes (yaw, pitch) ``points`` (P, 2), roll 0, at the
        horizon the held-out set is judged at (the criterion's own horizon where it has
        one)."""
        p = self.params
        train_t = criteria.run_horizon(p)
        long_t = criteria.judged_at(p, train_t, p.t_max)
        att = np.column_stack([points, np.zeros(len(points))])
        prob = horizon.at_horizon(self, long_t) if long_t > train_t else self
        runs = prob.evaluate_grid(mats, att)
        return {"converged": runs["converged"], "cost": runs["cost"], "horizon": long_t,
                "arrival_time": arrival_times(runs["converged"], runs["t_final"])}

    def sublevel_set(self, mats: Mapping[str, Any]) -> sublevel.SubLevelSet | None:
        """The sub-level-set estimate {V ≤ c} of the region of attraction of this law with
        ``mats`` (:mod:`penaltyrun.problems.attitude.sublevel`); None under a torque limit
        or when the linearized loop is unstable."""
        return sublevel.estimate(self.gain(mats), self.inertia,
                                 saturated=np.isfinite(self.params.saturation()))

    def basin_region(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None,
                     points: np.ndarray) -> dict[str, Any] | None:
        """Which points (P, 2) of the basin plane (yaw, pitch; roll 0; the case's rates)
        lie in the sampled sub-level set {V ≤ c} (``inside`` (P,) bool), with ``level`` c,
        the ``certified`` level and a ``label``; None without an estimate."""
        region = self.sublevel_set(mats)
        if region is None:
            return None
        att = np.column_stack([points, np.zeros(len(points))])
        q = euler_to_quaternion(att)
        q = np.where(q[:, :1] < 0.0, -q, q)  # the runs start with q0 >= 0
        w = np.broadcast_to(np.asarray(self.params.omega0, float), (len(q), 3))
        x = np.column_stack([q[:, 1:], w])
        return {"inside": region.value(x) <= region.sampled, "level": region.sampled,
                "certified": region.certified,
                "label": "sampled sub-level set {V ≤ c} of V = xᵀPx (Lyapunov equation "
                         "of the linearized loop)"}


__all__ = ["AttitudeScenarios"]
