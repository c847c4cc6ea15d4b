"""Optimizers over a box with a batched objective and an evaluation budget.

``pso`` (pyswarms), ``pso_matlab`` (MATLAB's ``particleswarm`` re-implemented in numpy),
``de`` (scipy differential evolution), ``cmaes`` (IPOP-CMA-ES,
:mod:`penaltyrun.optim.cma_core`), ``grid`` (exhaustive grid + local search, dimension ≤ 4),
``lbfgs`` (multi-start L-BFGS-B with the problem's exact gradient) and ``baseline`` (one
given point).
:func:`minimize` runs one of them, then the shared bounded polish (``optimizer.polish``)
inside the same ``max_evals`` (``polish=gradient``: L-BFGS-B with the problem's exact
gradient).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import fields
from typing import Any

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.optim.base import (
    POLISH_METHODS,
    BatchObjective,
    CommonSettings,
    CountingObjective,
    OptimResult,
    global_rng_kept,
    main_budget,
    planned_evals,
)
from penaltyrun.optim.baseline import BaselineSettings, run_baseline
from penaltyrun.optim.checks import coerce_field, settings_hints
from penaltyrun.optim.cmaes import CMAESSettings, run_cmaes
from penaltyrun.optim.de import DESettings, run_de
from penaltyrun.optim.grid import GridSettings, run_grid
from penaltyrun.optim.lbfgs import GradientFn, LBFGSSettings, gradient_polish, run_lbfgs
from penaltyrun.optim.polish import local_search
from penaltyrun.optim.pso import PSOSettings, run_pso
from penaltyrun.optim.pso_matlab import PSOMatlabSettings, run_pso_matlab

OPTIMIZERS = {"pso": (PSOSettings, run_pso), "de": (DESettings, run_de),
              "cmaes": (CMAESSettings, run_cmaes), "grid": (GridSettings, run_grid),
              "baseline": (BaselineSettings, run_baseline),
              "pso_matlab": (PSOMatlabSettings, run_pso_matlab),
              "lbfgs": (LBFGSSettings, run_lbfgs)}
#: Optimizers that need the problem's exact gradient.
GRADIENT_OPTIMIZERS = ("lbfgs",)

Settings = (PSOSettings | DESettings | CMAESSettings | GridSettings | BaselineSettings
            | PSOMatlabSettings | LBFGSSettings)


def make_settings(name: str, options: Mapping[str, Any]) -> Settings:
    """Validated settings for optimizer ``name`` from a config mapping.

    Every option is checked against the type annotation of its settings field (see
    :mod:`penaltyrun.optim.checks`), then by the settings' own ``validate()`` (ranges,
    strategy names) if the class defines one.

    Raises
    ------
    ConfigError
        Unknown optimizer, unknown option, a value of the wrong type or out of range.
    """
    if name not in OPTIMIZERS:
        raise ConfigError("optimizer.name", f"unknown optimizer {name!r}", allowed=OPTIMIZERS)
    cls = OPTIMIZERS[name][0]
    allowed = {f.name for f in fields(cls)}
    unknown = sorted(set(options) - allowed)
    if unknown:
        raise ConfigError(f"optimizer.{unknown[0]}", f"not an option of {name!r}",
                          allowed=sorted(allowed))
    options = dict(options)
    if isinstance(options.get("polish"), bool):  # older configs: DE's `polish: true`
        options["polish"] = "L-BFGS-B" if options["polish"] else "none"
    hints = settings_hints(cls)
    values = {k: coerce_field(f"optimizer.{k}", v, hints.get(k, Any))
              for k, v in options.items()}
    try:
        settings = cls(**values)
    except TypeError as exc:
        raise ConfigError("optimizer", str(exc)) from None
    validate = getattr(settings, "validate", None)
    if callable(validate):
        validate()
    return settings


def check_dimension(settings: Settings, dim: int) -> None:
    """Refuse a decision box the optimizer cannot handle (the grid above 4 variables).

    Raises
    ------
    ConfigError
    """
    check = getattr(settings, "check_dimension", None)
    if check is not None:
        check(dim)


def minimize(name: str, objective: BatchObjective, lb: np.ndarray, ub: np.ndarray,
             settings: Settings, seed: int, x0: np.ndarray | None = None,
             gradient: GradientFn | None = None) -> OptimResult:
    """Run optimizer ``name`` with ``settings`` on ``objective`` over [lb, ub].

    The search spends at most ``max_evals`` minus the polish share; the polish (if
    ``settings.polish`` is not ``none``) starts from the search's best and spends the rest.
    ``x0`` is the point the ``baseline`` optimizer evaluates (required for it) and the warm
    start of the search optimizers (evaluated once before the search, so the result is never
    worse than ``x0``).

    The caller's global ``np.random`` state is the same after the call
    (:func:`~penaltyrun.optim.base.global_rng_kept`): pyswarms seeds and draws from it inside
    the call only.
    """
    with global_rng_kept():
        return _minimize(name, objective, lb, ub, settings, seed, x0, gradient)


def _minimize(name: str, objective: BatchObjective, lb: np.ndarray, ub: np.ndarray,
              settings: Settings, seed: int, x0: np.ndarray | None,
              gradient: GradientFn | None) -> OptimResult:
    if name == "baseline":
        if x0 is None:
            raise ValueError("the baseline optimizer needs x0")
        return run_baseline(objective, x0)
    counted = CountingObjective(objective, max_evals=settings.max_evals)
    counted.limit = main_budget(settings)
    if x0 is not None:  # a warm start is evaluated first: the run's best is never worse
        counted(np.asarray(x0, float)[None, :])
    if name in GRADIENT_OPTIMIZERS:
        result = run_lbfgs(counted, lb, ub, settings, seed, x0, gradient)
    else:
        result = OPTIMIZERS[name][1](counted, lb, ub, settings, seed, x0)
    if settings.polish == "none":
        return result
    counted.limit = settings.max_evals
    if settings.polish == "gradient":
        outcome = gradient_polish(counted, counted.best_z, lb, ub, gradient,
                                  getattr(settings, "grad_cost", None))
    else:
        outcome = local_search(counted, counted.best_z, lb, ub, settings.polish)
    stop = result.stop_reason + ("+polish" if outcome != "max_evals" else "+polish:max_evals")
    return counted.result(result.history, result.n_iters, stop)


__all__ = ["GRADIENT_OPTIMIZERS", "OPTIMIZERS", "POLISH_METHODS", "BaselineSettings",
           "CMAESSettings", "CommonSettings", "DESettings", "GridSettings", "LBFGSSettings",
           "OptimResult", "PSOMatlabSettings",
           "PSOSettings", "Settings", "check_dimension", "make_settings", "minimize",
           "planned_evals"]
