"""Problem registry: name → module path (imported lazily so that numba compiles only what
is used).

Each module follows :mod:`penaltyrun.problems.base`.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from types import ModuleType
from typing import Any

from penaltyrun.errors import ConfigError
from penaltyrun.problems import multiscenario
from penaltyrun.problems.base import Problem

REGISTRY: dict[str, str] = {
    "zermelo": "penaltyrun.problems.zermelo",
    "attitude_lyapunov": "penaltyrun.problems.attitude_lyapunov",
    "attitude_lqr": "penaltyrun.problems.attitude_lqr",
    "lyapunov_transfer": "penaltyrun.problems.lyapunov_transfer",
    "qlaw": "penaltyrun.problems.qlaw",
}


def available() -> tuple[str, ...]:
    """Names of the problems whose module is present in this installation."""
    return tuple(name for name, mod in REGISTRY.items() if importlib.util.find_spec(mod))


def module(name: str) -> ModuleType:
    """Import and return the module of problem ``name``.

    Raises
    ------
    ConfigError
        If ``name`` is not a known problem.
    """
    if name not in available():
        raise ConfigError("problem", f"unknown problem {name!r}", allowed=available())
    return importlib.import_module(REGISTRY[name])


def make(name: str, case: str | None, params: Mapping[str, Any] | None = None) -> Problem:
    """Build problem ``name`` for ``case`` (``None`` → the module's default case).

    Parameters
    ----------
    name : str
        Registered problem name.
    case : str or None
        Case name; must be one of the module's ``CASES``.
    params : mapping, optional
        Parameter overrides (already merged with the case entry by the caller);
        ``train_scenarios`` / ``train_aggregate`` make a multi-scenario problem (see
        :mod:`penaltyrun.problems.multiscenario`).
    """
    mod = module(name)
    case = mod.DEFAULT_CASE if case in (None, "", "default") else str(case)
    if case not in mod.CASES:
        raise ConfigError("case", f"unknown case {case!r} for problem {name!r}", allowed=mod.CASES)
    return multiscenario.build(mod, case, dict(params or {}))
