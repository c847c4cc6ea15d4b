"""Optimizers over a box with a batched objective (``pso``: pyswarms; ``de``: scipy)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import fields
from typing import Any

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.optim.base import BatchObjective, OptimResult
from penaltyrun.optim.baseline import BaselineSettings, run_baseline
from penaltyrun.optim.de import DESettings, run_de
from penaltyrun.optim.pso import PSOSettings, run_pso

OPTIMIZERS = {"pso": (PSOSettings, run_pso), "de": (DESettings, run_de),
              "baseline": (BaselineSettings, run_baseline)}

_POSITIVE_INT = ("n_particles", "iters", "popsize", "ftol_iter")


Settings = PSOSettings | DESettings | BaselineSettings


def make_settings(name: str, options: Mapping[str, Any]) -> Settings:
    """Validated settings for optimizer ``name`` from a config mapping.

    Raises
    ------
    ConfigError
        Unknown optimizer, unknown option, or a non-positive budget.
    """
    if name not in OPTIMIZERS:
        raise ConfigError("optimizer.name", f"unknown optimizer {name!r}", allowed=OPTIMIZERS)
    cls = OPTIMIZERS[name][0]
    allowed = {f.name for f in fields(cls)}
    unknown = sorted(set(options) - allowed)
    if unknown:
        raise ConfigError(f"optimizer.{unknown[0]}", f"not an option of {name!r}",
                          allowed=sorted(allowed))
    for key in _POSITIVE_INT:
        value = options.get(key)
        if key in options and (isinstance(value, bool) or not isinstance(value, int)
                               or value < 1):
            raise ConfigError(f"optimizer.{key}", f"must be a positive integer, got "
                              f"{options[key]!r}")
    if name == "pso" and options.get("bh_strategy", "nearest") not in (
            "nearest", "random", "shrink", "reflective", "intermediate", "periodic"):
        raise ConfigError("optimizer.bh_strategy", "unknown boundary strategy",
                          allowed=("nearest", "random", "shrink", "reflective",
                                   "intermediate", "periodic"))
    values = {k: tuple(v) if isinstance(v, list) else v for k, v in options.items()}
    return cls(**values)


def minimize(name: str, objective: BatchObjective, lb: np.ndarray, ub: np.ndarray,
             settings: Settings, seed: int, x0: np.ndarray | None = None) -> OptimResult:
    """Run optimizer ``name`` with ``settings`` on ``objective`` over [lb, ub].

    ``x0`` is the point the ``baseline`` optimizer evaluates (required for it, ignored by
    the search optimizers).
    """
    if name == "baseline":
        if x0 is None:
            raise ValueError("the baseline optimizer needs x0")
        return run_baseline(objective, x0)
    return OPTIMIZERS[name][1](objective, lb, ub, settings, seed)


__all__ = ["OPTIMIZERS", "BaselineSettings", "DESettings", "OptimResult", "PSOSettings",
           "Settings", "make_settings", "minimize"]
