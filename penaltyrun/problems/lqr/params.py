"""Parameters of ``problem=lqr`` and their validation (every error names its key).

With no plant key given (``A``/``B``, ``plant_file``, ``plant``, ``dynamics``), the problem
is the built-in known-answer set-up :data:`KNOWN_ANSWER`: an unstable 3-state, 2-input
plant, a non-diagonal state weight and the three unit initial states, on which the LQR of
the performance weights is the global optimum and a diagonal Q cannot reach it. Once the
user gives a plant, none of the set-up's sized values apply: unset sizes default to the
unit initial states and identity weights.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any, ClassVar

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.problems import horizon
from penaltyrun.problems.base import ParamsMixin
from penaltyrun.problems.multiscenario import TrainingParams

PREFIX = "problem.params"
PLANT_KEYS = ("A", "B", "plant_file", "plant", "dynamics")
CASES = ("default",)
DEFAULT_CASE = "default"
#: Keys that do not define the tuned objective (left out of :attr:`Params.setup`).
NOT_SETUP = ("holdout_x0", "holdout_n", "holdout_seed", "holdout_horizon_factor",
             "holdout_t_max_cap", "cost_unit", "train_scenarios",
             "train_aggregate", "train_sample", "train_seed", "setup")

#: The known-answer set-up (used when no plant is given).
KNOWN_ANSWER: dict[str, Any] = {
    "A": ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (1.0, -1.0, 0.5)),
    "B": ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0)),
    "x0": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    "state_weight": ((1.2, -1.0, 1.0), (-1.0, 1.2, -1.0), (1.0, -1.0, 1.2)),
    "input_weight": ((1.0, 0.0), (0.0, 1.0)),
    "t_max": 30.0,
}


def _nested(value: Any) -> Any:
    """Lists (also nested) as tuples, so that the frozen parameters stay hashable."""
    if isinstance(value, (list, tuple)):
        return tuple(_nested(v) for v in value)
    if isinstance(value, np.ndarray):
        return _nested(value.tolist())
    return value


@dataclass(frozen=True)
class Params(ParamsMixin, TrainingParams):
    """``problem=lqr`` parameters (units are the user's: state unit, input unit, time unit).

    Attributes
    ----------
    A, B : tuple of tuple of float or None
        Plant matrices, n × n and n × m (see :mod:`penaltyrun.problems.lqr.plant`).
    plant_file : str or None
        ``.mat`` / ``.npz`` file holding ``A`` and ``B``.
    plant : str or None
        ``module:attribute`` of a continuous python-control ``StateSpace`` or an (A, B) pair.
    dynamics : str or None
        ``module:function`` of a vectorized nonlinear model f(X, U) → Ẋ.
    x0 : tuple or None
        Training initial states, k × n (one state: a flat list); default the n unit vectors.
    holdout_x0 : tuple or None
        Held-out initial states (k' × n); ``None``: ``holdout_n`` seeded states.
    holdout_n : int
        Size of the seeded held-out sample (uniform on the sphere of radius mean ‖x0‖).
    holdout_seed : int
        Seed of that sample.
    holdout_horizon_factor, holdout_t_max_cap : float
        Held-out horizon T = min(factor · t_max, cap) (time unit), never below ``t_max``:
        the held-out starts are judged with the cost integrated to T and to ``t_max`` (see
        :mod:`penaltyrun.problems.horizon`). Defaults 10 and 1 000.
    t_max : float
        Horizon T of the cost (time unit).
    u_max : float, tuple of float or None
        Input limit |u_i| ≤ u_max_i (one number for all inputs); ``None``: unsaturated.
    state_weight, input_weight : tuple or None
        W_x (n × n, symmetric positive semi-definite) and W_u (m × m, positive definite) of
        the performance cost; a flat list is a diagonal; ``None``: identity.
    settle_tol : float or None
        A run with ‖x(T)‖ > settle_tol·‖x0‖ is ``not_settled`` (graded penalty).
    cost_unit : str
        Unit of the cost, shown in reports.
    q_bounds, r_bounds : tuple of float
        Eigenvalue (diagonal-entry) bounds of the tuned Q and R.
    failure_penalty : float or None
        Penalty scale of failed runs (cost units); ``None``: 1000 × the linear optimum J*.
    x_bound : float or None
        ‖x‖ above which a run has diverged; ``None``: 1e4 × the largest ‖x0‖.
    rtol, atol : float
        Tolerances of the integrator (saturated or nonlinear loops only).
    max_steps : int
        Trial-step cap per run of the integrator.
    setup : str
        Derived, not a config key: :func:`setup_label` of the other values.
    """

    HOLDOUT_OFF: ClassVar[Mapping[str, Any]] = MappingProxyType({"holdout_x0": (),
                                                                 "holdout_n": 0})
    A: tuple | None = None
    B: tuple | None = None
    plant_file: str | None = None
    plant: str | None = None
    dynamics: str | None = None
    x0: tuple | None = None
    holdout_x0: tuple | None = None
    holdout_n: int = 16
    holdout_seed: int = 20250422
    holdout_horizon_factor: float = 10.0
    holdout_t_max_cap: float = 1000.0
    t_max: float = 20.0
    u_max: float | tuple | None = None
    state_weight: tuple | None = None
    input_weight: tuple | None = None
    settle_tol: float | None = None
    cost_unit: str = "weighted state² × time (user units)"
    q_bounds: tuple[float, float] = (1e-2, 1e2)
    r_bounds: tuple[float, float] = (1e-2, 1e2)
    failure_penalty: float | None = None
    x_bound: float | None = None
    rtol: float = 1e-10
    atol: float = 1e-12
    max_steps: int = 100_000
    setup: str = ""


#: Reports split cells by :attr:`Params.setup` alone (one short label per plant and cost
#: definition) instead of listing every plant matrix that differs from the defaults.
VARIANT_IGNORE = tuple(f.name for f in fields(Params) if f.name != "setup")


def setup_label(values: Mapping[str, Any]) -> str:
    """Short label of a plant and cost definition: its source and a digest of every
    objective-defining value (e.g. ``dynamics=cartpole:dynamics#3f2a9c1b``); ``""`` for the
    built-in known-answer set-up."""
    import hashlib
    import json

    defining = {k: v for k, v in values.items() if k not in NOT_SETUP}
    if defining == {k: v for k, v in _known_answer_values().items() if k not in NOT_SETUP}:
        return ""
    digest = hashlib.sha256(json.dumps(defining, sort_keys=True, default=str).encode())
    if values.get("dynamics") is not None:
        source = f"dynamics={values['dynamics']}"
    elif values.get("plant") is not None:
        source = f"plant={values['plant']}"
    elif values.get("plant_file") is not None:
        source = f"plant_file={Path(str(values['plant_file'])).name}"
    else:
        source = "A,B"
    return f"{source}#{digest.hexdigest()[:8]}"


def _known_answer_values() -> dict[str, Any]:
    return asdict(replace(Params(), **{k: _nested(v) for k, v in KNOWN_ANSWER.items()}))


def build_params(case: str, overrides: Mapping[str, Any]) -> Params:
    """Defaults → (known-answer set-up when no plant is given) → ``overrides``."""
    names = {f.name for f in fields(Params)} - {"setup"}
    unknown = sorted(set(overrides) - names)
    if unknown:
        raise ConfigError(f"{PREFIX}.{unknown[0]}", "unknown parameter", allowed=sorted(names))
    user_plant = any(overrides.get(k) is not None for k in PLANT_KEYS)
    merged = {**({} if user_plant else KNOWN_ANSWER), **dict(overrides)}
    params = replace(Params(), **{k: _nested(v) for k, v in merged.items()})
    return replace(params, setup=setup_label(asdict(params)))


def _number(key: str, value: Any, positive: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise ConfigError(f"{PREFIX}.{key}", f"must be a finite number, got {value!r}")
    if positive and not value > 0:
        raise ConfigError(f"{PREFIX}.{key}", f"must be > 0, got {value!r}")
    return float(value)


def states(key: str, value: Any, n: int) -> np.ndarray:
    """Initial states as (k, n): a flat list of n numbers is one state; none may be 0."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{PREFIX}.{key}", f"need a list of states of {n} numbers each, "
                          f"got {value!r}") from None
    if arr.ndim == 1 and arr.size == n:
        arr = arr[None]
    if arr.ndim != 2 or arr.shape[1] != n or arr.shape[0] == 0:
        raise ConfigError(f"{PREFIX}.{key}", f"need a list of states of n = {n} numbers "
                          f"each (n from A), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)) or np.any(np.linalg.norm(arr, axis=1) == 0.0):
        raise ConfigError(f"{PREFIX}.{key}", "states must be finite and nonzero")
    return arr


def weight(key: str, value: Any, size: int, definite: bool) -> np.ndarray:
    """A weight matrix (size × size; flat list: diagonal; None: identity), symmetric and
    positive (semi-)definite."""
    if value is None:
        return np.eye(size)
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{PREFIX}.{key}", f"not a numeric matrix: {value!r}") from None
    if arr.ndim == 1 and arr.size == size:
        arr = np.diag(arr)
    if arr.shape != (size, size) or not np.all(np.isfinite(arr)):
        raise ConfigError(f"{PREFIX}.{key}", f"need a {size}x{size} matrix (or {size} diagonal "
                          f"entries), got shape {arr.shape}")
    if not np.allclose(arr, arr.T, rtol=0.0, atol=1e-12 * max(1.0, np.abs(arr).max())):
        raise ConfigError(f"{PREFIX}.{key}", "matrix is not symmetric")
    low = float(np.linalg.eigvalsh(arr)[0])
    tol = 1e-12 * max(1.0, np.abs(arr).max())
    if (definite and low <= 0.0) or low < -tol:
        what = "positive definite" if definite else "positive semi-definite"
        raise ConfigError(f"{PREFIX}.{key}", f"matrix is not {what} (smallest eigenvalue "
                          f"{low:.3g})")
    return arr


def limits(value: Any, m: int) -> np.ndarray | None:
    """``u_max`` as an (m,) array of positive limits, or None."""
    if value is None:
        return None
    vals = value if isinstance(value, (tuple, list)) else (value,) * m
    if len(vals) != m:
        raise ConfigError(f"{PREFIX}.u_max", f"need one number or m = {m} numbers (one per "
                          f"input), got {len(vals)}")
    return np.array([_number("u_max", v) for v in vals])


def bounds(key: str, value: Any) -> tuple[float, float]:
    """Eigenvalue bounds [lower, upper] with 0 < lower < upper."""
    if not isinstance(value, (tuple, list)) or len(value) != 2:
        raise ConfigError(f"{PREFIX}.{key}", f"need [lower, upper], got {value!r}")
    lo, hi = (_number(key, v) for v in value)
    if not lo < hi:
        raise ConfigError(f"{PREFIX}.{key}", f"need lower < upper, got {list(value)}")
    return lo, hi


def scalars(p: Params) -> None:
    """Checks of the scalar parameters (horizon, tolerances, caps, held-out sample)."""
    _number("t_max", p.t_max)
    _number("rtol", p.rtol)
    _number("atol", p.atol)
    for key in ("settle_tol", "failure_penalty", "x_bound"):
        if getattr(p, key) is not None:
            _number(key, getattr(p, key))
    for key in ("max_steps", "holdout_n", "holdout_seed"):
        value = getattr(p, key)
        if isinstance(value, bool) or not isinstance(value, int) or value < (key == "max_steps"):
            raise ConfigError(f"{PREFIX}.{key}", f"must be an integer >= "
                              f"{int(key == 'max_steps')}, got {value!r}")
    horizon.check_settings(p, PREFIX)
    if not isinstance(p.cost_unit, str):
        raise ConfigError(f"{PREFIX}.cost_unit", f"must be a string, got {p.cost_unit!r}")


__all__ = ["CASES", "DEFAULT_CASE", "KNOWN_ANSWER", "PLANT_KEYS", "PREFIX", "Params",
           "VARIANT_IGNORE", "bounds", "build_params", "setup_label", "limits", "scalars", "states",
           "weight"]
