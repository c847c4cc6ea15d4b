"""Tuning criteria: what a candidate's cost measures (one definition for every problem).

The paper's criterion, ``deadline``, minimizes control energy subject to reaching the target
before a hard deadline ``t_max``. It is ill-posed: without the deadline the infimum is 0
(arrive ever later, ever more gently), and with it the energy of a linear loop falls about
as T⁻³, so every optimum sits on the deadline, on the edge where the cost jumps to the
failure penalty. Two well-posed criteria sit beside it (problem parameter ``criterion``):

``deadline`` (default)
    The problem's own cost, unchanged (reproduction of the paper).
``time_energy`` — free final time
    J = ∫₀^{t_f} (½ uᵀu + ρ) dt, t_f the first time the problem's own target event fires
    (its terminal tolerance), over the long horizon ``free_time_cap`` (no deadline). ρ
    (``rho``, the problem's energy rate unit) is the price of one second: the optimum
    balances ρ against the energy saved by arriving later. A run that never arrives by the
    cap gets the problem's graded failure cost there (criterion value at the cap plus the
    failure penalty). Sampled problems use the sum over steps of (½ u_kᵀu_k + ρ) Tₛ.
``terminal`` — fixed horizon with a terminal penalty
    J = ∫₀ᵀ ½ uᵀu dt + x(T)ᵀ S x(T), T = ``t_max``, no terminal event: every run lasts T
    and the penalty S (``terminal_weight``) prices the state left at T. A run that reaches
    T without a numerical failure counts as converged; its final distance is recorded.

A problem defines what ``x`` and the energy are in its own terms (see its module and
``docs/explanation/criteria.md``); this module holds the names, the shared settings and
their validation, and the arithmetic every problem shares.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.problems import horizon
from penaltyrun.typed import is_number

#: Criterion names (problem parameter ``criterion``); the first is the default.
CRITERIA = ("deadline", "time_energy", "terminal")
DEADLINE, TIME_ENERGY, TERMINAL = CRITERIA
#: Parameter names of the criterion settings (every problem with criteria has them).
SETTINGS = ("criterion", "rho", "terminal_weight", "free_time_cap")
#: Problem parameters added after studies were committed: left ``null`` they are dropped
#: from the config hash (:func:`hashed_node`), so older configurations keep their hash.
HASH_NEUTRAL_WHEN_NULL = (*SETTINGS, "train_quantile")
#: Relative tolerance of the symmetry and PSD checks of ``terminal_weight``.
SYM_RTOL = 1e-10


@dataclass(frozen=True)
class CriterionParams:
    """Criterion settings shared by the ``Params`` of every problem with criteria.

    A problem's ``Params`` redeclares ``rho`` and ``free_time_cap`` with defaults in its
    units; ``terminal_weight`` ``None`` means the problem's documented default S.

    Attributes
    ----------
    criterion : str
        ``deadline`` (the paper's), ``time_energy`` or ``terminal`` (see
        :mod:`penaltyrun.problems.criteria`).
    rho : float
        Price of time of ``time_energy`` (> 0), in the problem's cost units per second.
    terminal_weight : tuple or None
        S of ``terminal``: n diagonal entries or an n × n symmetric positive semidefinite
        nested list, in the problem's cost units per squared state unit; ``None``: the
        problem's default.
    free_time_cap : float
        Long horizon of ``time_energy`` (s): a run that has not arrived by then fails.
    """

    criterion: str = DEADLINE
    rho: float = 1.0
    terminal_weight: tuple | None = None
    free_time_cap: float = 10_000.0


def freeze(value: Any) -> Any:
    """``terminal_weight`` as nested tuples (hashable in a frozen dataclass); other values
    (``None``, numbers, strings) unchanged."""
    if isinstance(value, (list, tuple)) or (isinstance(value, np.ndarray) and value.ndim):
        return tuple(freeze(v) for v in value)
    return value


def terminal_matrix(value: Any, n: int, key: str) -> np.ndarray:
    """S (n × n) from ``terminal_weight``: n diagonal entries or a full matrix.

    Raises
    ------
    ConfigError
        Not n numbers or an n × n matrix, not finite, not symmetric or not positive
        semidefinite (one line naming ``key``).
    """
    try:
        S = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(key, f"expected {n} diagonal entries or a {n}x{n} matrix") from None
    if S.shape == (n,):
        S = np.diag(S)
    if S.shape != (n, n):
        raise ConfigError(key, f"expected {n} diagonal entries or a {n}x{n} matrix, got "
                               f"shape {S.shape}")
    if not np.all(np.isfinite(S)):
        raise ConfigError(key, "entries must be finite numbers")
    scale = max(float(np.max(np.abs(S))), 1e-300)
    if not np.allclose(S, S.T, rtol=0.0, atol=SYM_RTOL * scale):
        raise ConfigError(key, "S must be symmetric")
    S = 0.5 * (S + S.T)
    if float(np.linalg.eigvalsh(S)[0]) < -SYM_RTOL * scale:
        raise ConfigError(key, "S must be positive semidefinite (an eigenvalue is negative)")
    return S


def check(params: Any, prefix: str = "problem") -> None:
    """Validate ``criterion``, ``rho`` and ``free_time_cap`` (``terminal_weight`` needs the
    state size: :func:`terminal_matrix`).

    Raises
    ------
    ConfigError
        Naming the key (``<prefix>.<name>``) in one line.
    """
    if params.criterion not in CRITERIA:
        raise ConfigError(f"{prefix}.criterion", f"unknown criterion {params.criterion!r}",
                          allowed=CRITERIA)
    rho = params.rho
    if not (is_number(rho, any_real=True) and 0.0 < rho < math.inf):
        raise ConfigError(f"{prefix}.rho", f"must be a positive number (the price of one "
                          f"second in cost units), got {rho!r}")
    cap = params.free_time_cap
    if not (is_number(cap, any_real=True) and 0.0 < cap < math.inf):
        raise ConfigError(f"{prefix}.free_time_cap", f"must be a positive time (s), got "
                          f"{cap!r}")


def hashed_node(problem: Mapping[str, Any]) -> dict[str, Any]:
    """A config's ``problem`` node as its config hash sees it: the settings of
    :data:`HASH_NEUTRAL_WHEN_NULL` (the criterion settings, ``train_quantile``) left
    ``null`` are dropped, so a shipped problem YAML that lists them hashes as it did before
    they existed (committed studies find their runs by that hash)."""
    node = dict(problem)
    params = node.get("params")
    if isinstance(params, Mapping):
        node["params"] = {k: v for k, v in params.items()
                          if not (k in HASH_NEUTRAL_WHEN_NULL and v is None)}
    return node


def run_horizon(params: Any) -> float:
    """How long a run may last (s): ``free_time_cap`` for ``time_energy``, else ``t_max``."""
    if params.criterion == TIME_ENERGY:
        return float(params.free_time_cap)
    return float(params.t_max)


def judges_at_deadline(params: Any) -> bool:
    """Whether the held-out set is judged at a deadline and again at a longer horizon
    (``deadline`` only: the other criteria define their own horizon, used for both)."""
    return params.criterion == DEADLINE


def judged_at(params: Any, train_t: float, t_max: float, step: float | None = None
              ) -> float:
    """The horizon a held-out set (and a basin map) is judged at (s): under ``deadline``
    the held-out horizon of ``t_max`` (:func:`penaltyrun.problems.horizon.holdout_horizon`,
    ``step`` a sampled controller's period), under the other criteria their own run
    horizon ``train_t``."""
    if not judges_at_deadline(params):
        return float(train_t)
    return horizon.holdout_horizon(t_max, params.holdout_horizon_factor,
                                   params.holdout_t_max_cap, step)


def report_name(params: Any, deadline_name: str, free_energy: str, fixed_energy: str
                ) -> str:
    """The cost's name in reports: ``deadline_name`` under ``deadline``; else
    ``J = <free_energy> + ρ·t_f (ρ = …)`` (the energy to arrival, e.g.
    ``"∫₀^t_f ½‖u‖² dt"``) or ``J = <fixed_energy> + x(T)ᵀ S x(T)`` (to T = t_max)."""
    if params.criterion == TIME_ENERGY:
        return f"J = {free_energy} + ρ·t_f (ρ = {float(params.rho):g})"
    if params.criterion == TERMINAL:
        return f"J = {fixed_energy} + x(T)ᵀ S x(T)"
    return deadline_name


def time_energy_cost(energy: Any, t_final: Any, rho: float) -> np.ndarray:
    """Free-final-time value ∫ (½ uᵀu + ρ) dt = energy + ρ · t_final."""
    return np.asarray(energy, dtype=float) + float(rho) * np.asarray(t_final, dtype=float)


def terminal_cost(x_final: Any, S: np.ndarray) -> np.ndarray:
    """x(T)ᵀ S x(T) of final states ``x_final`` (..., n)."""
    x = np.asarray(x_final, dtype=float)
    return np.einsum("...i,ij,...j->...", x, S, x)


__all__ = ["CRITERIA", "CriterionParams", "DEADLINE", "HASH_NEUTRAL_WHEN_NULL", "SETTINGS",
           "TERMINAL", "TIME_ENERGY",
           "check", "freeze", "hashed_node", "judges_at_deadline", "report_name", "run_horizon",
           "terminal_cost", "terminal_matrix", "time_energy_cost"]
