"""Multi-scenario tuning: one objective over several training scenarios of a problem.

A problem's parameters may carry ``train_scenarios`` (a list of parameter overrides, each
one training scenario on top of the case and the other overrides; ``{}`` is the case's own
scenario), ``train_sample`` / ``train_seed`` (a seeded sample of that many scenarios drawn
by the problem's ``sample_training(n, seed)``, appended to the list) and
``train_aggregate`` (``mean`` or ``max``). The tuned objective of a candidate
is then the mean (or the max) of its costs over the training scenarios, each cost as the
single-scenario problem defines it (graded penalty included, so it stays finite); the
candidate converges only if it converges in every training scenario.

The held-out set stays the one of the problem built without ``train_scenarios`` (see each
problem's ``holdout_scenarios``) and must be disjoint from the training scenarios: an
overlap, an empty list or an unknown aggregate is a config error.

Problems take part through three methods: ``scenario_key()`` (hashable key of the training
scenario), ``holdout_keys()`` (keys of the held-out scenarios) and the usual
``make_problem`` / ``evaluate`` / ``evaluate_batch``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from types import MappingProxyType, ModuleType
from typing import Any, ClassVar

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.problems.base import (
    BatchEvaluation,
    CostGradient,
    accepts_thresholds,
    gradient_support,
)
from penaltyrun.typed import is_int

AGGREGATES = ("mean", "max")
KEYS = ("train_scenarios", "train_aggregate", "train_sample", "train_seed")


@dataclass(frozen=True)
class TrainingParams:
    """Multi-scenario tuning settings shared by every problem's ``Params``.

    Attributes
    ----------
    train_scenarios : tuple of mapping or None
        Training scenarios as parameter overrides; ``None``: single-scenario tuning (the
        case itself).
    train_aggregate : str
        ``"mean"`` or ``"max"`` of the per-scenario costs.
    train_sample : int
        Further training scenarios drawn by the problem's ``sample_training`` (0: none).
    train_seed : int
        Seed of that sample (different from the held-out seeds).
    HOLDOUT_OFF : mapping (class attribute)
        Overrides that empty a problem's held-out set: training scenarios are built with
        them, since only the run's own held-out set counts (and a training scenario must not
        fail on a held-out set of its own, e.g. one made from its own departure).
    """

    HOLDOUT_OFF: ClassVar[Mapping[str, Any]] = MappingProxyType({})
    train_scenarios: tuple | None = None
    train_aggregate: str = "mean"
    train_sample: int = 0
    train_seed: int = 1


def _aggregate(costs: np.ndarray, how: str) -> np.ndarray:
    return costs.mean(axis=0) if how == "mean" else costs.max(axis=0)


class MultiScenarioProblem:
    """A problem whose objective aggregates several training scenarios.

    Parameters
    ----------
    base : Problem
        The problem without ``train_scenarios`` (its held-out set is the one used).
    scenarios : list of Problem
        One problem per training scenario.
    overrides : list of dict
        The training scenarios' overrides (recorded in results).
    aggregate : str
        ``"mean"`` or ``"max"``.
    params : dataclass, optional
        Parameters to report (default: the base's with the training settings filled in).
    """

    def __init__(self, base: Any, scenarios: list[Any], overrides: list[dict[str, Any]],
                 aggregate: str, params: Any = None) -> None:
        self.base = base
        self.scenarios = scenarios
        self.overrides = overrides
        self.aggregate = aggregate
        self.name = base.name
        self.case = base.case
        self.matrices = base.matrices
        self.scalars = base.scalars
        self.params = params if params is not None else replace(
            base.params, train_scenarios=tuple(overrides), train_aggregate=aggregate)

    def __getattr__(self, name: str) -> Any:
        # Anything not overridden (plots, histories, problem-specific helpers) is the base
        # problem's.
        if name == "base":
            raise AttributeError(name)
        if name == "gradient":  # the aggregate's, never the base scenario's alone
            if all(not gradient_support(p) for p in self.scenarios):
                return self._gradient
            raise AttributeError(name)
        return getattr(self.base, name)

    def _gradient(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None
                  ) -> CostGradient:
        """Gradient of the aggregate (the ``gradient`` hook when every training scenario
        has one): the mean of the scenarios' gradients, or for ``max`` the gradient of the
        one scenario whose cost is the largest (none where two tie: a kink)."""
        parts = [p.gradient(mats, scalars) for p in self.scenarios]
        costs = np.asarray([g.cost for g in parts], dtype=float)
        cost = float(_aggregate(costs[:, None], self.aggregate)[0])
        failed = [g for g in parts if not g.exists]
        status = next((g.status for g in parts if g.status != "converged"), "converged")
        if failed:
            return CostGradient(cost, status, None, {}, f"training scenario: {failed[0].reason}")
        if self.aggregate == "mean":
            weights = np.full(len(parts), 1.0 / len(parts))
        else:
            order = np.argsort(costs)
            if len(costs) > 1 and costs[order[-1]] - costs[order[-2]] <= \
                    1e-9 * max(1.0, abs(costs[order[-1]])):
                return CostGradient(cost, status, None, {}, "the largest training scenario "
                                    "costs tie (the max has a kink there)")
            weights = np.zeros(len(parts))
            weights[order[-1]] = 1.0
        mats_out = {k: sum(w * np.asarray(g.matrices[k]) for w, g in zip(weights, parts))
                    for k in parts[0].matrices}
        sc_out = {k: float(sum(w * g.scalars[k] for w, g in zip(weights, parts)))
                  for k in (parts[0].scalars or {})}
        return CostGradient(cost, status, mats_out, sc_out, "")

    def evaluate_batch(self, mats: Mapping[str, np.ndarray],
                       scalars: Mapping[str, np.ndarray] | None = None,
                       thresholds: np.ndarray | None = None) -> BatchEvaluation:
        """Aggregated costs of B candidates over the training scenarios.

        ``thresholds`` (exact cutoff, shape (B,)) are passed to every scenario that takes
        them when the aggregate is ``max`` (a scenario's bound above the threshold puts the
        max above it too); the ``mean`` ignores them (one scenario's cost says nothing of
        the mean without bounds on the others').
        """
        cut = thresholds if self.aggregate == "max" else None
        evals = [p.evaluate_batch(mats, scalars, thresholds=cut)
                 if cut is not None and accepts_thresholds(p) else p.evaluate_batch(mats, scalars)
                 for p in self.scenarios]
        cost = _aggregate(np.stack([e.cost for e in evals]), self.aggregate)
        conv = np.stack([e.converged for e in evals])
        status = []
        for b in range(cost.shape[0]):
            bad = [str(e.status[b]) for e in evals if not e.converged[b]]
            status.append(bad[0] if bad else "converged")
        return BatchEvaluation(cost=cost, converged=conv.all(axis=0),
                               status=np.asarray(status, dtype=object))

    def evaluate(self, mats: Mapping[str, Any],
                 scalars: Mapping[str, float] | None = None) -> dict[str, Any]:
        """Detailed evaluation: the aggregate plus every training scenario's result.

        Returns
        -------
        dict
            ``cost`` (aggregate), ``converged`` (all), ``status`` (first failure or
            ``converged``), ``t_final`` (largest over scenarios), ``train_aggregate``,
            ``train_scenarios`` (list of {``overrides``, ``cost``, ``converged``,
            ``status``, ``t_final``}), ``problem``, ``case``.
        """
        details = [p.evaluate(mats, scalars) for p in self.scenarios]
        costs = np.array([[d["cost"]] for d in details])
        bad = [d["status"] for d in details if not d["converged"]]
        return {
            "problem": self.name, "case": self.case,
            "cost": float(_aggregate(costs, self.aggregate)[0]),
            "converged": all(bool(d["converged"]) for d in details),
            "status": bad[0] if bad else "converged",
            "t_final": max(float(d["t_final"]) for d in details),
            "train_aggregate": self.aggregate,
            "train_scenarios": [{"overrides": o, "cost": float(d["cost"]),
                                 "converged": bool(d["converged"]), "status": d["status"],
                                 "t_final": float(d["t_final"])}
                                for o, d in zip(self.overrides, details)],
        }

    def simulate(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None
                 ) -> dict[str, np.ndarray]:
        """Histories of the first training scenario."""
        return self.scenarios[0].simulate(mats, scalars)

    def holdout(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None
                ) -> Any:
        """The base problem's held-out evaluation (disjoint from the training scenarios)."""
        return self.base.holdout(mats, scalars)


def build(mod: ModuleType, case: str, overrides: Mapping[str, Any]) -> Any:
    """``mod.make_problem`` with multi-scenario tuning when ``train_scenarios`` is given.

    Raises
    ------
    ConfigError
        Empty or malformed ``train_scenarios``, an unknown ``train_aggregate``, or a training
        scenario that is also a held-out scenario.
    """
    rest = {k: v for k, v in overrides.items() if k not in KEYS}
    scenarios = overrides.get("train_scenarios")
    aggregate = overrides.get("train_aggregate") or "mean"
    if aggregate not in AGGREGATES:
        raise ConfigError("problem.params.train_aggregate", f"unknown aggregate {aggregate!r}",
                          allowed=AGGREGATES)
    base = mod.make_problem(case, rest)
    n_sample = overrides.get("train_sample") or 0
    seed = overrides.get("train_seed", 1)
    if not (is_int(n_sample) and n_sample >= 0):
        raise ConfigError("problem.params.train_sample",
                          f"must be an integer >= 0, got {n_sample!r}")
    if not is_int(seed) or seed < 0:
        raise ConfigError("problem.params.train_seed", f"must be an integer >= 0, got {seed!r}")
    listed = scenarios
    if listed is not None and (isinstance(listed, Mapping) or not hasattr(listed, "__len__")
                               or not listed):
        raise ConfigError("problem.params.train_scenarios",
                          "need a non-empty list of parameter overrides (use {} for the "
                          "case itself), or null for single-scenario tuning")
    if n_sample:
        if not hasattr(base, "sample_training"):
            raise ConfigError("problem.params.train_sample",
                              f"problem {base.name!r} cannot draw training scenarios")
        scenarios = list(scenarios or []) + base.sample_training(n_sample, seed)
    if scenarios is None:
        return base
    if getattr(getattr(base, "params", None), "objective_form", "cost") != "cost":
        # the aggregate is of recorded costs: a case's objective form does not carry over
        if "objective_form" in overrides:
            raise ConfigError("problem.params.objective_form", "multi-scenario tuning "
                              "minimizes the aggregate cost: use objective_form=cost")
        rest = {**rest, "objective_form": "cost"}
        base = mod.make_problem(case, rest)
    if not scenarios:
        raise ConfigError("problem.params.train_scenarios",
                          "need a non-empty list of parameter overrides (use {} for the "
                          "case itself), or null for single-scenario tuning")
    built, recorded = [], []
    held = base.holdout_keys() if hasattr(base, "holdout_keys") else set()
    for k, scen in enumerate(scenarios):
        if not isinstance(scen, Mapping):
            raise ConfigError("problem.params.train_scenarios",
                              f"scenario {k} is not a mapping of parameter overrides: {scen!r}")
        inner = sorted(set(scen) & set(KEYS))
        if inner:
            raise ConfigError("problem.params.train_scenarios",
                              f"scenario {k} sets {inner[0]}, which is not a problem parameter")
        held_keys = sorted(name for name in scen if str(name).startswith("holdout_"))
        if held_keys:
            raise ConfigError("problem.params.train_scenarios",
                              f"scenario {k} sets {held_keys[0]}: the held-out set belongs to "
                              "the run, not to one training scenario")
        off = dict(getattr(type(base.params), "HOLDOUT_OFF", {}))
        try:
            prob = mod.make_problem(case, {**rest, **dict(scen), **off})
        except ConfigError as err:
            raise ConfigError("problem.params.train_scenarios",
                              f"scenario {k} ({dict(scen)}) is invalid: {err}") from None
        if hasattr(prob, "scenario_key") and prob.scenario_key() in held:
            raise ConfigError("problem.params.train_scenarios",
                              f"training scenario {k} ({dict(scen)}) is also in the held-out "
                              "set; training and held-out scenarios must be disjoint")
        built.append(prob)
        recorded.append(dict(scen))
    params = replace(base.params, train_scenarios=None if listed is None else tuple(listed),
                     train_aggregate=aggregate, train_sample=n_sample, train_seed=seed)
    return MultiScenarioProblem(base, built, recorded, aggregate, params)


__all__ = ["AGGREGATES", "KEYS", "MultiScenarioProblem", "TrainingParams", "build"]
