"""Multi-scenario tuning: one objective over several training scenarios of a problem.

A problem's parameters may carry ``train_scenarios`` (a list of parameter overrides, each
one training scenario on top of the case and the other overrides; ``{}`` is the case's own
scenario), ``train_sample`` / ``train_seed`` (a seeded sample of that many scenarios drawn
by the problem's ``sample_training(n, seed)``, appended to the list) and
``train_aggregate`` (``mean``, ``max`` or ``quantile``, the last at level
``train_quantile``). The tuned objective of a candidate is then the mean, the max or the
quantile of its costs over the training scenarios, each cost as the single-scenario problem
defines it (graded penalty included, so it stays finite); the candidate converges only if it
converges in every training scenario.

The quantile is numpy's default (``method="linear"``): with the m costs sorted,
c₍₀₎ ≤ … ≤ c₍ₘ₋₁₎, and h = q (m − 1), it is c₍⌊h⌋₎ + (h − ⌊h⌋)(c₍⌊h⌋+1₎ − c₍⌊h⌋₎). A
high quantile (e.g. q = 0.9) prices the bad scenarios without letting the single worst one
(``max``) decide alone; q = 1 is the max, q = 0.5 the median.

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
from penaltyrun.problems.hooks import hooks
from penaltyrun.typed import is_int, is_number

AGGREGATES = ("mean", "max", "quantile")
KEYS = ("train_scenarios", "train_aggregate", "train_sample", "train_seed", "train_quantile")
#: Level of ``train_aggregate: quantile`` when ``train_quantile`` is not set.
DEFAULT_QUANTILE = 0.9


@dataclass(frozen=True)
class TrainingParams:
    """Multi-scenario tuning settings shared by every problem's ``Params``.

    Attributes
    ----------
    train_scenarios : tuple of mapping or None
        Training scenarios as parameter overrides; ``None``: single-scenario tuning (the
        case itself).
    train_aggregate : str
        ``"mean"``, ``"max"`` or ``"quantile"`` of the per-scenario costs.
    train_sample : int
        Further training scenarios drawn by the problem's ``sample_training`` (0: none),
        some problems with the sizes of their held-out set (attitude: the case's state
        perturbed by ``holdout_perturb_deg``, ``holdout_rate_rel``; MPC: starts on the
        held-out sphere); reports then split cells by those held-out parameters too.
    train_seed : int
        Seed of that sample (different from the held-out seeds).
    train_quantile : float or None
        Level q in (0, 1] of ``train_aggregate: quantile`` (``None``: 0.9); only with that
        aggregate.
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
    train_quantile: float | None = None


def _aggregate(costs: np.ndarray, how: str, q: float = DEFAULT_QUANTILE) -> np.ndarray:
    """Aggregate of per-scenario costs ``costs`` (m, B) over the scenarios → (B,)."""
    if how == "mean":
        return costs.mean(axis=0)
    if how == "max":
        return costs.max(axis=0)
    return np.quantile(costs, q, axis=0)


def quantile_weights(costs: np.ndarray, q: float) -> np.ndarray | None:
    """Weights w (m,) with quantile(costs, q) = w · costs locally (numpy's ``linear``
    method: the two order statistics around h = q (m − 1)); ``None`` where the quantile has
    a kink (two tied costs of neighbouring ranks with different weights: moving one of them
    swaps the ranks, and the weight jumps), so no gradient exists there."""
    m = len(costs)
    order = np.argsort(costs, kind="stable")
    h = q * (m - 1)
    lo = int(np.floor(h))
    frac = h - lo
    by_rank = np.zeros(m)
    by_rank[lo] = 1.0 - frac
    if frac > 0.0:
        by_rank[lo + 1] = frac
    ranked = np.asarray(costs, dtype=float)[order]
    scale = max(1.0, float(np.max(np.abs(ranked))))
    for j in range(m - 1):
        if by_rank[j] != by_rank[j + 1] and ranked[j + 1] - ranked[j] <= 1e-9 * scale:
            return None
    weights = np.zeros(m)
    weights[order] = by_rank
    return weights


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
        ``"mean"``, ``"max"`` or ``"quantile"``.
    params : dataclass, optional
        Parameters to report (default: the base's with the training settings filled in).
    """

    def __init__(self, base: Any, scenarios: list[Any], overrides: list[dict[str, Any]],
                 aggregate: str, params: Any = None, quantile: float = DEFAULT_QUANTILE
                 ) -> None:
        self.base = base
        self.scenarios = scenarios
        self.overrides = overrides
        self.aggregate = aggregate
        self.quantile = float(quantile)
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
        has one): the mean of the scenarios' gradients, for ``max`` the gradient of the
        one scenario whose cost is the largest (none where two tie: a kink), for
        ``quantile`` the interpolation of the two order statistics it uses
        (:func:`quantile_weights`; none at a tie)."""
        parts = [p.gradient(mats, scalars) for p in self.scenarios]
        costs = np.asarray([g.cost for g in parts], dtype=float)
        cost = float(_aggregate(costs[:, None], self.aggregate, self.quantile)[0])
        failed = [g for g in parts if not g.exists]
        status = next((g.status for g in parts if g.status != "converged"), "converged")
        if failed:
            return CostGradient(cost, status, None, {}, f"training scenario: {failed[0].reason}")
        if self.aggregate == "mean":
            weights = np.full(len(parts), 1.0 / len(parts))
        elif self.aggregate == "quantile":
            found = quantile_weights(costs, self.quantile)
            if found is None:
                return CostGradient(cost, status, None, {}, "training scenario costs tie "
                                    "at the quantile's order statistics (a kink)")
            weights = found
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
        max above it too); the ``mean`` and the ``quantile`` ignore them (one scenario's
        cost says nothing of them without bounds on the others').
        """
        cut = thresholds if self.aggregate == "max" else None
        evals = [p.evaluate_batch(mats, scalars, thresholds=cut)
                 if cut is not None and accepts_thresholds(p) else p.evaluate_batch(mats, scalars)
                 for p in self.scenarios]
        cost = _aggregate(np.stack([e.cost for e in evals]), self.aggregate, self.quantile)
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
            "cost": float(_aggregate(costs, self.aggregate, self.quantile)[0]),
            "converged": all(bool(d["converged"]) for d in details),
            "status": bad[0] if bad else "converged",
            "t_final": max(float(d["t_final"]) for d in details),
            "train_aggregate": self.aggregate,
            **({"train_quantile": self.quantile} if self.aggregate == "quantile" else {}),
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
        Empty or malformed ``train_scenarios``, an unknown ``train_aggregate``, a
        ``train_quantile`` outside (0, 1] or set without ``train_aggregate: quantile``, or a
        training scenario that is also a held-out scenario.
    """
    rest = {k: v for k, v in overrides.items() if k not in KEYS}
    scenarios = overrides.get("train_scenarios")
    aggregate = overrides.get("train_aggregate") or "mean"
    if aggregate not in AGGREGATES:
        raise ConfigError("problem.params.train_aggregate", f"unknown aggregate {aggregate!r}",
                          allowed=AGGREGATES)
    quantile = check_quantile(overrides.get("train_quantile"), aggregate)
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
        sample = hooks(base).sample_training
        if sample is None:
            raise ConfigError("problem.params.train_sample",
                              f"problem {base.name!r} cannot draw training scenarios")
        scenarios = list(scenarios or []) + sample(n_sample, seed)
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
    holdout_keys = hooks(base).holdout_keys
    held = holdout_keys() if holdout_keys is not None else set()
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
        key = hooks(prob).scenario_key
        if key is not None and key() in held:
            raise ConfigError("problem.params.train_scenarios",
                              f"training scenario {k} ({dict(scen)}) is also in the held-out "
                              "set; training and held-out scenarios must be disjoint")
        built.append(prob)
        recorded.append(dict(scen))
    params = replace(base.params, train_scenarios=None if listed is None else tuple(listed),
                     train_aggregate=aggregate, train_sample=n_sample, train_seed=seed,
                     train_quantile=quantile if aggregate == "quantile" else None)
    return MultiScenarioProblem(base, built, recorded, aggregate, params, quantile)


def check_quantile(value: Any, aggregate: str) -> float:
    """The level of ``train_aggregate: quantile`` (``value`` ``None``: 0.9).

    Raises
    ------
    ConfigError
        ``value`` not a number in (0, 1], or set with another aggregate.
    """
    if value is None:
        return DEFAULT_QUANTILE
    if aggregate != "quantile":
        raise ConfigError("problem.params.train_quantile",
                          f"is the level of train_aggregate=quantile, but the aggregate is "
                          f"{aggregate!r}; set train_aggregate=quantile or drop train_quantile")
    if not (is_number(value, any_real=True) and 0.0 < float(value) <= 1.0):
        raise ConfigError("problem.params.train_quantile",
                          f"must be a number in (0, 1] (0.9: the 90 % quantile of the "
                          f"training costs), got {value!r}")
    return float(value)


__all__ = ["AGGREGATES", "DEFAULT_QUANTILE", "KEYS", "MultiScenarioProblem", "TrainingParams",
           "build", "check_quantile", "quantile_weights"]
