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

from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from penaltyrun import lazy
from penaltyrun.errors import ConfigError
from penaltyrun.jobrecord import polished_stop
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
from penaltyrun.optim.pattern import compass_search
from penaltyrun.optim.polish import local_search
from penaltyrun.optim.pso import PSOSettings, run_pso
from penaltyrun.optim.pso_matlab import PSOMatlabSettings, run_pso_matlab


@dataclass(frozen=True)
class Optimizer:
    """One optimizer of the registry (:data:`OPTIMIZERS`).

    A new optimizer is one module of this package (its settings dataclass, with
    ``validate`` and ``batch_size`` where the defaults do not fit, and its run function
    ``run(objective, lb, ub, settings, seed, x0) -> OptimResult``), one entry here and one
    preset ``penaltyrun/conf/optimizer/<name>.yaml``; the command line, the checks, the
    forecast, the warm start, the worker pool and the configuration reference read it
    from here.

    Attributes
    ----------
    settings : type
        Its settings dataclass (every field an ``optimizer.*`` option).
    run : callable
        Its run function.
    needs_gradient : bool
        It calls the problem's exact gradient (refused before a run on a problem without
        one; ``run`` then also takes the gradient function).
    warm_start : bool
        A full-map run may spend a share of its ``max_evals`` on the diagonal map first
        (``runner.warm_start``): false for optimizers without an evaluation budget.
    shared_imports : tuple of str
        Modules (or ``module:loader``) it imports on its first run, imported once in the
        parent before worker processes are forked (:mod:`penaltyrun.runner.pool`).
    """

    settings: type
    run: Callable[..., OptimResult]
    needs_gradient: bool = False
    warm_start: bool = True
    shared_imports: tuple[str, ...] = ()


#: The optimizers, by the name ``optimizer.name`` (and ``optimizer=<name>``) gives them.
OPTIMIZERS: dict[str, Optimizer] = {
    "pso": Optimizer(PSOSettings, run_pso, shared_imports=("penaltyrun.optim.pso:load_pyswarms",)),
    "de": Optimizer(DESettings, run_de),
    "cmaes": Optimizer(CMAESSettings, run_cmaes),
    "grid": Optimizer(GridSettings, run_grid, warm_start=False),
    "baseline": Optimizer(BaselineSettings, run_baseline, warm_start=False),
    "pso_matlab": Optimizer(PSOMatlabSettings, run_pso_matlab),
    "lbfgs": Optimizer(LBFGSSettings, run_lbfgs, needs_gradient=True,
                       shared_imports=("scipy.optimize",)),
}
#: Optimizers that need the problem's exact gradient.
GRADIENT_OPTIMIZERS = tuple(name for name, opt in OPTIMIZERS.items() if opt.needs_gradient)

def check_gradient_available(optimizer: str, options: Mapping[str, Any], prob: Any) -> None:
    """Refuse an optimizer (or polish) that needs the exact gradient on a problem without
    one, before any job runs (the command line's check and :func:`penaltyrun.tune`'s).

    Raises
    ------
    ConfigError
        ``optimizer`` or ``optimizer.polish``, naming why the problem has no gradient.
    """
    from penaltyrun.problems.base import gradient_support

    reason = gradient_support(prob)
    if not reason:
        return
    if optimizer in GRADIENT_OPTIMIZERS:
        raise ConfigError("optimizer", f"{optimizer} needs the exact gradient, but {reason}; "
                                       "pick another optimizer")
    if options.get("polish") == "gradient":
        raise ConfigError("optimizer.polish", f"gradient needs the exact gradient, but "
                                              f"{reason}; use polish=L-BFGS-B (differences)")


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
    cls = OPTIMIZERS[name].settings
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
    entry = OPTIMIZERS[name]
    if entry.needs_gradient:
        result = entry.run(counted, lb, ub, settings, seed, x0, gradient)
    else:
        result = entry.run(counted, lb, ub, settings, seed, x0)
    if settings.polish == "none":
        return result
    counted.limit = settings.max_evals
    searched = counted.n_evals
    if settings.polish == "gradient":
        outcome = gradient_polish(counted, counted.best_z, lb, ub, gradient,
                                  settings.grad_cost)
    elif settings.polish == "pattern":
        outcome = compass_search(counted, counted.best_z, lb, ub)
    else:
        outcome = local_search(counted, counted.best_z, lb, ub, settings.polish)
    stop = polished_stop(result.stop_reason, outcome)
    return replace(counted.result(result.history, result.n_iters, stop),
                   polish_evals=counted.n_evals - searched)


#: Imported on first use: the gradient helpers need the problems and the parameterizations
#: (numba), which a refused command-line value must not load.
_NAMES = {"declared_gradient_cost": "gradient", "with_gradient_cost": "gradient"}

__getattr__, __dir__ = lazy.exports(__name__, _NAMES, globals())

__all__ = ["GRADIENT_OPTIMIZERS", "OPTIMIZERS", "POLISH_METHODS", "BaselineSettings", "Optimizer",
           "CMAESSettings", "CommonSettings", "DESettings", "GridSettings", "LBFGSSettings",
           "OptimResult", "PSOMatlabSettings",
           "PSOSettings", "Settings", "check_dimension", "check_gradient_available",
           "declared_gradient_cost",
           "make_settings", "minimize", "planned_evals", "with_gradient_cost"]
