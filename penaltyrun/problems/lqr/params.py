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
from penaltyrun.problems import criteria, horizon
from penaltyrun.problems.base import ParamsMixin
from penaltyrun.problems.lqr import expr
from penaltyrun.problems.multiscenario import TrainingParams
from penaltyrun.typed import is_int, is_number

PREFIX = "problem.params"
PLANT_KEYS = ("A", "B", "plant_file", "plant", "dynamics")
#: Keys whose value names user code as ``module:attribute`` and keys whose value is a data
#: file read here (:mod:`penaltyrun.problems.base`): part of every job's identity.
CODE_PARAMS = ("plant", "dynamics")
FILE_PARAMS = ("plant_file",)
CASES = ("default",)
DEFAULT_CASE = "default"
#: Keys that do not define the tuned objective (left out of :attr:`Params.setup`).
NOT_SETUP = ("holdout_x0", "holdout_n", "holdout_seed", "holdout_horizon_factor",
             "holdout_t_max_cap", "cost_unit", "train_scenarios", "train_aggregate",
             "train_sample", "train_seed", "train_quantile", "setup", "constants")
#: Keys whose strings are not arithmetic (names, paths, units, training scenarios).
NOT_ARITHMETIC = ("plant_file", "plant", "dynamics", "cost_unit", "constants",
                  "train_scenarios", "train_aggregate", "train_sample", "train_seed",
                  "train_quantile", "criterion")

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
class Params(ParamsMixin, TrainingParams, criteria.CriterionParams):
    """``problem=lqr`` parameters (units are the user's: state unit, input unit, time unit).

    Attributes
    ----------
    A, B : tuple of tuple of float or None
        Plant matrices, n × n and n × m (see :mod:`penaltyrun.problems.lqr.plant`).
    plant_file : str or None
        ``.mat`` / ``.npz`` / ``.yaml`` file holding ``A`` and ``B`` (optionally ``dt``; a
        YAML file may hold ``constants`` for expressions in its numbers).
    plant : str or None
        ``module:attribute`` of a python-control ``StateSpace`` (continuous, or discrete with
        its ``dt``) or an (A, B) pair.
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
        A run with ‖x(T)‖ > settle_tol·‖x0‖ is ``not_settled`` (graded penalty); under
        ``criterion: time_energy`` the settling level (default 0.01).
    criterion : str
        ``deadline`` (the cost above, default), ``terminal`` (plus x(T)ᵀ S x(T) per start)
        or ``time_energy`` (the cost to the settling time plus ρ times it); see
        :mod:`penaltyrun.problems.lqr.criteria`.
    rho : float
        ρ of ``time_energy`` (cost units per time unit; default 0.01).
    terminal_weight : tuple or None
        S of ``terminal`` (n diagonal entries or n × n symmetric PSD, n the loop's state
        size incl. integrator states; cost units per squared state unit); ``None``: the
        Riccati solution P* of (A, B, W_x, W_u).
    free_time_cap : float
        Long horizon of ``time_energy`` (time unit; default 1 000): not settled by then is
        ``not_settled``.
    cost_unit : str
        Unit of the cost, shown in reports (the default reads "summed over steps" instead
        of "× time" for a discrete-time plant).
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
    constants : tuple of (str, float) or None
        Named numbers (given as a mapping; a value may be an expression over the names
        before it) that every numeric key may use in expressions such as ``"r/J"``
        (:mod:`~penaltyrun.problems.lqr.expr`).
    dt : float or None
        Sampling time of a discrete-time plant x[k+1] = A x[k] + B u[k] (time unit);
        ``None``: continuous time. The gain is then the discrete LQR gain and the cost the
        sum over the steps (see :mod:`~penaltyrun.problems.lqr.discrete`).
    q_output : tuple or None
        C_q (p × n): the tuned matrix is the p × p Q̃ and the Riccati equation uses
        Q = C_qᵀ Q̃ C_q + ``q_fixed``; ``None``: C_q = I (Q̃ is n × n).
    q_fixed : tuple or None
        Q₀ (n × n, symmetric positive semi-definite, a flat list is a diagonal), a fixed
        part added to the tuned one; ``None``: 0.
    integral_outputs : tuple or None
        C_I (q × n_plant): integral action on the outputs C_I x through q integrator
        states ż = C_I x (discrete: z[k+1] = z[k] + dt C_I x[k]) appended to the state.
    outputs : tuple or None
        C_y (p × n_plant): outputs of the settling-time and overshoot constraints;
        ``None``: every plant state.
    settling_time_max : float or None
        Constraint: every output with y_i(0) ≠ 0 stays within ``settling_band`` |y_i(0)| of
        0 from this time on (time unit).
    settling_band : float
        Band of the settling time, a fraction of |y_i(0)| (default 0.02, as
        python-control's ``step_info``).
    overshoot_max : float or None
        Constraint: max over t of −y_i(t)/y_i(0) at most this (percent).
    disk_margin_min : float or None
        Constraint: balanced (skew 0) disk margin α of the loop broken at the plant
        input at least this (dimensionless; α = 1 ⇔ gain margin [1/3, 3], 53.1° phase).
    gain_margin_min, phase_margin_min : float or None
        Constraint in the units engineers quote: the disk-based gain margin (dB) and phase
        margin (degrees, below 180) the loop must keep, i.e. the disk margin α they imply
        (the larger of the two and ``disk_margin_min`` applies).
    response_points : int
        Samples of the continuous-time response of the settling and overshoot constraints
        (uniform on [0, T]).
    margin_points : int
        Frequencies of the disk margin (log-spaced; up to the Nyquist frequency π/dt
        in discrete time).
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
    constants: tuple | None = None
    dt: float | None = None
    q_output: tuple | None = None
    q_fixed: tuple | None = None
    integral_outputs: tuple | None = None
    outputs: tuple | None = None
    settling_time_max: float | None = None
    settling_band: float = 0.02
    overshoot_max: float | None = None
    disk_margin_min: float | None = None
    gain_margin_min: float | None = None
    phase_margin_min: float | None = None
    response_points: int = 1001
    margin_points: int = 400
    setup: str = ""
    rho: float = 0.01
    free_time_cap: float = 1000.0


#: Reports split cells by :attr:`Params.setup` alone (one short label per plant and cost
#: definition) instead of listing every plant matrix that differs from the defaults.
VARIANT_IGNORE = tuple(f.name for f in fields(Params) if f.name != "setup")


def setup_label(values: Mapping[str, Any]) -> str:
    """Short label of a plant and cost definition: its source and a digest of every
    objective-defining value (e.g. ``dynamics=cartpole:dynamics#3f2a9c1b``); ``""`` for the
    built-in known-answer set-up."""
    import hashlib
    import json

    defining = _defining(values)
    if defining == _defining(_known_answer_values()):
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


def _defining(values: Mapping[str, Any]) -> dict[str, Any]:
    """The objective-defining values; criterion settings count only when not at their
    defaults (so labels of set-ups from before the criteria existed do not change)."""
    defaults = Params()
    return {k: v for k, v in values.items() if k not in NOT_SETUP
            and not (k in criteria.SETTINGS and v == getattr(defaults, k))}


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
    names = expr.resolve_constants(merged.get("constants"), f"{PREFIX}.constants")
    merged = {k: v if k in NOT_ARITHMETIC else expr.resolve_value(v, names, f"{PREFIX}.{k}")
              for k, v in merged.items()}
    if names:
        merged["constants"] = tuple(names.items())
    params = replace(Params(), **{k: _nested(v) for k, v in merged.items()})
    return replace(params, setup=setup_label(asdict(params)))


DISCRETE_UNIT = "weighted state², summed over steps (user units)"


def cost_unit(p: Params, discrete: bool) -> str:
    """The cost unit to show: ``cost_unit``, or for a discrete plant left at the default,
    :data:`DISCRETE_UNIT`."""
    if discrete and p.cost_unit == Params.cost_unit:
        return DISCRETE_UNIT
    return str(p.cost_unit)


def _number(key: str, value: Any, positive: bool = True) -> float:
    if not is_number(value) or not np.isfinite(value):
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
    _number("settling_band", p.settling_band)
    for key in ("settle_tol", "failure_penalty", "x_bound", "dt", "settling_time_max",
                "disk_margin_min", "gain_margin_min", "phase_margin_min"):
        if getattr(p, key) is not None:
            _number(key, getattr(p, key))
    if p.phase_margin_min is not None and not p.phase_margin_min < 180.0:
        raise ConfigError(f"{PREFIX}.phase_margin_min", f"must be below 180 (degrees), got "
                          f"{p.phase_margin_min!r}")
    if p.overshoot_max is not None:
        _number("overshoot_max", p.overshoot_max, positive=False)
        if p.overshoot_max < 0:
            raise ConfigError(f"{PREFIX}.overshoot_max", f"must be >= 0 (percent), got "
                              f"{p.overshoot_max!r}")
    lowest = {"max_steps": 1, "holdout_n": 0, "holdout_seed": 0, "response_points": 3,
              "margin_points": 2}
    for key, low in lowest.items():
        value = getattr(p, key)
        if not is_int(value) or value < low:
            raise ConfigError(f"{PREFIX}.{key}", f"must be an integer >= {low}, got "
                              f"{value!r}")
    horizon.check_settings(p, PREFIX)
    criteria.check(p, PREFIX)
    if not isinstance(p.cost_unit, str):
        raise ConfigError(f"{PREFIX}.cost_unit", f"must be a string, got {p.cost_unit!r}")


def matrix(key: str, value: Any, cols: int, what: str) -> np.ndarray:
    """A p × ``cols`` numeric matrix (a flat list of ``cols`` numbers is one row)."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{PREFIX}.{key}", f"not a numeric matrix: {value!r}") from None
    if arr.ndim == 1 and arr.size == cols:
        arr = arr[None]
    if arr.ndim != 2 or arr.shape[1] != cols or arr.shape[0] == 0 \
            or not np.all(np.isfinite(arr)):
        raise ConfigError(f"{PREFIX}.{key}", f"need finite rows of {cols} numbers ({what}), "
                          f"got shape {arr.shape}")
    return arr


__all__ = ["CASES", "DEFAULT_CASE", "DISCRETE_UNIT", "KNOWN_ANSWER", "PLANT_KEYS", "PREFIX",
           "Params", "VARIANT_IGNORE", "bounds", "build_params", "cost_unit", "limits",
           "matrix", "scalars", "setup_label", "states", "weight"]
