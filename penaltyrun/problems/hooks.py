"""The optional hooks of a problem instance, as typed capabilities.

The required members of a problem are the :class:`~penaltyrun.problems.base.Problem`
protocol. Each optional hook is a ``typing.Protocol`` of its own here (as
:class:`~penaltyrun.problems.base.GradientProblem` and
:class:`~penaltyrun.problems.basins.BasinProblem` are), and :func:`hooks` gathers a
problem's optional hooks into one typed object, :class:`ProblemHooks`, whose fields are
``None`` where the problem has no such hook; the runner, the forecast, the diagnostics,
the multi-scenario build and the reports read that object (none probes a problem for them
with ``hasattr``). The hooks:

* held-out scenarios (:class:`HeldOutProblem`): ``holdout_scenarios()`` (the held-out set:
  a mapping with a ``scenario`` list of labels and per-scenario arrays) and
  ``holdout(mats, scalars)`` (the candidate judged on it);
* closed loop (:class:`ClosedLoopProblem`): ``closed_loop(mats, scalars) -> ClosedLoop |
  None`` (the loop linearized at the target);
* gradient (:class:`~penaltyrun.problems.base.GradientProblem`):
  ``gradient(mats, scalars) -> CostGradient``, and its measured cost in evaluations
  (:class:`~penaltyrun.problems.base.PricedGradientProblem`): ``gradient_cost() ->
  GradientCost | None``;
* multi-scenario training (:class:`ScenarioProblem`, :mod:`penaltyrun.problems.multiscenario`):
  ``scenario_key()``, ``holdout_keys()`` and ``sample_training(n, seed)``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from penaltyrun.problems.base import ClosedLoop, CostGradient, GradientCost

Mats = Mapping[str, np.ndarray]
Scalars = Mapping[str, float] | None


@runtime_checkable
class HeldOutProblem(Protocol):
    """A problem with a held-out set of scenarios, disjoint from the ones it is tuned on."""

    def holdout_scenarios(self) -> Mapping[str, Any]:
        """The held-out set: ``scenario`` (labels) and per-scenario arrays."""
        ...

    def holdout(self, mats: Mats, scalars: Scalars = None) -> dict[str, Any]:
        """One candidate judged on every held-out scenario (per-scenario lists)."""
        ...


@runtime_checkable
class ClosedLoopProblem(Protocol):
    """A problem whose closed loop can be linearized at the target."""

    def closed_loop(self, mats: Mats, scalars: Scalars = None) -> ClosedLoop | None:
        """The closed loop of one candidate, or None where it has none."""
        ...


@runtime_checkable
class ScenarioProblem(Protocol):
    """A problem that can be tuned on several scenarios at once (multi-scenario training)."""

    def scenario_key(self) -> Any:
        """A hashable key of this instance's scenario."""
        ...

    def holdout_keys(self) -> set[Any]:
        """The keys of the held-out scenarios (training scenarios must avoid them)."""
        ...

    def sample_training(self, n: int, seed: int) -> list[dict[str, Any]]:
        """``n`` training scenarios (parameter overrides) drawn with ``seed``."""
        ...


@dataclass(frozen=True)
class ProblemHooks:
    """The optional hooks of one problem instance (``None``: the problem has none).

    Attributes
    ----------
    holdout : callable or None
        ``holdout(mats, scalars) -> dict`` (with ``holdout_scenarios``).
    holdout_scenarios : callable or None
        ``holdout_scenarios() -> mapping`` (with ``holdout``).
    closed_loop : callable or None
        ``closed_loop(mats, scalars) -> ClosedLoop | None``.
    gradient : callable or None
        ``gradient(mats, scalars) -> CostGradient``.
    gradient_cost : callable or None
        ``gradient_cost() -> GradientCost | None``: what one gradient costs in evaluations.
    scenario_key, holdout_keys, sample_training : callable or None
        The multi-scenario training hooks.
    """

    holdout: Callable[[Mats, Scalars], dict[str, Any]] | None = None
    holdout_scenarios: Callable[[], Mapping[str, Any]] | None = None
    closed_loop: Callable[[Mats, Scalars], ClosedLoop | None] | None = None
    gradient: Callable[[Mats, Scalars], CostGradient] | None = None
    gradient_cost: Callable[[], GradientCost | None] | None = None
    scenario_key: Callable[[], Any] | None = None
    holdout_keys: Callable[[], set[Any]] | None = None
    sample_training: Callable[[int, int], list[dict[str, Any]]] | None = None

    def n_holdout(self) -> int:
        """Scenarios of the held-out set (0 without one)."""
        if self.holdout is None or self.holdout_scenarios is None:
            return 0
        found = self.holdout_scenarios()
        return len(found["scenario"]) if isinstance(found, Mapping) else len(found)


def hooks(problem: Any) -> ProblemHooks:
    """The optional hooks ``problem`` defines (see :class:`ProblemHooks`); a member that
    is not callable counts as absent."""

    def hook(name: str) -> Any:
        found = getattr(problem, name, None)
        return found if callable(found) else None

    return ProblemHooks(**{name: hook(name) for name in ProblemHooks.__dataclass_fields__})


__all__ = ["ClosedLoopProblem", "HeldOutProblem", "ProblemHooks", "ScenarioProblem", "hooks"]
