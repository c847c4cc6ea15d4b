"""Held-out evaluation away from the training deadline.

A matrix tuned on one start can leave slow closed-loop modes that its training start does
not excite; judged at the training deadline ``t_max``, such a gain fails from most held-out
starts and the held-out test has nothing to pair. So every problem with a deadline evaluates
its held-out set twice:

* at the training deadline (what the training run saw): ``converged_by_deadline``,
  ``cost_at_deadline``, ``status_at_deadline``, ``distance_at_deadline``;
* at the held-out horizon ``T = min(holdout_horizon_factor · t_max, holdout_t_max_cap)``
  (never below ``t_max``): ``cost``, ``converged``, ``status``, ``t_final``,
  ``final_distance`` and ``arrival_time`` (the event time, NaN if the run never arrived).

A gain that has still not converged by ``T`` gets the problem's own graded failure cost at
``T`` (the same rule as in training, with ``T`` in place of ``t_max``) and its status says
why. ``horizon`` and ``training_horizon`` (s) are stored with the scenarios.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.typed import is_number

#: Fields every long-horizon held-out result adds (beside ``cost``, ``converged``, ...).
DEADLINE_FIELDS = ("converged_by_deadline", "cost_at_deadline", "status_at_deadline",
                   "distance_at_deadline")
#: Parameter names of the setting (every problem with a deadline has both).
SETTINGS = ("holdout_horizon_factor", "holdout_t_max_cap")


def holdout_horizon(t_max: float, factor: float, cap: float, step: float | None = None
                    ) -> float:
    """The held-out horizon ``max(t_max, min(factor · t_max, cap))`` (s).

    ``step`` (s, optional): the horizon is rounded down to a whole number of steps (a
    sampled controller), never below ``t_max``.
    """
    horizon = max(float(t_max), min(float(factor) * float(t_max), float(cap)))
    if step:
        horizon = max(float(t_max), math.floor(horizon / step + 1e-9) * step)
    return horizon


def check_settings(params: Any, prefix: str) -> None:
    """Validate ``holdout_horizon_factor`` (≥ 1) and ``holdout_t_max_cap`` (> 0).

    Raises
    ------
    ConfigError
        Naming the key (``<prefix>.<name>``).
    """
    factor, cap = params.holdout_horizon_factor, params.holdout_t_max_cap
    if not (is_number(factor, any_real=True) and factor >= 1.0 and math.isfinite(factor)):
        raise ConfigError(f"{prefix}.holdout_horizon_factor",
                          f"must be a number ≥ 1 (1: judge at the training deadline), "
                          f"got {factor!r}")
    if not (is_number(cap, any_real=True) and cap > 0.0):
        raise ConfigError(f"{prefix}.holdout_t_max_cap",
                          f"must be a positive time (s), got {cap!r}")


def at_horizon(problem: Any, horizon: float, **attrs: Any) -> Any:
    """A shallow copy of ``problem`` whose ``params.t_max`` is ``horizon``; ``attrs`` are
    further attributes of the copy that cache the horizon (e.g. ``t_max``)."""
    clone = copy.copy(problem)
    clone.params = replace(problem.params, t_max=float(horizon))
    for name, value in attrs.items():
        setattr(clone, name, value)
    return clone


def combine(short: Mapping[str, Any], long: Mapping[str, Any], training_horizon: float,
            horizon: float, distance: str = "final_distance") -> dict[str, Any]:
    """One held-out result from the runs at the training deadline (``short``) and at the
    held-out horizon (``long``); see the module docstring for the fields.

    Parameters
    ----------
    short, long : mapping
        Per-scenario arrays with ``cost``, ``converged``, ``status``, ``t_final`` and
        ``distance`` (a final distance to the target).
    """
    out = dict(long)
    conv = np.asarray(long["converged"], dtype=bool)
    out["arrival_time"] = np.where(conv, np.asarray(long["t_final"], float), np.nan)
    out["converged_by_deadline"] = np.asarray(short["converged"], dtype=bool)
    out["cost_at_deadline"] = np.asarray(short["cost"], dtype=float)
    out["status_at_deadline"] = np.asarray(short["status"], dtype=object)
    out["distance_at_deadline"] = np.asarray(short[distance], dtype=float)
    out["horizon"] = float(horizon)
    out["training_horizon"] = float(training_horizon)
    return out


__all__ = ["DEADLINE_FIELDS", "SETTINGS", "at_horizon", "check_settings", "combine",
           "holdout_horizon"]
